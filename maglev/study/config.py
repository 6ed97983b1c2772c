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

import functools
import hashlib
import json
import re

from omegaconf import DictConfig, OmegaConf

from maglev.structures import get as get_structure
from maglev.study.schema import typed

# study keys that change a run's result (the rest — name, skipping, failing — do not)
HASHED_STUDY_KEYS = ("val_horizon", "resid_lags", "true_plant")


def orders_of(section: dict) -> list[int]:
    """MATLAB order vector of a structure config section, e.g. ``[na nb nk]`` for ARX."""
    return [int(section[k]) for k in get_structure(section["name"]).orders]


class StudyConfigError(ValueError):
    """A config that passed the schema but cannot describe a run (says which key is wrong)."""


def runs_jobs_here(launcher: DictConfig) -> bool:
    """Whether ``hydra.launcher`` is Hydra's basic launcher, which runs a sweep's jobs in the launching process,
    one after another (joblib and submitit run them in other processes)."""
    return str(launcher.get("_target_", "")).endswith("BasicLauncher")


def plain_config(cfg: DictConfig) -> dict:
    """The resolved task config as plain Python (enums as strings), with the schema re-applied.

    A mandatory value left unset (``???``, e.g. ``dataset=real_record`` alone) raises
    OmegaConf's ``MissingMandatoryValue`` naming the key.
    """
    return OmegaConf.to_container(typed(cfg), resolve=True, enum_to_str=True, throw_on_missing=True)


def task_config(config: DictConfig) -> dict:
    """The resolved task part of a full Hydra config (everything but ``hydra``)."""
    return plain_config(OmegaConf.masked_copy(config, [k for k in config if k != "hydra"]))


# A structure needs this many estimation samples per parameter: with d parameters and N samples the
# expected validation loss is inflated by (1 + d/N)/(1 - d/N) (Akaike's FPE), 22 % at N = 10 d.
SAMPLES_PER_PARAMETER = 10


# names that become file and folder names (the sweep dir, the report, artifact paths): no separator, no
# leading dot (``..``), within every filesystem's name length with room for the report's suffix
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._+-]{0,99}")
NAMED_KEYS = (("study", "name"), ("dataset", "name"))


def check_names(cfg: dict) -> None:
    """``study.name`` and ``dataset.name`` become paths (``multirun/<study.name>``, the report's file,
    artifact names): letters, digits, ``. _ + -``, not starting with a dot, at most 100 characters."""
    for section, key in NAMED_KEYS:
        value = str(cfg[section][key])
        if not NAME.fullmatch(value):
            shown = value if len(value) <= 60 else f"{value[:40]}… ({len(value)} characters)"
            raise StudyConfigError(f"{section}.{key}={shown!r}: a name must be 1-100 letters, digits or "
                                   "'._+-', starting with a letter or digit (it becomes a file name)")


def safe_name(text: str) -> str:
    """``text`` as a plain file name: characters other than letters, digits and ``._+-`` become ``_``, no
    leading dot, at most 100 characters (for names read back from a store, which anyone may have tagged)."""
    name = re.sub(r"[^A-Za-z0-9._+-]", "_", text)[:100].lstrip(".")
    return name or "_"


def report_file_name(name: str, sid: str) -> str:
    """A sweep's report file name, ``<name>-<first 8 characters of sid>.html`` (``sid``: its ``sweep_id``, or its
    parent run id without one), each part a plain file name (:func:`safe_name`).  Here, with no MLflow import,
    so that the relaunch's survey (:mod:`maglev.study.callbacks`) and the ranking name the same file."""
    return f"{safe_name(name)}-{safe_name(sid[:8])}.html"


# what MLflow can store runs in: SQLite (an absolute path), a tracking server, a database server
TRACKING_URI = re.compile(r"sqlite:////.+|https?://[^/\s]+(/.*)?|(postgresql|mysql|mssql)(\+\w+)?://.+")


def check_tracking(tracking: dict) -> None:
    """``tracking.uri`` one MLflow stores runs in (a bare path would be MLflow's deprecated file store),
    ``tracking.experiment`` a name, the HTTP bounds within MLflow's."""
    from maglev.study.credentials import public

    uri = str(tracking.get("uri", ""))
    if not TRACKING_URI.fullmatch(uri):
        raise StudyConfigError(f"tracking.uri={public(uri)!r}: expected sqlite:////ABSOLUTE/PATH/mlflow.db, "
                               "http(s)://HOST:PORT (a tracking server) or a database URI (postgresql://…)")
    name = str(tracking.get("experiment") or "")
    if not name.strip():
        raise StudyConfigError("tracking.experiment is empty: name the MLflow experiment (default: maglev)")
    if tracking.get("artifact_location") and not NAME.fullmatch(name):  # it names the artifact folder too
        raise StudyConfigError(f"tracking.experiment={name!r}: with a local artifact_location it names a folder: "
                               "1-100 letters, digits or '._+-', starting with a letter or digit")
    if not 0 <= tracking.get("max_retries", 0) <= 10:  # MLflow refuses more than 10
        raise StudyConfigError(f"tracking.max_retries must be in [0, 10], got {tracking['max_retries']}")
    if tracking.get("timeout_s", 1) < 1:
        raise StudyConfigError(f"tracking.timeout_s must be >= 1 (whole seconds), got {tracking['timeout_s']}")


