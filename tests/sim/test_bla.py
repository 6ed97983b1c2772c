"""Tests of maglev.sim.bla: the best linear approximation and the one-record frequency response.

Known truths: on a linear plant the BLA is its transfer function (coverage of the
standard error); on the levitator it depends on the input class; the identity
E|y - G u|² = ‖G_BLA - G‖²_Φu + var(y_s) holds for any linear G; a record's coherent and
incoherent output split into G u and the noise; the cache returns what it stored.  Short
classes and few realisations keep the tests fast.
"""

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy import signal

from maglev.sim import bla as bla_mod
from maglev.sim.bla import BLA, bla, record_distance, relative_distance, validation_records, weighted_distance
from maglev.spectral import FrequencyResponse, Preprocess, frequency_response
from maglev.data import IOData
from maglev.estimation import arx, oe
from maglev.sim.labdata import ExperimentSpec, input_signal
from maglev.model import PolyModel
from maglev.sim.plant import PLANTS, Levitator, rig

STICK_SLIP = PLANTS["stick_slip"]  # the plant these tests' numbers were measured on

BINARY = ExperimentSpec("binary", 1.5, 4.0, alpha=0.25, duration_s=12.0)
NARROW = ExperimentSpec("uniform", 1.75, 2.5, duration_s=12.0)
DEC2 = Preprocess(trim=2000, detrend=True, decimate=2)
SEG = 2.0  # s per Welch segment: the 12 s classes here are too short for the default (bla.SEGMENT_S, 8 s)
# a lightly damped second-order plant with a delay, on the 1 ms label: pole pair at 0.1 rad/sample
TRUE = PolyModel(A=[1.0], B=[0.0, 0.0, 0.02, 0.015], C=[1.0], D=[1.0],
                 F=np.real(np.poly([0.97 * np.exp(0.1j), 0.97 * np.exp(-0.1j)])), nk=2, Ts=1e-3, structure="oe")
NOISE_STD = 0.3  # output noise of the linear plant: the standard error is then ≈ 5-10 % of |G|


def _linear_plant(u: np.ndarray, seed: int) -> np.ndarray:
    return TRUE.simulate(u) + NOISE_STD * np.random.default_rng(seed).standard_normal(u.size)


def _coverage(G: np.ndarray, G0: np.ndarray, std: np.ndarray, k: float) -> float:
    return float(np.mean(np.abs(G - G0) <= k * std))


def test_bla_of_a_linear_plant_is_its_transfer_function_within_the_standard_error():
    est = bla(BINARY, _linear_plant, preprocess=Preprocess(), realisations=8, segment_s=SEG)
    band = est.w > 0
    G0 = TRUE.freqresp(est.w[band])
    # with SE² from the spread of M = 8 realisations, |Ĝ - G|²/SE² ~ F(2, 14):
    # P(<= 1) = 0.61 and P(<= 4) = 0.96 (over ~1000 frequencies, correlated in pairs)
    assert 0.50 <= _coverage(est.G[band], G0, est.std[band], 1.0) <= 0.72
    assert 0.92 <= _coverage(est.G[band], G0, est.std[band], 2.0) <= 0.99
    low = band & (est.w < 300)  # rad/s: up to past the resonance, where |G| is large
    assert np.median(est.std[low] / np.abs(TRUE.freqresp(est.w[low]))) < 0.05  # the bounds are not vacuous
    # the model itself is at distance ≈ SE; a 10 % gain error is far beyond it
    assert weighted_distance(TRUE.freqresp(est.w), est) < 0.02
    assert weighted_distance(1.1 * TRUE.freqresp(est.w), est) == pytest.approx(0.1, abs=0.01)
    assert relative_distance(1.1 * TRUE.freqresp(est.w), est) == pytest.approx(0.1, abs=0.02)


