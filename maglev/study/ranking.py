"""Rank a sweep's models by validation FIT and compute the lab's comparisons (§3.7) for the ranking run.

Reads the FINISHED model runs of a sweep (:mod:`maglev.study.store`), ranks them by
``val_fit`` — ties go to the simpler model (fewer ``n_params``) — and builds what the
ranking run logs (:func:`log_ranking`; ``kind=ranking``, tag ``sweep_parent``; not a
child, so the sweep's run counts stay those of its models): the full table and the top
four (CSV and Markdown; column ``final_order``: whether the run's order is its structure's
final order by the orders decision, :mod:`maglev.lab.orders`), best vs worst (Bode, pole-zero maps, residual correlations)
and, for one structure, binary- vs uniform-input models (FIT table and plot, plus FIT of
every such model on every one of their validation sets, so they are also compared on
the same data).  ``maglev rank`` and the end-of-sweep callback call it.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np
import pandas as pd

from maglev.study.cautions import Caution, cautions
from maglev.study.store import Sweep, SweepError, artifact_bytes, artifact_json, dataset_configs
from maglev.study.tracking import log_files
from maglev.validation import ResidResult

TOP = 4
TABLE_COLUMNS = ["rank", "name", "structure", "orders", "dataset", "input_class", "val_fit", "val_fit_naive",
                 "val_fit_sim", "n_params", "final_order", "val_dataset", "aic", "whiteness_pvalue",
                 "independence_pvalue", "run_id"]


# ---------------------------------------------------------------------------- ranking
def rank_table(runs: pd.DataFrame) -> pd.DataFrame:
    """Runs ordered by ``val_fit`` (descending), ties to fewer ``n_params``, then by name; with ``rank``."""
    t = runs.copy()
    for col in TABLE_COLUMNS[1:]:
        if col not in t:
            t[col] = math.nan
    t = t.sort_values(["val_fit", "n_params", "name"], ascending=[False, True, True], na_position="last",
                      kind="mergesort").reset_index(drop=True)
    t.insert(0, "rank", np.arange(1, len(t) + 1))
    t["n_params"] = t["n_params"].round().astype("Int64")
    t["order"] = [model_order(o) for o in t["orders"]]
    return t[TABLE_COLUMNS + [c for c in t.columns if c not in TABLE_COLUMNS]]


def mark_final_orders(table: pd.DataFrame, orders) -> pd.DataFrame:
    """``table`` with ``final_order``: whether each run's order is its structure's final order in the orders
    decision ``orders`` (:class:`maglev.lab.decision.Decision` or None); a structure the decision does not cover
    (swept at one order) has nothing to choose between, so each of its runs is at its final order."""
    choice = orders.choice if orders is not None else {}
    t = table.copy()
    t["final_order"] = [st not in choice or o == choice[st] for st, o in zip(t["structure"], t["order"])]
    return t


def model_order(orders: str) -> float:
    """The largest polynomial order of a MATLAB order vector string (``"[3 3 3 3 2]"`` → 3; nk excluded)."""
    try:
        values = [int(v) for v in str(orders).strip("[]").split()][:-1]
    except ValueError:
        return math.nan
    return float(max(values)) if values else math.nan


def validation_note(table: pd.DataFrame) -> str | None:
    """A warning when the rows were validated on different data (their FITs are then not strictly comparable)."""
    sets = list(dict.fromkeys(table["val_dataset"]))
    if len(sets) <= 1:
        return None
    return f"validated on different data ({', '.join(sets)}): compare FIT within one validation set"


def choose_structure(table: pd.DataFrame, structure: str | None = None) -> str | None:
    """The structure of the binary-vs-uniform comparison: ``structure`` (checked), else the best-fitting
    structure having both binary- and uniform-input runs (None when no structure has both)."""
    classes = table.groupby("structure")["input_class"].agg(lambda s: set(s))
    both = [s for s, c in classes.items() if {"binary", "uniform"} <= c]
    if structure is not None:
        if structure not in classes:
            raise SweepError(f"--structure {structure}: the sweep has no FINISHED {structure} runs "
                             f"(structures: {', '.join(classes.index)})")
        if structure not in both:
            raise SweepError(f"--structure {structure}: needs both binary- and uniform-input runs, has only "
                             f"{', '.join(sorted(classes[structure]))} (structures with both: "
                             f"{', '.join(both) or 'none'})")
        return structure
    if not both:
        return None
    return max(both, key=lambda s: (table.loc[table["structure"] == s, "val_fit"].max(), s))


def comparison_table(table: pd.DataFrame, structure: str) -> pd.DataFrame:
    """The ranked runs of one structure, by orders then input class (binary first)."""
    t = table[table["structure"] == structure]
    return t.sort_values(["orders", "input_class", "dataset"]).reset_index(drop=True)


def common_validation(configs: dict[str, dict], runs: pd.DataFrame, models: dict) -> pd.DataFrame:
    """FIT % of every run in ``runs`` on the validation data of every dataset in ``runs`` (rows: run names).

    The lab compares input signals on the *same* validation data; each run was validated
    on its own dataset's, so the others are rebuilt from the runs' logged configs
    (``configs``: dataset name -> a run config).  A cell is NaN when the sampling periods differ.
    """
    from maglev.study.datasets import load
    from maglev.validation import compare

    names = sorted(set(runs["dataset"]))
    data = {n: load(configs[n]["dataset"], configs[n]["data_dir"]) for n in names}
    horizon = int(configs[names[0]]["study"]["val_horizon"])
    out = pd.DataFrame(index=list(runs["name"]), columns=[f"{n}[val]" for n in names], dtype=float)
    for _, row in runs.iterrows():
        model = models[row["run_id"]]
        for n in names:
            if math.isclose(data[n].val.Ts, model.Ts, rel_tol=1e-9):
                out.loc[row["name"], f"{n}[val]"] = compare(data[n].val, model, horizon)[0]
    return out


# ---------------------------------------------------------------------------- the result
@dataclass
class Ranking:
    """A ranked sweep with the lab's comparisons; ``files`` are the artifacts (path -> text or PNG bytes)."""

    sweep: Sweep
    table: pd.DataFrame
    structure: str | None
    comparison: pd.DataFrame | None
    common: pd.DataFrame | None
    models: dict  # run id -> PolyModel (best, worst and the compared runs)
    orders: Any  # the orders decision of the ranked runs (maglev.lab.decision.Decision), None without one
    configs: dict  # dataset name -> the logged config of one of its runs
    resids: dict  # run id -> ResidResult (best and worst)
    notes: list[str] = field(default_factory=list)
    cautions: list[Caution] = field(default_factory=list)
    files: dict[str, Any] = field(default_factory=dict)

    @property
    def top(self) -> pd.DataFrame:
        return self.table.head(TOP)

    @property
    def best(self) -> pd.Series:
        return self.table.iloc[0]

    @property
    def worst(self) -> pd.Series:
        return self.table.iloc[-1]

    @property
    def ranked_hash(self) -> str:
        """Identity of what was ranked (the run ids and the compared structure)."""
        text = " ".join(sorted(self.table["run_id"])) + f" {self.structure}"
        return hashlib.sha1(text.encode()).hexdigest()


