"""The lab-level steps of a sweep (EL2820 Lab 3 §3.1–3.4), computed once per sweep.

Working region from a staircase (simulated or the real record), rise time and the
advised sampling period inside it, the output spectrum of the sweep's base dataset
and the binary signal's α*.  No Hydra or MLflow: returns numbers and figures for the
sweep callback to log on the parent run.
"""

from __future__ import annotations

from pathlib import Path

from maglev.data import IOData
from maglev.lab.sampling import rise_time
from maglev.lab.working_region import working_region
from maglev.sim.plant import DEFAULT_PLANT
from maglev.study.datasets import load, plant_name


def staircase(lab: dict, data_dir: str, plant: str) -> IOData:
    """The staircase record: ``lab.staircase_file``, else simulated on the parameter set ``plant``."""
    if lab["staircase_file"]:
        path = Path(lab["staircase_file"])
        path = path if path.is_absolute() else Path(data_dir) / path
        if not path.is_file():
            raise FileNotFoundError(f"lab.staircase_file: {path} not found (data_dir={data_dir!r})")
        reader = IOData.from_csv if path.suffix.lower() == ".csv" else IOData.from_mat
        kwargs = {"Ts": 0.001} if path.suffix.lower() == ".csv" else {}
        return reader(path, u=lab["staircase_u"], y=lab["staircase_y"], name="working_region", **kwargs)
    from maglev.sim.labdata import experiment
    from maglev.sim.plant import rig

    return experiment("working_region", plant=rig(plant), cache=True)


def lab_steps(cfg: dict, jobs: list[dict] | None = None) -> tuple[dict, dict, dict]:
    """(metrics, figures, summary) of the lab steps for the resolved config ``cfg`` of a sweep whose jobs'
    configs are ``jobs`` (default: ``cfg`` alone); ``summary["decisions"]`` is the ``decisions.json`` content
    (:mod:`maglev.lab.decision`)."""
    from maglev.lab.decision import write_decisions
    from maglev.sim.plant import rig
    from maglev.study.decisions import alpha_star_of, sweep_decisions

    lab = cfg["lab"]
    ds = cfg["dataset"]
    plant = plant_name(ds) if ds["source"] == "sim" else DEFAULT_PLANT
    stairs = staircase(lab, cfg["data_dir"], plant)
    n = stairs.N - stairs.N % int(lab["levels"])
    stairs = stairs.segment(0, n)
    wr = working_region(stairs.u, stairs.y, int(lab["levels"]), float(lab["tail"]))
    rt = rise_time(stairs, u_range=(wr.u_min, wr.u_max), tail=float(lab["tail"]))
    prep = load(cfg["dataset"], cfg["data_dir"])
    # α is a probability per recorded sample: the band is taken on the recorded (not decimated) axis
    spec, alpha = alpha_star_of(prep.raw, int(ds["preprocess"]["trim"]), float(lab["energy_fraction"]))
    orders = order_selection(prep, int(lab["max_order"]), int(lab["max_delay"]))
    decisions = sweep_decisions(cfg, jobs or [cfg], wr, rig(plant).params.i_sat, rt.response)
    metrics = {
        "lab.u_min": wr.u_min, "lab.u_max": wr.u_max, "lab.u_star": wr.u_star, "lab.slope": wr.slope,
        "lab.rise_time_samples": rt.samples, "lab.rise_time_s": rt.seconds,
        "lab.Ts_min": rt.ts_range[0], "lab.Ts_max": rt.ts_range[1], "lab.decimation": rt.decimation,
        "lab.band_low": spec.band[0], "lab.band_high": spec.band[1], "lab.alpha_star": alpha.alpha_star,
        **{f"lab.{k}": v for k, v in orders.items() if k != "table"},
    }
    from maglev.lab import plots
    from maglev.plots import plot_arxstruc

    figures = {"working_region.png": plots.plot_working_region(wr), "rise_time.png": plots.plot_rise_time(rt),
               "output_spectrum.png": plots.plot_output_spectrum(spec), "alpha.png": plots.plot_alpha(alpha),
               "orders.png": plot_arxstruc(orders["table"], [(orders["arx_na"], orders["arx_nb"], "AIC"),
                                                            (orders["arx_na_mdl"], orders["arx_nb_mdl"], "MDL")])}
    figures["orders.png"].axes[0].set_title(f"ARX orders on {prep.name} (nk = {orders['nk']} by delayest)",
                                            fontsize="medium")
    figures["output_spectrum.png"].axes[0].set_title(f"Output spectrum of {prep.name}", fontsize="medium")
    summary = {"staircase": lab["staircase_file"] or "simulated working_region",
               "spectrum_dataset": prep.name, **metrics,
               "alpha_shares": dict(zip(map(str, alpha.alphas), alpha.shares)),
               "arxstruc": orders["table"].to_dict(orient="records"), "decisions": write_decisions(decisions)}
    return metrics, figures, summary


def order_selection(prep, max_order: int, max_delay: int) -> dict:
    """MATLAB's order and delay selection on a dataset: ``delayest`` (ARX [2 2 nk], nk in 0..max_delay) on
    the estimation part, then ``arxstruc`` (na, nb in 1..max_order, that nk; losses on the validation
    part) and ``selstruc`` by AIC and by MDL: the orders the data suggest before any PEM model is fitted."""
    from maglev.estimation.selection import arxstruc, delayest, selstruc

    nk = delayest(prep.est, 2, 2, 0, max_delay)
    table = arxstruc(prep.est, prep.val, range(1, max_order + 1), range(1, max_order + 1), nk)
    na, nb, _ = selstruc(table, "aic")
    na_mdl, nb_mdl, _ = selstruc(table, "mdl")
    return {"nk": nk, "arx_na": na, "arx_nb": nb, "arx_na_mdl": na_mdl, "arx_nb_mdl": nb_mdl,
            "max_order": max_order, "table": table}