def test_a_feature_narrower_than_a_welch_bin_counts_with_the_band_it_occupies():
    """A slow pole-zero pair near ω = 0 (as OE [4 4 2] fits on the narrow uniform class) on a flat input
    spectrum: given the model's response as a function the distance is the integral's; sampled at the
    Welch frequencies it weighs the pair's dip at ω = 0 as if it filled a whole bin."""

    w = np.linspace(0, np.pi / 1e-3, 1001)  # the Welch grid of 2 s segments at 1 ms: 0.5 Hz apart
    suu = np.ones(w.size)
    suu[[0, -1]] = 0.5  # a one-sided Welch density: end bins not doubled
    ref = FrequencyResponse(w=w, G=TRUE.freqresp(w), std=np.zeros(w.size), coherence=np.ones(w.size), Suu=suu,
                            Syy=suu, Ts=1e-3, averages=1)
    dense = np.linspace(0, np.pi / 1e-3, 2_000_001)
    for zero, pole, grid_error in ((0.99996, 0.9994, 0.3), (0.99, 0.95, 0.0)):
        model = PolyModel(A=[1.0], B=np.convolve(TRUE.B, [1.0, -zero]), C=[1.0], D=[1.0],
                          F=np.convolve(TRUE.F, [1.0, -pole]), nk=2, Ts=1e-3, structure="oe")
        g0, g = TRUE.freqresp(dense), model.freqresp(dense)
        exact = np.sqrt(np.trapezoid(np.abs(g - g0) ** 2, dense) / np.trapezoid(np.abs(g0) ** 2, dense))
        assert weighted_distance(model.freqresp, ref) == pytest.approx(exact, rel=0.01)
        assert relative_distance(model.freqresp, ref) == pytest.approx(exact, rel=0.01)  # flat Φu: the same
        on_grid = weighted_distance(model.freqresp(w), ref)
        assert on_grid > (1 + grid_error) * exact if grid_error else on_grid == pytest.approx(exact, rel=0.01)


def test_on_finite_records_the_fitted_initial_state_takes_up_an_error_slower_than_the_record():
    """record_distance: as a validation simulation FIT with a fitted initial state sees G.  Errors of G at
    all frequencies count as in the stationary distance; a slow pole-zero pair (time constant 1.7 s) is an
    error the model's own slow mode, started from a fitted state, absorbs — the more, the shorter the record."""
    est = bla(BINARY, _linear_plant, preprocess=Preprocess(), realisations=16, segment_s=SEG)

    def on_records(model, n):
        return record_distance(model.G_polys, est, n)

    def with_pair(zero, pole):
        return PolyModel(A=[1.0], B=np.convolve(TRUE.B, [1.0, -zero]), C=[1.0], D=[1.0],
                         F=np.convolve(TRUE.F, [1.0, -pole]), nk=2, Ts=1e-3, structure="oe")

    scaled = PolyModel(A=[1.0], B=1.1 * np.asarray(TRUE.B), C=[1.0], D=[1.0], F=TRUE.F, nk=2, Ts=1e-3, structure="oe")
    for model in (scaled, with_pair(0.99, 0.95)):  # errors of G well inside the record's time scale
        assert on_records(model, 5000) == pytest.approx(weighted_distance(model.freqresp, est), rel=0.03)
    slow = with_pair(0.99996, 0.9994)
    short, middle, long = (on_records(slow, n) for n in (1000, 2000, 5000))
    assert short < middle < long < weighted_distance(slow.freqresp, est)
    assert short < 0.6 * weighted_distance(slow.freqresp, est)
    recs = validation_records(est, 1000, records=3)
    assert [d.N for d in recs] == [1000] * 3 and on_records(TRUE, 1000) < 0.03  # the truth itself: the BLA's error