def run_resid(sweep: Sweep, row: pd.Series, model):
    """The run's residual analysis: its ``resid/resid.json``, else recomputed from its logged config."""
    logged = sweep.artifact_json(row["run_id"], "resid/resid.json")
    if logged is not None:
        return ResidResult.from_dict(logged)
    from maglev.study.datasets import load
    from maglev.validation import resid

    cfg = sweep.config(row["run_id"])
    prep = load(cfg["dataset"], cfg["data_dir"])
    return resid(prep.val, model, lags=int(cfg["study"]["resid_lags"]))


def compute(sweep: Sweep, structure: str | None = None, common: bool = True, draw: bool = True,
            ranked: Ranking | None = None) -> Ranking:
    """Rank the sweep, load best/worst (and the compared runs) and draw the ranking's figures; with
    ``draw=False`` only the table, the comparison's choice and the cautions (enough for :func:`top_text`
    and :func:`previous_ranking_run`).  ``ranked``: that ``draw=False`` ranking of this sweep and
    ``structure``, made already (the end of a sweep asks it first): its table, comparison and cautions are
    taken as they are."""
    from maglev.study.decisions import orders_of_table
    from maglev.study import render
    from maglev.study.figures import best_worst_figures, comparison_figure, png, pngs

    if ranked is None:
        table = rank_table(sweep.runs)
        orders = orders_of_table(table)
        table = mark_final_orders(table, orders)
        chosen = choose_structure(table, structure)
        notes = []
        if chosen is None:
            notes.append("no structure has both binary- and uniform-input runs: no binary vs uniform comparison")
        comp = comparison_table(table, chosen) if chosen else None
        ranked = Ranking(sweep=sweep, table=table, structure=chosen, comparison=comp, common=None, models={},
                         orders=orders, configs={}, resids={}, notes=notes,
                         cautions=sweep_cautions(sweep, table, comp))
    if not draw:
        return ranked
    table, chosen, comp, notes = ranked.table, ranked.structure, ranked.comparison, list(ranked.notes)
    wanted = [table.iloc[0], table.iloc[-1]] + ([r for _, r in comp.iterrows()] if comp is not None else [])
    models = {r["run_id"]: sweep.model(r["run_id"]) for r in wanted}
    best, worst = table.iloc[0], table.iloc[-1]
    resids = {r["run_id"]: run_resid(sweep, r, models[r["run_id"]]) for r in (best, worst)}
    named = {k: replace(models[r["run_id"]], name=f"{k}: {r['name']}") for k, r in (("best", best), ("worst", worst))}
    drawn = render.offload(pngs, best_worst_figures, named["best"], named["worst"], resids[best["run_id"]],
                           resids[worst["run_id"]], best["val_fit"], worst["val_fit"])  # while the datasets are made
    configs, cross = {}, None
    try:
        configs = dataset_configs(sweep)
        if comp is not None and common:
            cross = common_validation(configs, comp, models)
    except (SweepError, OSError, ValueError) as exc:  # e.g. a record no longer where it was
        notes.append(f"datasets not rebuilt (no FIT on common validation data): {exc}")
    ranking = Ranking(sweep=sweep, table=table, structure=chosen, comparison=comp, common=cross,
                      models=models, orders=ranked.orders, configs=configs, resids=resids, notes=notes,
                      cautions=ranked.cautions)
    compared = png(comparison_figure(comp, cross, chosen)) if comp is not None else None
    made = tables(ranking)
    ranking.files.update({f"best_vs_worst/{k}.png": v for k, v in drawn().items()})
    if compared is not None:
        ranking.files["binary_vs_uniform/fit.png"] = compared
    ranking.files.update(made)
    return ranking


