"""The lab's decisions for a sweep, from its records: the glue between the configs and :mod:`maglev.lab`'s rules.

The rules themselves (working region, record choice, start transient and split, α, delay,
orders) are plain functions in :mod:`maglev.lab`; this module feeds them the records a config
names (and the sets the records are chosen from: the 2022 set, :data:`SIM_RECORDS` on the simulator)
and turns their answers into config values and one ``decisions.json``
(schema: :mod:`maglev.lab.decision`).  Three OmegaConf resolvers (registered by
:mod:`maglev.study.schema`) let a config ask for a rule's answer, so a sweep stays
declarative and a ``key=value`` override still forces any of them:

* ``${maglev.record:uniform,1,name,${data_dir},${lab.staircase_file}}`` — the field (``name``, ``file``,
  ``u``, ``y``, ``Ts``) of the rule's 1st uniform record of the 2022 set (conf/dataset/real_choice_*.yaml);
* ``${maglev.transient:${data_dir},${..file},${..u},${..y},${..Ts}}`` — the record's start transient in samples;
* ``${maglev.split:${data_dir},${..file},${..u},${..y},${..Ts},${.trim},${.decimate}}`` — the estimation
  fraction that gives 10 s / 7 s when the record allows.

No MLflow here; the sweep callback logs :func:`sweep_decisions` on the parent run.
"""

from __future__ import annotations

import functools
from dataclasses import replace
from pathlib import Path

from maglev.data import IOData
from maglev.lab.decision import Decision
from maglev.lab.records import (RecordAssessment, alpha_decision, assess, choose_records, length_decision,
                                length_split, start_transient, switching_rate)
from maglev.lab.working_region import WorkingRegion, working_region
from maglev.refdata import DESIGN_ALPHA, KTH_2022, RECORDS

STAIRCASE_2022 = f"{KTH_2022}/working_region.mat"
STAIR_LEVELS, STAIR_TAIL = 21, 50.0


def record_class(name: str) -> str | None:
    """The input class of a 2022 record by its name (None for the staircase)."""
    if name.startswith("binary_signal"):
        return "binary"
    if name.startswith("white_noise"):
        return "uniform"
    return None


@functools.lru_cache(maxsize=8)
def _read(path: str, u: str, y: str, Ts: float | None) -> IOData:
    reader = IOData.from_csv if path.lower().endswith(".csv") else IOData.from_mat
    return reader(path, u=u, y=y, Ts=Ts)


def _record(data_dir: str, file: str, u: str, y: str, Ts: float | None) -> IOData:
    path = Path(file) if Path(file).is_absolute() else Path(data_dir) / file
    if not path.is_file():
        raise FileNotFoundError(f"dataset file {path} not found (data_dir={data_dir!r})")
    return _read(str(path), u, y, None if Ts is None else float(Ts))


# ------------------------------------------------------------------------------------- working region
def region_of(stairs: IOData, levels: int = STAIR_LEVELS, tail: float = STAIR_TAIL) -> WorkingRegion:
    n = stairs.N - stairs.N % levels
    return working_region(stairs.u[:n], stairs.y[:n], levels, tail)


@functools.lru_cache(maxsize=4)
def real_region(data_dir: str, staircase_file: str | None) -> WorkingRegion:
    """The working region of a real staircase (``staircase_file`` under ``data_dir``; default the 2022 one)."""
    return region_of(_record(data_dir, staircase_file or STAIRCASE_2022, "u", "y", None))


# ------------------------------------------------------------------------------------- records
@functools.lru_cache(maxsize=4)
def assessed_2022(data_dir: str, staircase_file: str | None) -> tuple[RecordAssessment, ...]:
    """Every 2022 input record measured against the staircase's working region and static curve."""
    wr = real_region(data_dir, staircase_file)
    region, curve = (wr.u_min, wr.u_max), (float(wr.y_bar.min()), float(wr.y_bar.max()))
    out = []
    for name, (u, y, Ts) in RECORDS.items():
        cls = record_class(name)
        if cls is None:
            continue
        d = _record(data_dir, f"{KTH_2022}/{name}.mat", u, y, Ts)
        out.append(assess(f"real_{name}", cls, d.u, d.y, d.Ts, region, curve))
    return tuple(out)