def test_record_distance_is_the_records_simulations_from_fitted_states_as_predict_makes_them():
    """All records at once (one filter pass and one least-squares fit of every record's initial state) give what
    ``model.predict(record, inf, "estimate")`` record by record gives; an unstable G is refused."""
    est = bla(BINARY, _linear_plant, preprocess=Preprocess(), realisations=4, segment_s=SEG)
    arx = PolyModel(A=[1.0, -1.2, 0.4], B=[0.0, 0.0, 0.3, 0.1], C=[1.0], D=[1.0], F=[1.0], nk=2, Ts=1e-3,
                    structure="arx")
    for model in (TRUE, arx):
        recs = validation_records(est, 800, records=5)
        err = sum(float(np.sum((d.y - model.predict(d, math.inf, "estimate")) ** 2)) for d in recs)
        by_record = math.sqrt(err / sum(float(np.sum(d.y ** 2)) for d in recs))
        assert record_distance(model.G_polys, est, 800, records=5) == pytest.approx(by_record, rel=1e-10)
    with pytest.raises(ValueError, match="unit circle"):
        record_distance(([0.0, 1.0], [1.0, -1.01]), est, 800, records=5)


def test_one_record_frequency_response_error_matches_its_coherence_based_standard_error():
    u = input_signal(replace(BINARY, seed=3, duration_s=40.0))
    frf = frequency_response(IOData(u=u, y=_linear_plant(u, 4), Ts=1e-3).trim(2000).detrend())
    band = frf.w > 0
    cover2 = _coverage(frf.G[band], TRUE.freqresp(frf.w[band]), frf.std[band], 2.0)
    assert 0.92 <= cover2 <= 1.0  # nominal 1 - e^-4 = 0.98 for a complex Gaussian error
    assert frf.averages == 1 + (38000 - 2000) // 1000


@pytest.fixture(scope="module")
def binary_bla(tmp_path_factory) -> BLA:
    """The default levitator's BLA for binary α .25 1.5-4 A, 12 s, trimmed, detrended, decimated by 2."""
    return bla(BINARY, rig("stick_slip"), preprocess=DEC2, realisations=6, segment_s=SEG,
               cache=tmp_path_factory.mktemp("bla"))


def test_levitator_bla_depends_on_the_input_class(binary_bla):
    big = binary_bla
    small = bla(NARROW, rig("stick_slip"), preprocess=DEC2, realisations=3, segment_s=SEG, cache=False)
    assert big.Ts == small.Ts == 2e-3
    band = (big.w > 30) & (big.w < 300)  # rad/s: around both resonances
    z = np.abs(big.G - small.G)[band] / np.hypot(big.std, small.std)[band]
    # the friction's damping: the large binary hops see a resonant gain, small white noise a heavily
    # damped one; the two estimates differ by many times their standard errors
    assert np.median(z) > 5
    assert np.abs(big.G[band]).max() > 3 * np.abs(small.G[band]).max()
    assert 0 < small.fit_ceiling < 100 and 0 < big.fit_ceiling < 100


def test_simulation_error_of_any_linear_model_is_its_weighted_distance_plus_the_distortion(binary_bla):
    lev, est = rig("stick_slip"), binary_bla
    records = []
    for seed in range(4):  # held out: seeds the estimate did not use
        u = input_signal(replace(BINARY, seed=seed))
        records.append(DEC2.apply(IOData(u=u, y=lev.simulate(u, seed=seed, noise=False).y, Ts=BINARY.Ts)))
    half = est.w.size - 1
    fits = [100 * (1 - np.linalg.norm(d.y[half:-half] - est.simulate(d.u)[half:-half])
                   / np.linalg.norm(d.y[half:-half])) for d in records[1:]]
    assert np.mean(fits) == pytest.approx(est.fit_ceiling, abs=4.0)
    predicted = []
    for model in (oe(records[0], 2, 2, 2), arx(records[0], 1, 1, 2)):  # a resonance, and none
        d = weighted_distance(model.freqresp(est.w), est)
        pred = d ** 2 * est.linear_variance + est.distortion_variance
        mse = np.array([np.mean((r.y[300:] - model.simulate(r.u)[300:]) ** 2) for r in records[1:]])
        # tolerance: 3 standard errors of the mean over the 3 records (each record's mean square
        # scatters by ≈ 7 %) plus 5 % for the BLA's own estimation error with M = 6 (measured 2-4 %)
        tol = 3 * mse.std(ddof=1) / np.sqrt(mse.size) + 0.05 * pred
        assert abs(mse.mean() - pred) <= tol, (model.label, mse, pred)
        predicted.append(pred)
    assert predicted[1] > 1.5 * predicted[0]  # the identity separates a good model from a poor one