def check_keys(cfg: dict) -> None:
    """No key the schema does not have: ``+structure.oder=3`` (Hydra's own hint for a typo) adds one that
    composition accepts and nothing reads."""
    from dataclasses import fields

    from maglev.study import schema

    sections = {"": schema.Config, "dataset": schema.DATASET_SCHEMAS.get(cfg["dataset"].get("source")),
                "dataset.preprocess": schema.PreprocessCfg, "structure": schema.register_structure(cfg["structure"]["name"]),
                "tracking": schema.TrackingCfg, "lab": schema.LabCfg, "study": schema.StudyCfg}
    for path, cls in sections.items():
        node = cfg
        for key in filter(None, path.split(".")):
            node = node.get(key) or {}
        unknown = sorted(set(node) - {f.name for f in fields(cls)}) if cls is not None else []
        if unknown:
            where = f"{path}." if path else ""
            raise StudyConfigError(f"{where}{unknown[0]}: no such key (known: {', '.join(f.name for f in fields(cls))})")


def check(cfg: dict) -> None:
    """Semantic checks the schema cannot express; raise ``StudyConfigError`` naming the key.

    Everything the config decides is checked here, before any run exists: orders, the
    dataset's length after trim, decimation and split against what the structure and the
    validation (``study.resid_lags``, ``study.val_horizon``) need, and the iteration limit.
    """
    from maglev.structures import PolySpec

    st, ds, study = cfg["structure"], cfg["dataset"], cfg["study"]
    check_keys(cfg)
    check_names(cfg)
    if "tracking" in cfg:
        check_tracking(cfg["tracking"])
    if ds["source"] == "sim" and not 0 <= ds["seed"] < 2**32:
        raise StudyConfigError(f"dataset.seed must be in [0, 2**32), got {ds['seed']}")
    try:
        spec = PolySpec.from_orders(st["name"], orders_of(st))
    except ValueError as exc:
        raise StudyConfigError(f"structure: {exc}") from None
    if "max_iterations" in st and st["max_iterations"] < 0:
        raise StudyConfigError(f"structure.max_iterations must be >= 0, got {st['max_iterations']}")
    pp = ds["preprocess"]
    if not 0 < pp["split"] < 1:
        raise StudyConfigError(f"dataset.preprocess.split must be in (0, 1), got {pp['split']}")
    if pp["decimate"] < 1 or pp["trim"] < 0:
        raise StudyConfigError("dataset.preprocess: decimate must be >= 1 and trim >= 0, "
                               f"got decimate={pp['decimate']}, trim={pp['trim']}")
    if study["val_horizon"] < 1:
        raise StudyConfigError(f"study.val_horizon must be >= 1, got {study['val_horizon']}")
    if study["resid_lags"] < 1:
        raise StudyConfigError(f"study.resid_lags must be >= 1, got {study['resid_lags']}")
    check_lengths(ds, spec, study, raw_length(ds, cfg["data_dir"]))


def raw_length(ds: dict, data_dir: str) -> int:
    """Samples of the dataset before preprocessing, without simulating (a file is read once)."""
    if ds["source"] == "sim":
        from maglev.sim.plant import PLANTS
        from maglev.study.datasets import plant_name, sim_spec

        if plant_name(ds) not in PLANTS:
            raise StudyConfigError(f"dataset {ds['name']!r}: dataset.plant must be one of {sorted(PLANTS)} "
                                   f"(maglev.sim.plant.PLANTS), got {ds['plant']!r}")
        if ds["input_class"] == "binary" and ds.get("alpha") is None:
            raise StudyConfigError(f"dataset {ds['name']!r}: dataset.alpha (switching probability in [0, 1]) "
                                   "is needed for a binary input")
        try:
            return sim_spec(ds).n
        except (TypeError, ValueError) as exc:
            raise StudyConfigError(f"dataset {ds['name']!r}: {exc}") from None
    from maglev.study.datasets import data_path

    try:
        path = data_path(ds, data_dir)
    except FileNotFoundError as exc:
        raise StudyConfigError(str(exc)) from None
    try:
        return _file_length(str(path), ds["u"], ds["y"], ds.get("Ts"))
    except ValueError as exc:
        raise StudyConfigError(f"dataset {ds['name']!r}: {exc}") from None