def alpha_star_of(data: IOData, trim: int, fraction: float = 0.8):
    """(output spectrum, α choice) of a record on its recorded sample axis, after ``trim`` samples: α is a
    per-recorded-sample probability, so the band must be in rad per recorded sample (not decimated)."""
    from maglev.lab.input_design import choose_alpha, output_spectrum

    spec = output_spectrum(data.y[trim:], fraction)
    return spec, choose_alpha(spec.band)


@functools.lru_cache(maxsize=4)
def records_2022(data_dir: str, staircase_file: str | None, fraction: float = 0.8,
                 forced: tuple[str, ...] | None = None) -> Decision:
    """The records decision on the 2022 set: uniform records first, α* from the best one's output spectrum
    (lab §3.4), then the binary record nearest α*."""
    assessed = assessed_2022(data_dir, staircase_file)
    first = choose_records(assessed, None, {"uniform": 1})
    if not first.choice["uniform"]:
        raise ValueError("no uniform record of the 2022 set passes the record rule")
    best = first.choice["uniform"][0].removeprefix("real_")
    u, y, Ts = RECORDS[best]
    d = _record(data_dir, f"{KTH_2022}/{best}.mat", u, y, Ts)
    _, alpha = alpha_star_of(d, start_transient(d.y, d.Ts).samples, fraction)
    dec = choose_records(assessed, alpha.alpha_star, forced=forced)
    dec.reasons.insert(0, f"α* = {alpha.alpha_star:g}, from the output spectrum of {first.choice['uniform'][0]} on "
                          "its recorded sample axis.")
    return dec


def chosen_record(cls: str, rank: int, field: str, data_dir: str, staircase_file: str | None = None) -> object:
    """A field of the rule's ``rank``-th (1-based) record of class ``cls``: the resolver ``maglev.record``.

    Without the records under ``data_dir`` the rule cannot run: the fields then name the staircase the rule
    needs, so that the config check refuses the dataset with the usual missing-file error."""
    if not (Path(data_dir) / (staircase_file or STAIRCASE_2022)).is_file():
        return {"name": f"real_choice_{cls}_{rank}", "file": staircase_file or STAIRCASE_2022, "u": "u", "y": "y",
                "Ts": None}[field]
    choice = records_2022(str(data_dir), staircase_file).choice
    names = choice.get(str(cls), [])
    rank = int(rank)
    if not 1 <= rank <= len(names):
        raise ValueError(f"maglev.record: the record rule chose {len(names)} {cls} record(s) ({names}), "
                         f"none ranked {rank}")
    stem = names[rank - 1].removeprefix("real_")
    u, y, Ts = RECORDS[stem]
    fields = {"name": f"real_{stem}", "file": f"{KTH_2022}/{stem}.mat", "u": u, "y": y, "Ts": Ts}
    if field not in fields:
        raise ValueError(f"maglev.record: field must be one of {sorted(fields)}, got {field!r}")
    return fields[field]


# ------------------------------------------------------------------------------------- length
def _present(data_dir: str, file: str) -> bool:
    return (Path(file) if Path(file).is_absolute() else Path(data_dir) / file).is_file()


def transient_samples(data_dir: str, file: str, u: str, y: str, Ts: float | None) -> int:
    """The resolver ``maglev.transient``: the record's start transient in recorded samples (0 when the file is
    missing: the config check then refuses the dataset, naming the file)."""
    if not _present(data_dir, file):
        return 0
    d = _record(str(data_dir), str(file), str(u), str(y), Ts)
    return int(start_transient(d.y, d.Ts).samples)


