"""Structured-config schemas of the study, registered in Hydra's ConfigStore.

Every YAML file under ``conf/`` starts from one of these schemas (through its
defaults list), so a misspelt key (``structure.nx=2``), a wrong type
(``structure.na=two``) or an unknown enum value fails while Hydra composes the
config — before any job starts and before any MLflow run exists — and the error
names the key.  Orders live in per-structure schemas: ``structure.na`` exists for
``arx``/``armax`` only, so ``structure=oe structure.na=2`` is refused as well.

``structure.order`` is a shorthand: every polynomial order of the structure
defaults to it (``na: ${.order}``), so one sweep axis ``structure.order=2,3`` works
for all structures, while ``structure.na=3`` still overrides a single order.

The resolver ``${maglev.root:}`` gives the project root (:func:`maglev.paths.project_root`).  Importing
this module also has each config file parsed once per process (:func:`maglev.study.compose.parse_each_file_once`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields as schema_fields, is_dataclass, make_dataclass
from enum import Enum
from typing import Any, Optional, get_type_hints

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, DictConfig, OmegaConf

from maglev.paths import project_root
from maglev.study import compose
from maglev.structures import get as get_structure
from maglev.structures import names as structure_names


compose.parse_each_file_once()

if not OmegaConf.has_resolver("maglev.root"):
    OmegaConf.register_new_resolver("maglev.root", lambda: str(project_root()))


def _decided(rule: str):
    """A resolver that asks :mod:`maglev.study.decisions` for a rule's answer (imported on first use)."""
    def resolve(*args):
        from maglev.study import decisions

        return getattr(decisions, rule)(*args)
    return resolve


for _name, _rule in (("maglev.record", "chosen_record"), ("maglev.transient", "transient_samples"),
                     ("maglev.split", "split_fraction")):
    if not OmegaConf.has_resolver(_name):
        OmegaConf.register_new_resolver(_name, _decided(_rule))


class InputClass(Enum):
    uniform = "uniform"
    binary = "binary"


class InitialCondition(Enum):
    auto = "auto"
    zero = "zero"
    estimate = "estimate"
    backcast = "backcast"


@dataclass
class PreprocessCfg:
    """Applied in this order: trim, detrend, decimate, split."""

    trim: int = 2000  # samples dropped at the start (the magnet's start-up transient)
    detrend: bool = True  # remove the means of u and y
    decimate: int = 1  # keep every k-th sample after an anti-aliasing filter
    split: float = 0.5  # estimation fraction; the rest is validation data


@dataclass
class SimDatasetCfg:
    """A lab experiment run on the simulator (``maglev.sim.labdata``)."""

    name: str = MISSING
    source: str = "sim"
    input_class: InputClass = MISSING  # the signal: uniform white noise or random binary
    low: float = MISSING  # A
    high: float = MISSING  # A
    alpha: Optional[float] = None  # switching probability (binary only)
    duration_s: float = 24.0  # lab §3.4: >= 10 s estimation and 7 s validation after trimming
    seed: int = 0
    Ts: float = 0.001
    plant: str = "stuck_stretched"  # the simulator's parameter set (maglev.sim.plant.PLANTS, DEFAULT_PLANT)
    preprocess: PreprocessCfg = field(default_factory=PreprocessCfg)


@dataclass
class FileDatasetCfg:
    """A recorded experiment: ``file`` (.mat or .csv) relative to the top-level ``data_dir``."""

    name: str = MISSING
    source: str = "file"
    input_class: InputClass = MISSING
    file: str = MISSING
    u: str = "u"  # variable / column of the input
    y: str = "y"  # variable / column of the output
    Ts: Optional[float] = None  # seconds; None: read from the file
    preprocess: PreprocessCfg = field(default_factory=PreprocessCfg)


def structure_schema(name: str) -> type:
    """The config schema of a registered structure: its MATLAB orders (each defaulting to ``order``),
    ``nk``, ``initial_condition`` and, for iterative estimators, ``max_iterations``.

    Generated from :mod:`maglev.structures`, so a key the structure does not have (``na``
    for OE) is refused at composition, naming the key.  The class is bound to this
    module under its name (``OeCfg``): joblib workers unpickle the config by reference
    and must find the same class that their own import of this module registered.
    """
    entry = get_structure(name)
    fields = [("name", str, field(default=name)), ("order", int, field(default=2))]
    fields += [(k, int, field(default="${.order}")) for k in entry.free]
    fields += [("nk", int, field(default=1)),
               ("initial_condition", InitialCondition, field(default=InitialCondition.auto))]
    if not entry.least_squares:
        fields.append(("max_iterations", int, field(default=200)))
    cls_name = f"{name.capitalize()}Cfg"
    cls = make_dataclass(cls_name, fields)
    cls.__module__, cls.__qualname__ = __name__, cls_name
    globals()[cls_name] = cls
    return cls