@functools.lru_cache(maxsize=64)
def _file_length(path: str, u: str, y: str, Ts: float | None) -> int:
    from maglev.data import IOData

    reader = IOData.from_csv if path.lower().endswith(".csv") else IOData.from_mat
    return reader(path, u=u, y=y, Ts=Ts).N


def parts(n_raw: int, trim: int, decimate: int, split: float) -> tuple[int, int]:
    """Estimation and validation samples left of ``n_raw`` by trim, decimate and split
    (as :func:`maglev.study.datasets.prepare` cuts them: decimation keeps samples 0, k, 2k, …)."""
    n = max(-(-(n_raw - trim) // decimate), 0)
    n_est = int(round(n * split))
    return n_est, n - n_est


def check_lab(cfg: dict) -> None:
    """A sweep's lab steps read ``lab.staircase_file`` (relative to ``data_dir``): it must exist."""
    from pathlib import Path

    lab = cfg.get("lab") or {}
    if lab.get("enabled") and lab.get("staircase_file"):
        path = Path(lab["staircase_file"])
        path = path if path.is_absolute() else Path(cfg["data_dir"]) / path
        if not path.is_file():
            raise StudyConfigError(f"lab.staircase_file: {path} not found (data_dir={cfg['data_dir']!r}); set "
                                   "$MAGLEV_REFDATA or pass data_dir=/path/to/refdata, or lab=sim")


def check_lengths(ds: dict, spec, study: dict, n_raw: int) -> None:
    """The estimation and validation parts left by trim, decimate and split must be long enough for the
    structure (``SAMPLES_PER_PARAMETER`` per parameter, and the estimator's own minimum) and for the
    validation (``study.resid_lags`` below half its samples; ``study.val_horizon`` at most half of
    them, so that at least half of the k-step predictions start from a measured output: the first k
    come from the initial state alone, and a horizon of N samples or more is a simulation).

    The error names the key to change first: the trim or decimation when both parts are too
    short, the split when an even split would do, else the orders (estimation) or the
    residual lags / horizon (validation); and any other single change that would do.
    """
    from maglev.data import MIN_SAMPLES

    pp, name = ds["preprocess"], ds["name"]
    trim, k, split = int(pp["trim"]), int(pp["decimate"]), float(pp["split"])
    lags, horizon = int(study["resid_lags"]), int(study["val_horizon"])
    need_est = max(spec.max_lag + 2 * spec.n_params + 1, SAMPLES_PER_PARAMETER * spec.n_params, MIN_SAMPLES)
    need_val = max(2 * (lags + 1), 2 * horizon, MIN_SAMPLES)

    def fits(n_est: int, n_val: int) -> bool:
        return n_est >= need_est and n_val >= need_val

    n_est, n_val = parts(n_raw, trim, k, split)
    if fits(n_est, n_val):
        return
    changes = {f"dataset.preprocess.trim={trim}": trim > 0 and fits(*parts(n_raw, 0, k, split)),
               f"dataset.preprocess.decimate={k}": k > 1 and fits(*parts(n_raw, trim, 1, split)),
               f"dataset.preprocess.split={split}": fits(*parts(n_raw, trim, k, 0.5))}
    trim_key, dec_key, split_key = changes
    if n_est < need_est and n_val < need_val and (changes[trim_key] or changes[dec_key]):
        key = trim_key if changes[trim_key] else dec_key  # the record is too short after preprocessing
    elif changes[split_key]:
        key = split_key
    elif n_est < need_est:
        key = f"structure.order ({spec.label})"
    else:
        key = f"study.val_horizon={horizon}" if need_val == 2 * horizon else f"study.resid_lags={lags}"
    others = [k_ for k_, ok in changes.items() if ok and k_ != key]
    raise StudyConfigError(
        f"{key}: dataset {name!r} ({n_raw} samples; trim {trim}, decimate {k}, split {split}) leaves "
        f"{n_est} estimation and {n_val} validation samples; {spec.label} needs at least {need_est} estimation "
        f"samples ({spec.n_params} parameters, {SAMPLES_PER_PARAMETER} samples each) and the validation at "
        f"least {need_val} (study.resid_lags={lags} below half of them, study.val_horizon={horizon} at most half)"
        + (f"; changing {' or '.join(others)} alone would also do" if others else ""))


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