def split_fraction(data_dir: str, file: str, u: str, y: str, Ts: float | None, trim: int, decimate: int) -> float:
    """The resolver ``maglev.split``: the estimation fraction of :func:`maglev.lab.records.length_split` (0.5
    when the file is missing)."""
    if not _present(data_dir, file):
        return 0.5
    d = _record(str(data_dir), str(file), str(u), str(y), Ts)
    n = -(-(d.N - int(trim)) // int(decimate))
    return float(length_split(n, d.Ts * int(decimate))[0])


def _raw(ds: dict, data_dir: str) -> IOData:
    from maglev.study.datasets import load_raw

    return load_raw(ds, data_dir)


def length_rows(datasets: list[dict], data_dir: str) -> list[dict]:
    """One row per dataset config for :func:`maglev.lab.records.length_decision`."""
    rows = []
    for ds in datasets:
        raw = _raw(ds, data_dir)
        pp = ds["preprocess"]
        trim, k, split = int(pp["trim"]), int(pp["decimate"]), float(pp["split"])
        n = -(-(raw.N - trim) // k)
        n_est = int(round(n * split))
        ts = raw.Ts * k
        rows.append({"dataset": ds["name"], "transient_s": start_transient(raw.y, raw.Ts).seconds,
                     "trim_s": trim * raw.Ts, "split": split, "est_s": n_est * ts, "val_s": (n - n_est) * ts})
    return rows


def alpha_rows(datasets: list[dict], data_dir: str) -> list[dict]:
    """One row per binary dataset: α from its switching rate on the recorded axis, its design value."""
    rows = []
    for ds in datasets:
        if ds["input_class"] != "binary":
            continue
        raw = _raw(ds, data_dir)
        u = raw.u[int(ds["preprocess"]["trim"]):]
        design = ds.get("alpha") if ds["source"] == "sim" else DESIGN_ALPHA.get(ds["name"].removeprefix("real_"))
        rows.append({"dataset": ds["name"], "alpha": switching_rate(u),
                     "design": None if design is None else float(design), "samples": int(u.size)})
    return rows


# ------------------------------------------------------------------------------------- the sweep's decisions
def _unique_datasets(jobs: list[dict]) -> list[dict]:
    seen: dict[str, dict] = {}
    for cfg in jobs:
        seen.setdefault(cfg["dataset"]["name"], cfg["dataset"])
    return list(seen.values())


# The simulated lab's set of records (like the 2022 set: uniform noise over several ranges and offsets, one of
# them beyond the working region; random binary signals at every α of the lab's Fig. 5 over the lab's region and
# over part of it), 24 s at 1 ms each: name -> (input class, low A, high A, α, seed).  The records rule chooses
# the simulated sweep's datasets from it as it chooses the real sweep's from the 2022 set; conf/dataset's
# uniform_wide, uniform_narrow and binary_a025 are its choice on the default plant (tests/study/test_decisions.py).
SIM_RECORDS: dict[str, tuple[str, float, float, float | None, int]] = {
    "sim_uniform_1.75-2.5": ("uniform", 1.75, 2.5, None, 31),
    "sim_uniform_1.5-3": ("uniform", 1.5, 3.0, None, 32),
    "sim_uniform_1.75-3.25": ("uniform", 1.75, 3.25, None, 11),
    "sim_uniform_1.5-3.5": ("uniform", 1.5, 3.5, None, 12),
    "sim_uniform_1.5-4": ("uniform", 1.5, 4.0, None, 33),
    "sim_binary_1.5-3.5_a0.25": ("binary", 1.5, 3.5, 0.25, 41),
    "sim_binary_1.75-3.25_a0.25": ("binary", 1.75, 3.25, 0.25, 42),
    "sim_binary_2-3_a0.25": ("binary", 2.0, 3.0, 0.25, 13),
    **{f"sim_binary_{r}_a{a:g}": ("binary", lo, hi, a, seed)
       for a, base in ((0.5, 50), (0.75, 60), (1.0, 70))
       for r, lo, hi, seed in (("1.5-3.5", 1.5, 3.5, base + 1), ("2-3", 2.0, 3.0, base + 2))},
}
SIM_RECORD_S, SIM_RECORD_TS = 24.0, 0.001


def _sim_candidate(name: str) -> dict:
    cls, low, high, alpha, seed = SIM_RECORDS[name]
    return {"name": name, "source": "sim", "input_class": cls, "low": low, "high": high, "alpha": alpha,
            "duration_s": SIM_RECORD_S, "seed": seed, "Ts": SIM_RECORD_TS}


@functools.lru_cache(maxsize=4)
def assessed_sim(plant: str, region: tuple[float, float], curve: tuple[float, float],
                 fraction: float = 0.8) -> tuple[tuple[RecordAssessment, ...], float, str]:
    """(every record of :data:`SIM_RECORDS` simulated on ``plant`` and measured against the working ``region``
    and the static ``curve``, α*, the uniform record it comes from): α* from the output spectrum of the rule's
    best uniform record on its recorded sample axis, as on the 2022 set."""
    from maglev.study.datasets import load_raw

    raws = {n: load_raw({**_sim_candidate(n), "plant": plant}, "") for n in SIM_RECORDS}
    assessed = tuple(assess(n, SIM_RECORDS[n][0], d.u, d.y, d.Ts, region, curve) for n, d in raws.items())
    first = choose_records(assessed, None, {"uniform": 1}).choice["uniform"]
    if not first:
        raise ValueError(f"no simulated uniform record passes the record rule on plant {plant!r}")
    d = raws[first[0]]
    _, alpha = alpha_star_of(d, start_transient(d.y, d.Ts).samples, fraction)
    return assessed, float(alpha.alpha_star), first[0]


def _same_record(ds: dict, name: str, plant: str) -> bool:
    from maglev.study.datasets import plant_name, sim_spec

    return plant_name(ds) == plant and sim_spec(ds) == sim_spec(_sim_candidate(name))


def sim_records(datasets: list[dict], wr: WorkingRegion, data_dir: str) -> Decision:
    """The records decision of a simulated sweep: the records rule's choice from :data:`SIM_RECORDS` simulated
    on the sweep's plant; a candidate that is one of the sweep's datasets carries the dataset's name.  When the
    sweep's datasets are not the rule's choice (a ``dataset=`` override) the decision is forced, and a dataset
    outside the set is measured beside the candidates (its row and any refusal as a caution)."""
    from maglev.study.datasets import plant_name

    region, curve = (wr.u_min, wr.u_max), (float(wr.y_bar.min()), float(wr.y_bar.max()))
    plant = plant_name(datasets[0])
    assessed, alpha_star, best = assessed_sim(plant, region, curve)
    names = {n: next((ds["name"] for ds in datasets if _same_record(ds, n, plant)), n) for n in SIM_RECORDS}
    assessed = [replace(a, name=names[a.name]) for a in assessed]
    extra = [ds for ds in datasets if ds["name"] not in names.values()]
    measured = [assess(ds["name"], ds["input_class"], raw.u, raw.y, raw.Ts, region, curve)
                for ds in extra for raw in [_raw(ds, data_dir)]]
    dec = choose_records(assessed, alpha_star)
    chosen = sorted(n for names_ in dec.choice.values() for n in names_)
    sweep = sorted(ds["name"] for ds in datasets)
    head = [f"The rule chooses from the {len(SIM_RECORDS)} simulated lab records on plant {plant}. α* = "
            f"{alpha_star:g}, from the output spectrum of {names[best]} on its recorded sample axis."]
    if sweep != chosen:
        dec = choose_records(assessed, alpha_star, forced=sweep)
    dec.reasons[:0] = head
    for a in measured:
        verdict = "refused: " + "; ".join(a.refusals) if a.refusals else "passes the rule"
        dec.evidence.append({**a.row(), "verdict": f"outside the simulated set, {verdict}; used: forced by the config"})
    dec.cautions.extend(f"{a.name} is forced by the config although the rule refuses it: " + "; ".join(a.refusals)
                        + "." for a in measured if a.refusals)
    return dec


def delay_of(datasets: list[dict], data_dir: str, response, max_order: int, max_delay: int,
             configured: int | None) -> Decision:
    """The delay decision (:func:`maglev.lab.delay.delay_decision`) over the sweep's datasets, with the
    staircase's averaged step ``response`` (recorded samples; None without one)."""
    from maglev.estimation.selection import delayest
    from maglev.lab.delay import dead_time, delay_decision
    from maglev.study.datasets import load

    parts, de = [], {}
    for ds in datasets:
        prep = load(ds, data_dir)
        parts.append((ds["name"], prep.est, prep.val))
        de[ds["name"]] = delayest(prep.est, 2, 2, 0, max_delay)
    k = int(datasets[0]["preprocess"]["decimate"])
    dead = None if response is None else dead_time(response) / k
    return delay_decision(parts, dead, de, max_order, configured)


def sweep_decisions(task: dict, jobs: list[dict], wr: WorkingRegion, u_sat: float | None,
                    step_response=None) -> dict[str, Decision]:
    """The pre-run decisions of a sweep (working region, records, data length, α, delay) from its task
    config, its jobs' configs, the staircase's working region, the physical model's saturation current and
    the staircase's averaged step response."""
    from maglev.lab.working_region import region_decision

    data_dir = task["data_dir"]
    datasets = _unique_datasets(jobs) or [task["dataset"]]
    out = {"working_region": region_decision(wr, u_sat)}
    if all(ds["source"] == "sim" for ds in datasets):
        out["records"] = sim_records(datasets, wr, data_dir)
    else:
        names = tuple(sorted(ds["name"] for ds in datasets))
        staircase = task["lab"].get("staircase_file")
        rule = records_2022(str(data_dir), staircase)
        chosen = tuple(sorted(n for names_ in rule.choice.values() for n in names_))
        out["records"] = rule if names == chosen else records_2022(str(data_dir), staircase, forced=names)
    out["data_length"] = length_decision(length_rows(datasets, data_dir))
    alphas = alpha_rows(datasets, data_dir)
    if alphas:
        out["alpha"] = alpha_decision(alphas)
    nks = {int(cfg["structure"]["nk"]) for cfg in jobs} or {int(task["structure"]["nk"])}
    out["delay"] = delay_of(datasets, data_dir, step_response, int(task["lab"]["max_order"]),
                            int(task["lab"]["max_delay"]), nks.pop() if len(nks) == 1 else None)
    return out


# ------------------------------------------------------------------------------------- orders, after the runs
PHYSICS_ORDER = 4  # states of the physical model (two masses, positions and velocities: plant-physics notes)


def orders_of_table(table) -> Decision | None:
    """The orders decision (:func:`maglev.lab.orders.orders_decision`) of a ranked sweep's table: per structure
    the mean validation simulation FIT, AIC, distance to the BLA and near pole-zero cancellations by order over
    the datasets swept at every order (as :func:`maglev.study.cautions.order_choice` averages them); None with
    fewer than two orders."""
    from maglev.lab.orders import orders_decision

    if table is None or table.empty or not {"structure", "order", "dataset", "val_fit_sim"} <= set(table):
        return None
    from maglev.study.cautions import mean_by_order

    fit, aic, bla, cancel = {}, {}, {}, {}
    for st, runs in table.groupby("structure", sort=False):
        by = runs.pivot_table(index="dataset", columns="order", values="val_fit_sim", aggfunc="mean").dropna()
        if by.shape[1] < 2 or by.empty:
            continue
        fit[str(st)] = {int(o): float(v) for o, v in by.mean().sort_index().items()}
        if "aic" in runs:
            a = runs[runs["dataset"].isin(by.index)].groupby("order")["aic"].mean()
            aic[str(st)] = {int(o): float(v) for o, v in a.items() if int(o) in fit[str(st)]}
        bla[str(st)] = mean_by_order(runs, "g_bla_err")[0]
        cancel[str(st)] = mean_by_order(runs, "near_cancellations", list(by.index))[0]
    return orders_decision(fit, aic, PHYSICS_ORDER, bla=bla, cancellations=cancel) if fit else None


def with_orders(content: dict | None, orders: Decision | None) -> dict | None:
    """A ``decisions.json`` content with the ranked runs' ``orders`` decision (:func:`orders_of_table`) added
    (None when there is none); the caller logs it on the parent run again, whole."""
    from maglev.lab.decision import write_decisions

    if orders is None:
        return None
    return {**(content or {}), **write_decisions([orders])}