@dataclass
class TrackingCfg:
    uri: str = MISSING  # sqlite:///ABS/PATH/mlflow.db or http://host:port
    artifact_location: Optional[str] = None  # root folder for a local store; None: the server decides
    experiment: str = "maglev"
    reap: bool = True  # before a sweep, mark runs of dead local processes KILLED
    log_figures: bool = True
    max_retries: int = 2  # a tracking server: MLflow's HTTP retries per call (waits 0, 2, 4 ... s between; MLflow: 7)
    timeout_s: int = 10  # a tracking server: seconds per HTTP attempt (MLflow: 120)


@dataclass
class LabCfg:
    """The lab-level steps logged once per sweep on the parent run."""

    enabled: bool = True
    staircase_file: Optional[str] = None  # relative to data_dir; None: simulate the lab's staircase
    staircase_u: str = "u"
    staircase_y: str = "y"
    levels: int = 21  # number of staircase levels
    tail: float = 50.0  # percent of each level averaged as stationary
    energy_fraction: float = 0.8  # share of the output energy defining the band for alpha*
    max_order: int = 8  # ARX order selection (arxstruc/selstruc): na, nb in 1..max_order
    max_delay: int = 10  # delay estimation (delayest): nk in 0..max_delay


@dataclass
class StudyCfg:
    name: str = "study"  # sweep name: the parent run's name and the sweep folder
    val_horizon: int = 1  # prediction horizon of val_fit (1 = one step ahead)
    resid_lags: int = 25
    # simulated data: distances to the best linear approximation of the input class (g_bla_err) and to the
    # simulator's linearisation
    true_plant: bool = True
    skip_finished: bool = True  # skip a config whose hash already has a FINISHED run
    fail_on_error: bool = False  # re-raise a failing run's error (stops a basic-launcher sweep)


@dataclass
class Config:
    dataset: Any = MISSING
    structure: Any = MISSING
    tracking: TrackingCfg = field(default_factory=TrackingCfg)
    lab: LabCfg = field(default_factory=LabCfg)
    study: StudyCfg = field(default_factory=StudyCfg)
    data_dir: str = "${oc.env:MAGLEV_REFDATA,${maglev.root:}/../shared/refdata}"


DATASET_SCHEMAS = {"sim": SimDatasetCfg, "file": FileDatasetCfg}
STRUCTURE_SCHEMAS: dict[str, type] = {}


def register() -> None:
    """Register the schemas (idempotent): ``base_config`` and ``<group>/<kind>_schema``."""
    cs = ConfigStore.instance()
    cs.store(name="base_config", node=Config)
    for kind, node in DATASET_SCHEMAS.items():
        cs.store(group="dataset", name=f"{kind}_schema", node=node)
    for name in structure_names():
        register_structure(name)
    cs.store(group="tracking", name="tracking_schema", node=TrackingCfg)
    cs.store(group="lab", name="lab_schema", node=LabCfg)


def register_structure(name: str) -> type:
    """Generate and register the schema ``structure/<name>_schema`` of a registered structure (idempotent)."""
    if name not in STRUCTURE_SCHEMAS:
        STRUCTURE_SCHEMAS[name] = structure_schema(name)
        ConfigStore.instance().store(group="structure", name=f"{name}_schema", node=STRUCTURE_SCHEMAS[name])
    return STRUCTURE_SCHEMAS[name]


# Config's sections of one schema each (tracking, lab, study), as its fields declare them
SECTIONS = {key: kind for key, kind in get_type_hints(Config).items() if is_dataclass(kind)}


def _carries(cfg: DictConfig, schemas: dict[str, type]) -> bool:
    """Whether ``cfg`` has exactly ``Config``'s keys and each section named in ``schemas`` already that schema."""
    return (set(cfg) == {f.name for f in schema_fields(Config)}
            and all(key in cfg and OmegaConf.get_type(cfg, key) is schema for key, schema in schemas.items()))


def typed(cfg: DictConfig) -> DictConfig:
    """Re-apply the schemas to a config that has lost them (e.g. one loaded from a YAML file); a config that
    still has them (as Hydra composed it) is returned as it is.

    Raises the same ``ValidationError``/``ConfigKeyError`` naming the key as composition does.
    """
    ds_kind = OmegaConf.select(cfg, "dataset.source", default="sim")
    st_kind = OmegaConf.select(cfg, "structure.name", default="arx")
    if ds_kind not in DATASET_SCHEMAS:
        raise ValueError(f"dataset.source must be one of {list(DATASET_SCHEMAS)}, got {ds_kind!r}")
    if st_kind not in structure_names():
        raise ValueError(f"structure.name must be one of {list(structure_names())}, got {st_kind!r}")
    register_structure(st_kind)
    if _carries(cfg, {"dataset": DATASET_SCHEMAS[ds_kind], "structure": STRUCTURE_SCHEMAS[st_kind], **SECTIONS}):
        return cfg  # as Hydra composed it: merging the same schemas again would change nothing (≈ 10 ms a job)
    base = OmegaConf.structured(Config)
    base.dataset = OmegaConf.structured(DATASET_SCHEMAS[ds_kind])
    base.structure = OmegaConf.structured(STRUCTURE_SCHEMAS[st_kind])
    return OmegaConf.merge(base, cfg)


register()
