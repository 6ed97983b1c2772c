"""Tests of maglev.lab (the lab's analysis steps) and maglev.sim.labdata (the simulated dataset)."""

import os
from pathlib import Path

import numpy as np
import pytest
from scipy import integrate

from maglev.lab.averages import get_average, get_stationary_averages
from maglev.lab.input_design import choose_alpha, output_spectrum
from maglev.lab.sampling import rise_time
from maglev.lab.working_region import working_region
from maglev.sim import labdata
from maglev.data import IOData
from maglev.sim.plant import PLANTS, Levitator, rig

STICK_SLIP = PLANTS["stick_slip"]  # the plant these tests' numbers were measured on
from maglev.lab.signals import rbs_spectrum, staircase
from maglev.sim.checks import RISE_TOLERANCE

REAL = Path(os.environ.get("MAGLEV_REFDATA", Path(__file__).resolve().parents[2].parent / "shared" / "refdata"))
KTH = REAL / "el2820_maglev_2022"
needs_real = pytest.mark.skipif(not KTH.is_dir(), reason=f"real lab records not found at {KTH} "
                                "(set MAGLEV_REFDATA to the shared refdata folder)")
LEVELS = np.arange(0.0, 10.5, 0.5)


@pytest.fixture(scope="module")
def sim_stair() -> IOData:
    return rig("stick_slip").simulate(staircase(LEVELS, 500), seed=5)


def test_get_average_and_stationary_averages():
    v = np.r_[np.zeros(6), np.ones(4)]
    assert get_average(v, 40) == 1.0
    assert get_average(v, 100) == 0.4
    y = np.r_[np.full(10, 3.0), np.full(10, 5.0)]
    y[:5] = 100.0  # transient at the start of the first level is ignored
    assert get_stationary_averages(y, 2, 50).tolist() == [3.0, 5.0]


@pytest.mark.parametrize("tail", [0, -5, 100.5])
def test_bad_tail_is_named(tail):
    with pytest.raises(ValueError, match=rf"tail must be a percentage in \(0, 100\], got {tail}"):
        get_average(np.ones(5), tail)


def test_staircase_not_multiple_of_nwr_is_named():
    with pytest.raises(ValueError, match="y_step has 10 samples, which is not a multiple of nwr=3"):
        get_stationary_averages(np.ones(10), 3, 50)


def test_working_region_on_a_known_curve():
    u_levels = np.arange(0, 11, 1.0)
    y_levels = np.clip(u_levels, 3, 7.5) * 2.0  # flat, linear from 3 to 7.5, flat
    u = staircase(u_levels, 20)
    y = staircase(y_levels, 20)
    wr = working_region(u, y, 11, 50)
    assert (wr.u_min, wr.u_max, wr.u_star) == (3.0, 7.0, 5.0)
    assert wr.slope == pytest.approx(2.0)
    # a level on the saturation plateau is never inside, even at the line's corner
    corner = working_region(u, staircase(np.clip(u_levels, 3, 7) * 2.0, 20), 11, 50)
    assert (corner.u_min, corner.u_max) == (3.0, 6.0)
    bent = y_levels.copy()
    bent[6] += 0.6  # a kink in the middle: a strict criterion splits the range
    strict = working_region(u, staircase(bent, 20), 11, 50, max_dev=0.02)
    assert strict.u_max - strict.u_min < 4.0


@needs_real
def test_working_region_of_the_real_staircase():
    data = IOData.from_mat(KTH / "working_region.mat")
    wr = working_region(data.u, data.y, 21, 50)
    assert 1.5 <= wr.u_min and wr.u_max <= 4.0 and wr.u_max - wr.u_min >= 2.0


def test_working_region_of_the_simulator_is_its_built_in_one(sim_stair):
    lev = rig("stick_slip")
    first_lifted = min(u for u in LEVELS if not lev.equilibrium(u).lower_seated)
    wr = working_region(sim_stair.u, sim_stair.y, 21, 50)
    # from the first level above lift-off to the last level below the regulator saturation
    assert wr.u_min == first_lifted
    assert wr.u_max < lev.params.i_sat <= wr.u_max + 0.5