def sweep_cautions(sweep: Sweep, table: pd.DataFrame, comparison: pd.DataFrame | None) -> list[Caution]:
    """The cautions of the ranked table, with the sweep's working point and the compared datasets' mean inputs."""
    lab = sweep.parent.data.metrics
    compared = comparison if comparison is not None else table
    u0 = compared.groupby("dataset")["u0"].first().dropna().to_dict() if "u0" in compared else {}
    width = lab.get("lab.u_max", math.nan) - lab.get("lab.u_min", math.nan)
    return cautions(table, u0, lab.get("lab.u_star"), width if math.isfinite(width) else None)


# ---------------------------------------------------------------------------- tables
def markdown(df: pd.DataFrame, digits: int = 2) -> str:
    """A GitHub Markdown table (floats with ``digits`` decimals, NaN as empty)."""
    def cell(v) -> str:
        if isinstance(v, (float, np.floating)):
            return "" if math.isnan(v) else f"{v:.{digits}f}" if abs(v) < 1e6 else f"{v:.4g}"
        return str(v).replace("|", "\\|")

    head = "| " + " | ".join(map(str, df.columns)) + " |"
    rule = "|" + "---|" * len(df.columns)
    rows = ["| " + " | ".join(cell(v) for v in row) + " |" for row in df.itertuples(index=False)]
    return "\n".join([head, rule, *rows]) + "\n"


