"""Tests of maglev.calibrate (the fits) and maglev.refdata (where the real records are)."""

import os
from pathlib import Path

import numpy as np
import pytest

from maglev import calibrate, refdata
from maglev.plant import Levitator
from maglev.sim_vs_real import stair_averages

REAL = Path(os.environ.get("MAGLEV_REFDATA", Path(__file__).resolve().parents[1].parent / "shared" / "refdata"))
needs_real = pytest.mark.skipif(not (REAL / refdata.KTH_2022).is_dir(),
                                reason=f"real lab records not found under {REAL} "
                                "(set MAGLEV_REFDATA to the shared refdata folder)")


def test_refdata_dir_honours_env(monkeypatch, tmp_path):
    monkeypatch.setenv("MAGLEV_REFDATA", str(tmp_path))
    assert refdata.refdata_dir() == tmp_path
    monkeypatch.setenv("MAGLEV_REFDATA", str(tmp_path / "missing"))
    assert refdata.refdata_dir() is None
    with pytest.raises(ValueError, match="record must be one of"):
        refdata.load_record("no_such_record", tmp_path)


@needs_real
@pytest.mark.realdata
def test_static_fit_recovers_a_curve_close_to_the_real_one():
    stair = refdata.load_record("working_region", REAL)
    start = Levitator(zero_at_10=True).with_params(a=0.5, b=2.0, n_coil=1.5, kappa=0.3, y_off=0.3, i_sat=4.0)
    fitted = calibrate.fit_static(stair, start)
    u_bar, y_bar = stair_averages(stair)
    assert np.sqrt(np.mean((fitted.static_curve(u_bar) - y_bar) ** 2)) < 0.01


# ---------------------------------------------------------------------- dry friction (issue #3)
@needs_real
@pytest.mark.realdata
def test_friction_defaults_beat_the_viscous_only_calibration_on_the_fit_objective():
    targets = calibrate.friction_targets(REAL)
    fitted = Levitator(zero_at_10=True)
    viscous = fitted.with_params(coulomb_lower=0.0, coulomb_upper=0.0, stiction_lower=0.0, stiction_upper=0.0,
                                 gamma_lower=10.79, gamma_upper=1.009, t_phys=6.575e-3, noise_line_hz=103.96)
    r_fit = calibrate._friction_residual(fitted, targets)
    r_visc = calibrate._friction_residual(viscous, targets)
    assert r_fit @ r_fit < 0.5 * (r_visc @ r_visc)
    # one evaluation of the fit itself runs and returns a plant (maxfev=1: the start)
    out = calibrate.fit_friction(fitted, REAL, maxfev=1, targets=targets)
    for name in calibrate.FRICTION_PARAMS:
        assert getattr(out.params, name) == pytest.approx(getattr(fitted.params, name), rel=1e-12)