def test_rise_time_of_a_known_first_order_step():
    tau = 20.0
    n = 400
    k = np.arange(n)
    resp = 1 - np.exp(-k / tau)
    u = np.r_[np.zeros(n), np.ones(n), np.zeros(n)]
    y = np.r_[np.zeros(n), resp, 1 - resp] + np.random.default_rng(0).normal(0, 0.02, 3 * n)
    rt = rise_time(IOData(u, y, 0.001))
    assert rt.n_steps == 2
    assert rt.samples == pytest.approx(tau * np.log(9), rel=0.1)
    lo, hi = rt.decimation_range
    assert 4 <= rt.samples / rt.decimation <= 10 and lo <= rt.decimation <= hi
    assert rt.ts_range[0] == pytest.approx(rt.seconds / 10)


@needs_real
def test_rise_time_and_alpha_agree_between_real_and_simulated_records(sim_stair):
    real = IOData.from_mat(KTH / "working_region.mat")
    r_real = rise_time(real, u_range=(1.5, 4.0))
    r_sim = rise_time(sim_stair, u_range=(1.5, 4.0))
    assert r_sim.samples == pytest.approx(r_real.samples, rel=RISE_TOLERANCE)
    assert r_sim.decimation == r_real.decimation
    wn = IOData.from_mat(KTH / "white_noise_4.mat").trim(0.25)
    wn_sim = Levitator(STICK_SLIP).simulate(wn.u, seed=2)
    a_real = choose_alpha(output_spectrum(wn.y).band).alpha_star
    a_sim = choose_alpha(output_spectrum(wn_sim.y).band).alpha_star
    assert a_real == a_sim


def test_output_spectrum_band_holds_a_sinusoid():
    n = 4096
    t = np.arange(n)
    y = np.sin(2 * np.pi * 200 / n * t) + 0.05 * np.random.default_rng(1).standard_normal(n)
    spec = output_spectrum(y, fraction=0.8)
    w0 = 2 * np.pi * 200 / n
    assert spec.band[0] <= w0 <= spec.band[1] and spec.band[1] - spec.band[0] < 0.01


def test_alpha_shares_match_the_integrated_spectrum_and_pick_the_right_alpha():
    band = (0.2, 0.9)
    choice = choose_alpha(band)
    for alpha, share in zip(choice.alphas, choice.shares):
        if 0 < alpha < 1:
            num, _ = integrate.quad(lambda w: rbs_spectrum(alpha, w), *band)
            assert share == pytest.approx(num / np.pi, rel=1e-6)
    assert choose_alpha((0.001, 0.1)).alpha_star == 0.25
    assert choose_alpha((2.8, np.pi)).alpha_star == 1.0
    assert choose_alpha((1.2, 1.9)).alpha_star == 0.5


def test_labdata_experiment_specs_and_catalogue(tmp_path):
    spec = labdata.ExperimentSpec("binary", 1.5, 3.0, alpha=0.25, duration_s=2.0, seed=4)
    d1, d2 = labdata.experiment(spec), labdata.experiment(spec)
    assert np.array_equal(d1.y, d2.y) and d1.N == 2000
    assert set(np.unique(d1.u)) == {1.5, 3.0}
    assert not np.array_equal(labdata.experiment(spec, seed=5).u, d1.u)
    stair = labdata.experiment("working_region")
    assert stair.N % 21 == 0 and stair.N * stair.Ts >= 20
    for name, s in labdata.CATALOGUE.items():
        assert s.duration_s >= 20, name
    assert {s.alpha for s in labdata.CATALOGUE.values() if s.kind == "binary"} == {0, 0.25, 0.5, 0.75, 1}
    with pytest.raises(ValueError, match="alpha must be a probability in \\[0, 1\\].*1.2"):
        labdata.ExperimentSpec("binary", 1.5, 3.0, alpha=1.2)
    with pytest.raises(ValueError, match="low/high.*12"):
        labdata.ExperimentSpec("uniform", 1.5, 12.0)


def test_labdata_cli_writes_loadable_files(tmp_path):
    assert labdata.main(["--out", str(tmp_path)]) == 0
    from scipy.io import loadmat

    for name in labdata.CATALOGUE:
        mat = IOData.from_mat(tmp_path / f"{name}.mat")
        csv = IOData.from_csv(tmp_path / f"{name}.csv")  # Ts from the time column
        assert csv.Ts == mat.Ts == 0.001
        assert np.array_equal(mat.u, csv.u) and np.array_equal(mat.y, csv.y)
        assert mat.N * mat.Ts >= 20
    # the units, as the rig reports them: coil current in A, upper magnet height in cm
    assert (tmp_path / "step.csv").read_text().splitlines()[0] == "t (s),u (A),y (cm)"
    units = loadmat(tmp_path / "step.mat")
    assert (str(units["u_unit"][0]), str(units["y_unit"][0])) == ("A", "cm")