def tables(r: Ranking) -> dict[str, str]:
    """The ranking's CSV and Markdown artifacts."""
    short = TABLE_COLUMNS
    out = {"ranking/table.csv": r.table.to_csv(index=False), "ranking/table.md": markdown(r.table[short]),
           "ranking/top4.csv": r.top[short].to_csv(index=False)}
    note = validation_note(r.top)
    out["ranking/top4.md"] = markdown(r.top[short]) + (f"\nNote: the top four were {note}.\n" if note else "")
    if r.comparison is not None:
        cols = ["rank", "name", "dataset", "input_class", "orders", "val_fit", "val_fit_sim", "n_params",
                "val_dataset"]
        out["binary_vs_uniform/table.csv"] = r.comparison[cols].to_csv(index=False)
        md = markdown(r.comparison[cols])
        note = validation_note(r.comparison)
        if note:
            md += f"\nNote: these runs were {note}.\n"
        if r.common is not None:
            out["binary_vs_uniform/common_validation.csv"] = r.common.to_csv(index_label="model")
            md += "\nFIT % of each model on each validation set:\n\n" + markdown(
                r.common.reset_index(names="model"))
        out["binary_vs_uniform/table.md"] = md
    out["cautions/cautions.json"] = json.dumps([asdict(c) for c in r.cautions], indent=1, default=str)
    out["cautions/cautions.md"] = "".join(f"- {c.text}\n" for c in r.cautions) or "No caution applies.\n"
    return out


def final_text(row) -> str:
    """Whether a ranked run's order is its structure's final order (column ``final_order``), in two words."""
    final = row.get("final_order")
    return "" if final is None or pd.isna(final) else "final order" if bool(final) else "not the final order"


def top_text(r: Ranking) -> str:
    """The top four as plain text for the terminal."""
    lines = [f"Top {min(TOP, len(r.table))} of {len(r.table)} FINISHED runs of sweep {r.sweep.name!r} "
             f"(parent {r.sweep.parent_id}), by one-step validation FIT (naive y(t-1) and simulation FIT beside):"]
    for _, row in r.top.iterrows():
        lines.append(f"  {row['rank']}. {row['val_fit']:7.2f} %  {row['name']:<32s}  "
                     f"naive {row['val_fit_naive']:6.2f} %  sim {row['val_fit_sim']:7.2f} %  "
                     f"n_params={int(row['n_params']) if not pd.isna(row['n_params']) else '?'}  "
                     f"val: {row['val_dataset']}  {final_text(row)}")
    note = validation_note(r.top)
    if note:
        lines.append(f"  note: {note}")
    lines.append(f"  best {r.best['name']} ({r.best['val_fit']:.2f} %), worst {r.worst['name']} "
                 f"({r.worst['val_fit']:.2f} %)")
    if r.sweep.ignored:
        lines.append("  ignored: " + ", ".join(f"{n} {s}" for s, n in sorted(r.sweep.ignored.items())))
    if r.cautions:
        lines.append(f"Cautions ({len(r.cautions)}):")
        lines += [f"  - {c.text}" for c in r.cautions]
    return "\n".join(lines)


# ---------------------------------------------------------------------------- the ranking run
def log_ranking(r: Ranking) -> str:
    """Log the ranking as a new FINISHED run (``kind=ranking``, source ``maglev rank``, which the end-of-sweep
    ranking runs as well); tag the parent with its id and describe both; return the id."""
    from maglev.study import tracking

    client = r.sweep.client
    tags = {"kind": "ranking", "sweep": r.sweep.name, "sweep_parent": r.sweep.parent_id,
            "best_run": r.best["run_id"], "worst_run": r.worst["run_id"], "best_run_name": r.best["name"],
            "worst_run_name": r.worst["name"], "compared_structure": r.structure or "",
            "ranked_hash": r.ranked_hash, **tracking.process_tags(), **tracking.source_tags("maglev rank")}
    run_id = client.create_run(r.sweep.experiment_id, run_name=f"ranking · {r.sweep.name}", tags=tags).info.run_id
    metrics = {"n_ranked": len(r.table), "best_val_fit": r.best["val_fit"], "worst_val_fit": r.worst["val_fit"],
               "n_cautions": len(r.cautions)}
    metrics.update({f"top{i + 1}_val_fit": v for i, v in enumerate(r.top["val_fit"])})
    metrics.update({f"ignored_{s.lower()}": n for s, n in r.sweep.ignored.items()})
    tracking.log_batch(client, run_id, metrics=metrics, tags={tracking.NOTE: ranking_description(r, run_id)})
    log_files(client, run_id, r.files)
    client.set_terminated(run_id, "FINISHED")
    tracking.log_batch(client, r.sweep.parent_id, tags={"ranking_run": run_id})
    describe_sweep(client, r.sweep.parent_id)
    return run_id


