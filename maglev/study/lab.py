"""The lab-level steps of a sweep (EL2820 Lab 3 §3.1–3.4), computed once per sweep.

Working region from a staircase (simulated or the real record), rise time and the
advised sampling period inside it, the output spectrum of the sweep's base dataset
and the binary signal's α*.  No Hydra or MLflow: returns numbers and figures for the
sweep callback to log on the parent run.
"""

from __future__ import annotations

from pathlib import Path

from maglev.data import IOData
from maglev.lab.input_design import choose_alpha, output_spectrum
from maglev.lab.sampling import rise_time
from maglev.lab.working_region import working_region
from maglev.study.datasets import load


def staircase(lab: dict, data_dir: str) -> IOData:
    if lab["staircase_file"]:
        path = Path(lab["staircase_file"])
        path = path if path.is_absolute() else Path(data_dir) / path
        if not path.is_file():
            raise FileNotFoundError(f"lab.staircase_file: {path} not found (data_dir={data_dir!r})")
        reader = IOData.from_csv if path.suffix.lower() == ".csv" else IOData.from_mat
        kwargs = {"Ts": 0.001} if path.suffix.lower() == ".csv" else {}
        return reader(path, u=lab["staircase_u"], y=lab["staircase_y"], name="working_region", **kwargs)
    from maglev.labdata import experiment

    return experiment("working_region")


def lab_steps(cfg: dict) -> tuple[dict, dict, dict]:
    """(metrics, figures, summary) of the lab steps for the resolved config ``cfg``."""
    lab = cfg["lab"]
    stairs = staircase(lab, cfg["data_dir"])
    n = stairs.N - stairs.N % int(lab["levels"])
    stairs = stairs.segment(0, n)
    wr = working_region(stairs.u, stairs.y, int(lab["levels"]), float(lab["tail"]))
    rt = rise_time(stairs, u_range=(wr.u_min, wr.u_max), tail=float(lab["tail"]))
    prep = load(cfg["dataset"], cfg["data_dir"])
    spec = output_spectrum(prep.data.y, float(lab["energy_fraction"]))
    alpha = choose_alpha(spec.band)
    metrics = {
        "lab.u_min": wr.u_min, "lab.u_max": wr.u_max, "lab.u_star": wr.u_star, "lab.slope": wr.slope,
        "lab.rise_time_samples": rt.samples, "lab.rise_time_s": rt.seconds,
        "lab.Ts_min": rt.ts_range[0], "lab.Ts_max": rt.ts_range[1], "lab.decimation": rt.decimation,
        "lab.band_low": spec.band[0], "lab.band_high": spec.band[1], "lab.alpha_star": alpha.alpha_star,
    }
    from maglev.lab import plots

    figures = {"working_region.png": plots.plot_working_region(wr), "rise_time.png": plots.plot_rise_time(rt),
               "output_spectrum.png": plots.plot_output_spectrum(spec), "alpha.png": plots.plot_alpha(alpha)}
    figures["output_spectrum.png"].axes[0].set_title(f"Output spectrum of {prep.name}", fontsize="medium")
    summary = {"staircase": lab["staircase_file"] or "simulated working_region",
               "spectrum_dataset": prep.name, **metrics,
               "alpha_shares": dict(zip(map(str, alpha.alphas), alpha.shares))}
    return metrics, figures, summary