def test_cache_round_trip_and_key(tmp_path, monkeypatch):
    lev = rig("stick_slip")
    spec = replace(NARROW, duration_s=6.0)
    first = bla(spec, lev, preprocess=DEC2, realisations=2, segment_s=SEG, cache=tmp_path)
    assert len(list(tmp_path.glob("*.npz"))) == 1
    bla_mod._MEMORY.clear()

    def no_simulation(*args, **kwargs):
        raise AssertionError("estimated again instead of read from the cache")

    monkeypatch.setattr(bla_mod, "_estimate", no_simulation)
    again = bla(replace(spec, seed=99), lev, preprocess=DEC2, realisations=2, segment_s=SEG, cache=tmp_path)  # seed: not a key
    assert isinstance(again, BLA) and again.spec.seed == 99
    for name in ("w", "G", "std", "coherence", "Suu", "Syy"):
        np.testing.assert_array_equal(getattr(again, name), getattr(first, name))
    assert (again.fit_ceiling, again.preprocess, again.Ts) == (first.fit_ceiling, first.preprocess, first.Ts)
    key = bla_mod.cache_key(spec, lev, DEC2, 2, SEG)
    assert key != bla_mod.cache_key(spec, lev.with_params(coulomb_upper=0.04), DEC2, 2, SEG)
    assert key != bla_mod.cache_key(replace(spec, alpha=None, kind="uniform", low=1.5), lev, DEC2, 2,
                                    SEG)
    assert key != bla_mod.cache_key(spec, lev, replace(DEC2, decimate=1), 2, SEG)
    assert key != bla_mod.cache_key(spec, lev, DEC2, 2, bla_mod.SEGMENT_S)  # the segment length is a key


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="stationary random input class"):
        bla(ExperimentSpec("step", 2.5, 3.0), _linear_plant)
    est = bla(replace(BINARY, duration_s=6.0), _linear_plant, preprocess=Preprocess(), realisations=2,
              segment_s=SEG)
    with pytest.raises(ValueError, match="freqresp"):
        weighted_distance(np.ones(3), est)
    with pytest.raises(ValueError, match="realisations must be >= 2"):
        bla(BINARY, _linear_plant, realisations=1)
    with pytest.raises(ValueError, match="Preprocess.decimate"):
        Preprocess(decimate=0)