def report_name(sweep: Sweep) -> str:
    """The sweep's report file name (:func:`maglev.study.config.report_file_name`) from its name and
    ``sweep_id`` as the store has them (the parent run id for a parent without one): two sweeps of one name
    never overwrite each other's report, and a relaunch of the same sweep updates its own.  Both are read back
    from the store, where anyone may have set them, and made plain file names, so ``--out DIR`` always writes
    in DIR."""
    from maglev.study.config import report_file_name

    return report_file_name(sweep.name, sweep.parent.data.tags.get("sweep_id") or sweep.parent_id)


def previous_ranking_run(r: Ranking) -> str | None:
    """The latest ranking run of the sweep that ranked exactly these runs (same ``ranked_hash``), if any."""
    sweep = r.sweep
    found = sweep.client.search_runs(
        [sweep.experiment_id], order_by=["attributes.start_time DESC"], max_results=1,
        filter_string=(f"tags.kind = 'ranking' and tags.sweep_parent = '{sweep.parent_id}' "
                       f"and tags.ranked_hash = '{r.ranked_hash}' and attributes.status = 'FINISHED'"))
    return found[0].info.run_id if found else None


# ---------------------------------------------------------------------------- descriptions
def _link(exp_id: str, run_id: str, text: str) -> str:
    from maglev.study.tracking import run_link

    return f"[{text.replace('[', '(').replace(']', ')')}]({run_link(exp_id, run_id)})"


def top_markdown(exp_id: str, top: pd.DataFrame) -> str:
    """The top four as a Markdown table whose names link to the runs."""
    lines = ["| # | run | val FIT % | naive % | sim FIT % | parameters | validated on | order |",
             "|---|---|---|---|---|---|---|---|"]
    for _, row in top.iterrows():
        n = "?" if pd.isna(row["n_params"]) else int(row["n_params"])
        lines.append(f"| {int(row['rank'])} | {_link(exp_id, row['run_id'], row['name'])} | {row['val_fit']:.2f} | "
                     f"{row['val_fit_naive']:.2f} | {row['val_fit_sim']:.2f} | {n} | {row['val_dataset']} | "
                     f"{final_text(row)} |")
    return "\n".join(lines) + "\n"


def ranking_description(r: Ranking, run_id: str) -> str:
    """The ranking run's description (Markdown): what was ranked, best and worst, the top four, the cautions."""
    exp = r.sweep.experiment_id
    ignored = ", ".join(f"{n} {s}" for s, n in sorted(r.sweep.ignored.items()))
    parts = [f"Ranking of sweep {r.sweep.name}: {len(r.table)} FINISHED model runs by one-step validation FIT "
             f"(ties to fewer parameters){f', {ignored} not ranked' if ignored else ''}. Best "
             f"{r.best['name']} ({r.best['val_fit']:.2f} %), worst {r.worst['name']} ({r.worst['val_fit']:.2f} %).",
             f"Sweep parent: {_link(exp, r.sweep.parent_id, r.sweep.name)}; best "
             f"{_link(exp, r.best['run_id'], r.best['name'])}, worst {_link(exp, r.worst['run_id'], r.worst['name'])}.",
             "### Top four\n\n" + top_markdown(exp, r.top)]
    note = validation_note(r.top)
    if note:
        parts.append(f"The top four were {note}.")
    parts.append(f"### Cautions ({len(r.cautions)})\n\n" + ("".join(f"- {c.text}\n" for c in r.cautions)
                                                            or "No caution applies.\n"))
    if r.structure:
        parts.append(f"Binary vs uniform input compared for `{r.structure}`: `binary_vs_uniform/`.")
    parts += [f"Note: {n}" for n in r.notes]
    parts.append("Artifacts: `ranking/table.md` (every ranked run), `best_vs_worst/`, `cautions/`, and the lab "
                 f"report `report/{report_name(r.sweep)}` (`maglev report`). Run id {run_id}.")
    return "\n\n".join(parts) + "\n"


