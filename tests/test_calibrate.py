"""Tests of maglev.calibrate: the simulator's defaults reproduce the real KTH records."""

import os
from pathlib import Path

import numpy as np
import pytest

from maglev import calibrate
from maglev.plant import Levitator

REAL = Path(os.environ.get("MAGLEV_REFDATA", Path(__file__).resolve().parents[1].parent / "shared" / "refdata"))
needs_real = pytest.mark.skipif(not (REAL / calibrate.KTH_2022).is_dir(),
                                reason=f"real lab records not found under {REAL} "
                                "(set MAGLEV_REFDATA to the shared refdata folder)")


def test_dominant_mode_converts_discrete_poles():
    Ts = 0.001
    s = -30 + 80j
    poles = np.exp(np.array([s, np.conj(s), -400.0]) * Ts)
    wn, zeta = calibrate.dominant_mode(poles, Ts)
    assert wn == pytest.approx(abs(s)) and zeta == pytest.approx(30 / abs(s))


def test_refdata_dir_honours_env(monkeypatch, tmp_path):
    monkeypatch.setenv("MAGLEV_REFDATA", str(tmp_path))
    assert calibrate.refdata_dir() == tmp_path
    monkeypatch.setenv("MAGLEV_REFDATA", str(tmp_path / "missing"))
    assert calibrate.refdata_dir() is None
    with pytest.raises(ValueError, match="record must be one of"):
        calibrate.load_record("no_such_record", tmp_path)


@needs_real
@pytest.mark.realdata
def test_defaults_reproduce_the_real_records():
    cmp = calibrate.compare(Levitator(zero_at_10=True), REAL, records=("binary_signal_3",))
    # static curve within 5 x the sensor noise std (rms over the 21 levels)
    assert cmp.static_rms <= cmp.static_tolerance
    std_r, peak_r, q_r = cmp.noise_real
    std_s, peak_s, q_s = cmp.noise_sim
    assert std_s == pytest.approx(std_r, rel=0.15)
    assert 0.30 <= peak_r <= 0.34 and abs(peak_s - peak_r) < 0.01
    assert q_s == pytest.approx(q_r, rel=1e-3)
    assert cmp.rise_sim == pytest.approx(cmp.rise_real, rel=0.25)
    assert cmp.alpha_sim == cmp.alpha_real
    (wn_r, z_r), (wn_s, z_s) = cmp.modes["binary_signal_3"]
    assert wn_s == pytest.approx(wn_r, rel=0.2)
    assert z_s == pytest.approx(z_r, rel=0.2)
    assert "rms" in cmp.table()


@needs_real
@pytest.mark.realdata
def test_static_fit_recovers_a_curve_close_to_the_real_one():
    stair = calibrate.load_record("working_region", REAL)
    start = Levitator(zero_at_10=True).with_params(a=0.5, b=2.0, n_coil=1.5, kappa=0.3, y_off=0.3, i_sat=4.0)
    fitted = calibrate.fit_static(stair, start)
    u_bar, y_bar = calibrate._stair_averages(stair)
    assert np.sqrt(np.mean((fitted.static_curve(u_bar) - y_bar) ** 2)) < 0.01