def test_band_rms_splits_the_output_into_the_filtered_input_and_the_noise():
    """y = G u + e, u and e white and independent: in each band the coherent rms is the rms of G u
    (from the true G: sqrt(∫ |G|² S_uu df)), the incoherent one e's (σe sqrt(2 Ts Δf)); their squares
    add up to the band's output power."""
    Ts, su, se = 1e-3, 1.0, 0.5
    a = np.real(np.poly([0.9 * np.exp(0.15j), 0.9 * np.exp(-0.15j)]))  # a resonance near 150 rad/s
    b = [0.0, 0.02, 0.01]
    rng = np.random.default_rng(5)
    u = su * rng.standard_normal(400_000)
    e = se * rng.standard_normal(u.size)
    Gu = signal.lfilter(b, a, u)
    frf = frequency_response(IOData(u=u, y=Gu + e, Ts=Ts), segment_s=1.0)
    assert frf.df == pytest.approx(1.0)
    # band edges halfway between Welch bins (1 Hz apart), so the bins in a band cover exactly [lo, hi)
    for lo_hz, hi_hz in ((0.0, 8.5), (8.5, 24.5), (24.5, 64.5)):
        lo, hi = 2 * math.pi * lo_hz, 2 * math.pi * hi_hz
        w = np.linspace(lo, hi, 20_001)
        G = signal.freqz(b, a, worN=w * Ts)[1]
        coherent = math.sqrt(np.trapezoid(np.abs(G) ** 2 * 2 * su ** 2 * Ts, w / (2 * math.pi)))
        incoherent = se * math.sqrt(2 * Ts * (hi - lo) / (2 * math.pi))
        assert 0.5 < coherent / incoherent < 3  # both parts matter in every band
        coh, incoh = frf.band_rms(lo, hi)
        assert coh == pytest.approx(coherent, rel=0.04), (lo, hi)
        assert incoh == pytest.approx(incoherent, rel=0.04), (lo, hi)
        inside = (frf.w >= lo) & (frf.w < hi)
        assert coh ** 2 + incoh ** 2 == pytest.approx(np.sum(frf.Syy[inside]) * frf.df, rel=1e-12)
        # without the noise the output is (almost) all coherent: leakage leaves a floor of a few %
        clean = frequency_response(IOData(u=u, y=Gu, Ts=Ts), segment_s=1.0).band_rms(lo, hi)
        assert 0 < clean[1] < 0.1 * clean[0]


@pytest.mark.parametrize("lo, hi", [(-1.0, 30.0), (30.0, 30.0), (150.0, 30.0), (math.nan, 30.0), (1.0, 2.0)])
def test_band_rms_rejects_a_band_that_is_not_one(lo, hi):
    w = np.linspace(0, np.pi / 1e-3, 501)  # 2π rad/s apart: (1, 2) holds no frequency
    ones = np.ones(w.size)
    frf = FrequencyResponse(w=w, G=ones.astype(complex), std=0 * ones, coherence=ones, Suu=ones, Syy=ones,
                                    Ts=1e-3, averages=1)
    with pytest.raises(ValueError, match=f"lo={lo!r}, hi={hi!r}|{lo!r} <= w < {hi!r}"):
        frf.band_rms(lo, hi)


def test_blas_of_several_classes_are_the_estimates_bla_makes_one_class_at_a_time(tmp_path, monkeypatch):
    """One batch for the classes of one length (binary α .25 and uniform 1.75-2.5 A, 0.8 s), the class of
    another length alone: every array and number equal to bla's own, class by class, and on disk."""
    specs = [replace(BINARY, duration_s=0.8), replace(NARROW, duration_s=0.8), replace(NARROW, duration_s=1.0)]
    settings = dict(preprocess=Preprocess(trim=200), realisations=bla_mod.BATCH_FROM, segment_s=0.25)
    lev = Levitator(STICK_SLIP)
    batches = []
    simulate_batch = Levitator.simulate_batch
    monkeypatch.setattr(Levitator, "simulate_batch", lambda self, U, **kw: batches.append(len(U)) or
                        simulate_batch(self, U, **kw))
    monkeypatch.setenv("MAGLEV_CACHE", str(tmp_path / "together"))
    monkeypatch.setattr(bla_mod, "_MEMORY", {})
    together = bla_mod.blas(specs, lev, **settings)
    assert batches == [2 * bla_mod.BATCH_FROM, bla_mod.BATCH_FROM]  # the two 0.8 s classes at once, then the 1 s one
    assert all(bla_mod.is_cached(spec, lev, **settings) for spec in specs)
    monkeypatch.setenv("MAGLEV_CACHE", str(tmp_path / "apart"))
    monkeypatch.setattr(bla_mod, "_MEMORY", {})
    apart = [bla(spec, lev, **settings) for spec in specs]
    for a, b in zip(together, apart):
        assert a.spec == b.spec and a.averages == b.averages
        for name in ("w", "G", "std", "coherence", "Suu", "Syy"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
        assert (a.distortion_variance, a.output_variance) == (b.distortion_variance, b.output_variance)
    assert not np.array_equal(together[0].G, together[1].G)  # two classes, two answers