def swept(kids: list) -> str:
    """What a sweep varied, from its model runs' tags: datasets, structures, largest polynomial orders (each in
    the order the runs started; per structure when the structures were swept over different orders)."""
    kids = sorted(kids, key=lambda r: r.info.start_time)

    def values(tag: str) -> list[str]:
        return list(dict.fromkeys(r.data.tags.get(tag, "?") for r in kids))

    ds, st = values("dataset"), values("structure")
    grids: dict[str, set[int]] = {s: set() for s in st}
    for r in kids:
        o = model_order(r.data.tags.get("orders", ""))
        if not math.isnan(o):
            grids[r.data.tags.get("structure", "?")].add(int(o))

    def listed(orders: set[int]) -> str:
        return ", ".join(map(str, sorted(orders))) or "?"

    if len({frozenset(g) for g in grids.values()}) > 1:
        orders_text = "(" + "; ".join(f"{s}: {listed(grids[s])}" for s in st) + ")"
    else:
        orders_text = listed(set().union(*grids.values()))
    return (f"{len(ds)} dataset(s) ({', '.join(ds)}) × {len(st)} structure(s) ({', '.join(st)}) × "
            f"orders {orders_text}")


def describe_sweep(client, parent_id: str) -> None:
    """Describe a sweep's parent run (Markdown): what was swept and how the runs ended; with its ranking run
    (tag ``ranking_run``) the best model, the top four with links and the cautions; also its source."""
    from maglev.study import claims, tracking

    parent = client.get_run(parent_id)
    exp, name = parent.info.experiment_id, parent.data.tags.get("sweep") or parent.info.run_name
    kids = [r for r in tracking.children(client, exp, parent_id) if r.data.tags.get("kind") == "model"]
    counts: dict[str, int] = {}
    for r in kids:
        counts[r.info.status] = counts.get(r.info.status, 0) + 1
    status = ", ".join(f"{n} {s}" for s, n in sorted(counts.items())) or "none yet"
    head = f"Sweep {name}: {len(kids)} model runs ({status})"
    head += f" of {swept(kids)}" if kids else ""
    refs = claims.referenced(client, exp, parent_id)  # configs other sweeps had run: ranked here too
    head += f", and {len(refs)} run(s) of other sweeps with the same configs." if refs else "."
    overrides = parent.data.tags.get("hydra.overrides", "")
    parts = [head, f"Launched with `python study.py -m {overrides}`." if overrides else ""]
    ranking_id = parent.data.tags.get("ranking_run")
    ranking = client.get_run(ranking_id) if ranking_id else None
    top = artifact_bytes(client, ranking_id, "ranking/top4.csv") if ranking else None
    if top is not None:
        table = pd.read_csv(io.BytesIO(top))
        best = table.iloc[0]
        parts[0] += (f" Best {best['name']} with one-step validation FIT {best['val_fit']:.2f} % "
                     f"(ranking run {_link(exp, ranking_id, ranking.info.run_name)}).")
        parts.append("### Top four\n\n" + top_markdown(exp, table))
        cautions_ = artifact_json(client, ranking_id, "cautions/cautions.json") or []
        parts.append(f"### Cautions ({len(cautions_)})\n\n" + ("".join(f"- {c['text']}\n" for c in cautions_)
                                                               or "No caution applies.\n"))
    else:
        parts.append(f"Not ranked yet: `maglev rank --parent {parent_id}`.")
    parts.append("Lab-level steps (working region, rise time and Ts, output spectrum, α*): metrics `lab.*` and "
                 "figures under `lab/`.")
    tracking.log_batch(client, parent_id, tags={tracking.NOTE: "\n\n".join(p for p in parts if p) + "\n",
                                                **tracking.source_tags("study.py")})


def ui_hint(sweep: Sweep, run_id: str) -> str:
    """How to look at a run in the MLflow UI (``maglev ui`` starts it on a local store)."""
    from maglev.study.tracking import run_link

    link = run_link(sweep.experiment_id, run_id)
    if sweep.uri.startswith("sqlite:///"):
        return f"maglev ui --tracking-uri {sweep.uri}   # then open http://127.0.0.1:5000/{link}"
    return f"{sweep.uri.rstrip('/')}/{link}"
