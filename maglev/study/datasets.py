"""Load a study dataset by its (resolved, plain-dict) config and preprocess it.

No Hydra and no MLflow here: ``load`` takes the ``dataset`` section of the resolved
config as a plain dict, so :mod:`maglev.study.reproduce` and notebooks can call it directly.
Simulated records come from :mod:`maglev.sim.labdata`; files from ``data_dir``.
Preprocessing order: trim → detrend → decimate → split.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

from maglev.data import IOData


@dataclass(frozen=True)
class Prepared:
    """A dataset ready for identification: the whole preprocessed record and its two parts."""

    name: str
    raw: IOData  # as loaded (simulated or read)
    data: IOData  # trimmed, detrended, decimated
    est: IOData
    val: IOData
    u0: float  # mean input of the trimmed record: the working point (A)

    @property
    def val_name(self) -> str:
        return self.val.name or f"{self.name}[val]"

    def info(self) -> dict:
        return {"raw": self.raw.to_dict(), "data": self.data.to_dict(), "est": self.est.to_dict(),
                "val": self.val.to_dict(), "u0": self.u0}


def data_path(ds: dict, data_dir: str) -> Path:
    """Where a file dataset lives; a clear error says how to point at the data when it is missing."""
    path = Path(ds["file"])
    if not path.is_absolute():
        path = Path(data_dir) / path
    if not path.is_file():
        raise FileNotFoundError(
            f"dataset {ds['name']!r}: {path} not found. Real records are looked up under data_dir="
            f"{data_dir!r}; set $MAGLEV_REFDATA or pass data_dir=/path/to/refdata"
        )
    return path


def load_raw(ds: dict, data_dir: str) -> IOData:
    """The record of a dataset config (``source`` ``sim`` or ``file``), before preprocessing."""
    if ds["source"] == "sim":
        return _simulate(ds["input_class"], float(ds["low"]), float(ds["high"]),
                         None if ds.get("alpha") is None else float(ds["alpha"]),
                         float(ds["duration_s"]), int(ds["seed"]), float(ds["Ts"]), ds["name"], plant_name(ds))
    if ds["source"] == "file":
        path = data_path(ds, data_dir)
        reader = IOData.from_csv if path.suffix.lower() == ".csv" else IOData.from_mat
        return reader(path, u=ds["u"], y=ds["y"], Ts=ds.get("Ts"), name=ds["name"])
    raise ValueError(f"dataset {ds.get('name')!r}: source must be 'sim' or 'file', got {ds['source']!r}")


def sim_spec(ds: dict):
    """The simulator's record spec (:class:`maglev.sim.labdata.ExperimentSpec`) of a ``source: sim`` dataset."""
    from maglev.sim.labdata import ExperimentSpec

    kind = str(ds["input_class"])
    alpha = ds.get("alpha") if kind == "binary" else None
    return ExperimentSpec(kind=kind, low=float(ds["low"]), high=float(ds["high"]),
                          alpha=None if alpha is None else float(alpha),
                          duration_s=float(ds["duration_s"]), seed=int(ds["seed"]), Ts=float(ds["Ts"]))


# The simulator parameter set of configs logged before ``dataset.plant`` existed (2026-11-23): the schema
# gives every newer config the key, so a config without it was simulated on the defaults of that time.
UNNAMED_PLANT = "dry_friction"


def plant_name(ds: dict) -> str:
    """The simulator parameter set (``maglev.sim.plant.PLANTS``) a dataset config names (``UNNAMED_PLANT``
    for a config logged before the key existed)."""
    return str(ds.get("plant") or UNNAMED_PLANT)


def _bla_preprocess(ds: dict):
    from maglev.spectral import Preprocess

    pp = ds["preprocess"]
    return Preprocess(trim=int(pp["trim"]), detrend=bool(pp["detrend"]), decimate=int(pp["decimate"]))


