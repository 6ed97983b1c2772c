"""The study's resolved config as plain data: schema re-applied, semantic checks, identity.

A job, a reproduction and the ranking all work on the resolved task config as a plain
dict (sections ``dataset``, ``structure``, ``study``, ``tracking``, ``lab``,
``data_dir``).  This module turns a Hydra/OmegaConf config into that dict with the
schema re-applied (:func:`plain_config`), refuses configs that cannot describe a run
before any run exists (:func:`check`, naming the key), and defines what identifies a
run's result (:func:`config_hash`) and how the config is logged as MLflow params
(:func:`flatten`).
"""

from __future__ import annotations

import hashlib
import json

from omegaconf import DictConfig, OmegaConf

from maglev.study.identify import orders_of
from maglev.study.schema import typed

# study keys that change a run's result (the rest — name, skipping, failing — do not)
HASHED_STUDY_KEYS = ("val_horizon", "resid_lags", "true_plant")


class StudyConfigError(ValueError):
    """A config that passed the schema but cannot describe a run (says which key is wrong)."""


def plain_config(cfg: DictConfig) -> dict:
    """The resolved task config as plain Python (enums as strings), with the schema re-applied.

    A mandatory value left unset (``???``, e.g. ``dataset=real_record`` alone) raises
    OmegaConf's ``MissingMandatoryValue`` naming the key.
    """
    return OmegaConf.to_container(typed(cfg), resolve=True, enum_to_str=True, throw_on_missing=True)


def task_config(config: DictConfig) -> dict:
    """The resolved task part of a full Hydra config (everything but ``hydra``)."""
    return plain_config(OmegaConf.masked_copy(config, [k for k in config if k != "hydra"]))


def check(cfg: dict) -> None:
    """Semantic checks the schema cannot express; raise ``StudyConfigError`` naming the key."""
    from maglev.structures import PolySpec
    from maglev.study.datasets import data_path

    st, ds = cfg["structure"], cfg["dataset"]
    try:
        PolySpec.from_orders(st["name"], orders_of(st))
    except ValueError as exc:
        raise StudyConfigError(f"structure: {exc}") from None
    pp = ds["preprocess"]
    if not 0 < pp["split"] < 1:
        raise StudyConfigError(f"dataset.preprocess.split must be in (0, 1), got {pp['split']}")
    if pp["decimate"] < 1 or pp["trim"] < 0:
        raise StudyConfigError("dataset.preprocess: decimate must be >= 1 and trim >= 0, "
                               f"got decimate={pp['decimate']}, trim={pp['trim']}")
    if ds["source"] == "sim":
        from maglev.study.datasets import sim_spec

        try:
            sim_spec(ds)
        except (TypeError, ValueError) as exc:
            raise StudyConfigError(f"dataset {ds['name']!r}: {exc}") from None
    else:
        try:
            data_path(ds, cfg["data_dir"])
        except FileNotFoundError as exc:
            raise StudyConfigError(str(exc)) from None
    if cfg["study"]["val_horizon"] < 1:
        raise StudyConfigError(f"study.val_horizon must be >= 1, got {cfg['study']['val_horizon']}")


def hashed_part(cfg: dict) -> dict:
    """What determines a run's result: data, preprocessing, structure and orders, validation."""
    st = cfg["structure"]
    structure = {k: v for k, v in st.items() if k != "order"}  # `order` is only a shorthand
    structure = {**structure, "orders": orders_of(st)}
    return {"dataset": dict(cfg["dataset"]), "structure": structure,
            "study": {k: cfg["study"][k] for k in HASHED_STUDY_KEYS}}


def config_hash(cfg: dict) -> str:
    """sha1 of the result-determining part of the resolved config (not tracking, paths or names)."""
    text = json.dumps(hashed_part(cfg), sort_keys=True, default=str)
    return hashlib.sha1(text.encode()).hexdigest()


def flatten(d: dict, prefix: str = "") -> dict[str, str]:
    """``{"a": {"b": 1}}`` → ``{"a.b": "1"}`` (lists as JSON, values cut to MLflow's 6000 chars)."""
    out: dict[str, str] = {}
    for key, value in d.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(flatten(value, name + "."))
        else:
            text = json.dumps(value) if isinstance(value, (list, tuple)) else str(value)
            out[name] = text[:6000]
    return out