def dataset_bla(ds: dict):
    """The simulator's best linear approximation for a simulated dataset's input class, on the time base
    of its models (the dataset's trim, detrend and decimation; :func:`maglev.sim.bla.bla`, cached)."""
    from maglev.sim.bla import bla
    from maglev.sim.plant import rig

    return bla(sim_spec(ds), rig(plant_name(ds)), preprocess=_bla_preprocess(ds))


def missing_blas(configs: list[dict]) -> list[dict]:
    """The simulated datasets of these job configs whose BLA their runs need and the disk cache lacks, in the
    jobs' order (each once)."""
    import json

    from maglev.sim.bla import is_cached
    from maglev.sim.plant import rig

    wanted: dict[str, dict] = {}
    for cfg in configs:
        ds = cfg["dataset"]
        if ds["source"] == "sim" and cfg["study"]["true_plant"]:
            wanted.setdefault(json.dumps(ds, sort_keys=True), ds)
    return [ds for ds in wanted.values()
            if not is_cached(sim_spec(ds), rig(plant_name(ds)), preprocess=_bla_preprocess(ds))]


def prepare_blas(configs: list[dict], missing: list[dict] | None = None):
    """Estimate, in a background process, the BLAs that the runs of these job configs will need and the
    disk cache lacks (``missing``, when :func:`missing_blas` was asked already), in the jobs' order;
    returns the process (None when there is nothing to do).

    A 24 s class's BLA takes ≈ 15 s (2-core machine, 2026-11-27), which the first run of each dataset
    would otherwise pay on the sweep's critical path; started before the store and the lab steps, the
    background has the first one well on its way by then and the others while the runs go on (a run
    that needs one still in the making waits for it: :func:`maglev.sim.bla.bla` locks each cache entry
    while estimating it).
    """
    import multiprocessing

    missing = missing_blas(configs) if missing is None else missing
    if not missing:
        return None
    proc = multiprocessing.get_context("spawn").Process(target=_estimate_blas, args=(missing,), daemon=True,
                                                        name="maglev-bla")
    proc.start()
    return proc


def _estimate_blas(datasets: list[dict]) -> None:
    """The datasets' BLAs, those of one plant and preprocessing together (:func:`maglev.sim.bla.blas`: the
    classes of one length in one batch; the default sweep's three: 35 s instead of 51 s, 2026-11-27)."""
    from maglev.sim.bla import blas
    from maglev.sim.plant import rig
    from maglev.study import heap

    heap.settle()  # a process started by study.py held full collections while it imported
    groups: dict[tuple, list[dict]] = {}
    for ds in datasets:
        groups.setdefault((plant_name(ds), _bla_preprocess(ds)), []).append(ds)
    for (plant, preprocess), members in groups.items():
        blas([sim_spec(ds) for ds in members], rig(plant), preprocess=preprocess)


@functools.lru_cache(maxsize=32)  # a sweep's records decision reads the simulated lab set's 18 records
def _simulate(kind, low, high, alpha, duration_s, seed, Ts, name, plant) -> IOData:
    from dataclasses import replace

    from maglev.sim.labdata import experiment
    from maglev.sim.plant import rig

    spec = sim_spec({"input_class": kind, "low": low, "high": high, "alpha": alpha, "duration_s": duration_s,
                     "seed": seed, "Ts": Ts})
    return replace(experiment(spec, plant=rig(plant), cache=True), name=name)


def prepare(raw: IOData, pp: dict, name: str) -> Prepared:
    """Apply the dataset's preprocessing and split into estimation and validation data."""
    data = raw.trim(int(pp["trim"])) if int(pp["trim"]) > 0 else raw
    u0 = float(data.u.mean())
    if pp["detrend"]:
        data = data.detrend()
    k = int(pp["decimate"])
    if k > 1:
        data = data.decimate(k)
    est, val = data.split(float(pp["split"]))
    return Prepared(name=name, raw=raw, data=data, est=est, val=val, u0=u0)


def load(ds: dict, data_dir: str) -> Prepared:
    """Load and preprocess the dataset described by the ``dataset`` config section."""
    return prepare(load_raw(ds, data_dir), ds["preprocess"], ds["name"])
