"""Confidence bounds: Monte-Carlo coverage on known systems, derivatives against finite differences, conventions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import norm

from maglev import estimation as E
from maglev import uncertainty as U
from maglev.model import PolyModel
from maglev.structures import PolySpec

from .systems import TRUE, simulate, true_model

W_NORMALISED = np.array([0.1, 0.5, 1.5])  # ωTs: below, near and above the poles' frequency
STEP_SAMPLES = (2, 5, 10, 29)


def _monte_carlo(name: str, runs: int, N: int = 2_000) -> dict[str, np.ndarray]:
    """Per run: the truth's distance from the estimate in the estimate's own standard deviations.

    ``mag``, ``phase`` (at W_NORMALISED) and ``step`` (at STEP_SAMPLES) are signed
    z-scores; ``pole`` is the squared Mahalanobis distance of the true upper-half-plane
    pole from the nearest estimated pole.  Coverage at k SD is then mean(|z| <= k).
    """
    truth = true_model(name)
    w = W_NORMALISED / truth.Ts
    G0 = truth.freqresp(w)
    p0 = next(p for p in truth.poles() if p.imag > 0)
    s0 = truth.simulate(np.ones(max(STEP_SAMPLES) + 1))[list(STEP_SAMPLES)]
    out = {"mag": [], "phase": [], "pole": [], "step": []}
    for seed in range(runs):
        m = E.estimate(simulate(name, N, 10_000 + seed), name, TRUE[name]["orders"])
        fb = U.frequency_bounds(m, w)
        out["mag"].append((np.abs(G0) - fb.magnitude) / fb.sd_magnitude)
        out["phase"].append(np.angle(G0 / fb.response, deg=True) / fb.sd_phase)
        poles = U.root_regions(m, "poles")
        i = int(np.argmin(np.abs(poles.roots - p0)))
        d = np.array([(p0 - poles.roots[i]).real, (p0 - poles.roots[i]).imag])
        out["pole"].append(d @ np.linalg.solve(poles.covariance[i], d))
        sb = U.step_bounds(m, max(STEP_SAMPLES) + 1)
        out["step"].append((s0 - sb.y[list(STEP_SAMPLES)]) / sb.sd[list(STEP_SAMPLES)])
    return {k: np.asarray(v) for k, v in out.items()}


@pytest.fixture(scope="module", params=[("arx", 400), ("oe", 150)], ids=["arx221", "oe222"])
def monte_carlo(request):
    name, runs = request.param
    return name, runs, _monte_carlo(name, runs)


@pytest.mark.parametrize("level", [0.95, 0.99])
def test_bounds_cover_the_truth_at_their_nominal_level(monte_carlo, level):
    """Each bound, built by the library from one data set, contains the true system in `level` of the runs.

    Tolerance: 3 binomial standard deviations of the observed fraction plus one
    point for the first-order approximation — at 99 % and 400 runs that is ±2.5
    points, tight enough to reject 2.58 SD for the 2-D pole region (96.4 %).
    """
    name, runs, z = monte_carlo
    k1, _ = U.multiplier(level, dims=1)
    k2, _ = U.multiplier(level, dims=2)
    observed = {
        "mag": np.mean(np.abs(z["mag"]) <= k1, axis=0),
        "phase": np.mean(np.abs(z["phase"]) <= k1, axis=0),
        "step": np.mean(np.abs(z["step"]) <= k1, axis=0),
        "pole": np.array([np.mean(z["pole"] <= k2**2)]),
    }
    tolerance = 3 * math.sqrt(level * (1 - level) / runs) + 0.01
    for what, fractions in observed.items():
        assert np.all(np.abs(fractions - level) <= tolerance), (name, what, level, fractions.round(3), tolerance)


def test_matlab_2p58_sd_ellipse_undercovers_a_complex_pole(monte_carlo):
    """MATLAB's documented '99 % ↔ 2.58 SD' holds for 1-D bounds, not for a pole's 2-D region (96.4 %)."""
    name, runs, z = monte_carlo
    k, coverage = U.multiplier(sd=2.58, dims=2)
    assert coverage == pytest.approx(1 - math.exp(-2.58**2 / 2))
    assert abs(np.mean(z["pole"] <= k**2) - coverage) <= 3 * math.sqrt(coverage * (1 - coverage) / runs) + 0.01


def test_multiplier_conventions():
    assert U.multiplier() == (1.0, pytest.approx(0.6826894921))  # MATLAB showConfidence default: 1 SD
    k, level = U.multiplier(0.99)
    assert k == pytest.approx(norm.ppf(0.995)) and round(k, 2) == 2.58 and level == 0.99  # MATLAB: 99 % ↔ 2.58 SD
    assert U.multiplier(0.99, dims=2)[0] == pytest.approx(math.sqrt(-2 * math.log(0.01)))  # χ²₂ quantile
    assert U.multiplier(sd=3)[1] == pytest.approx(0.9973, abs=1e-4)  # MATLAB: "3 SD ≈ 99.7 %"
    for bad, message in (({"level": 1.0}, "strictly between"), ({"sd": -1}, "positive"),
                         ({"level": 0.9, "sd": 2}, "not both"), ({"dims": 3}, "dims")):
        with pytest.raises(ValueError, match=message):
            U.multiplier(**bad)


# ---------------------------------------------------------------------------- derivatives
def _general_model() -> PolyModel:
    """A pem model using every polynomial, real and complex poles, and a made-up positive-definite covariance."""
    A, B, C, D, F = [1, -0.9, 0.2], [0, 0, 1.0, 0.4, 0.2], [1, 0.3], [1, 0.6], [1, -1.2, 0.5]
    spec = PolySpec("pem", na=2, nb=3, nc=1, nd=1, nf=2, nk=2)
    rng = np.random.default_rng(0)
    L = rng.standard_normal((spec.n_params, spec.n_params)) * 1e-2
    return PolyModel(A=A, B=B, C=C, D=D, F=F, nk=2, Ts=1e-3, structure="pem", covariance=L @ L.T)


def _perturbed(model: PolyModel, theta: np.ndarray) -> PolyModel:
    A, B, C, D, F = model.spec.polys(theta)
    return PolyModel(A=A, B=B, C=C, D=D, F=F, nk=model.nk, Ts=model.Ts, structure=model.structure)


def _finite_difference(model: PolyModel, fn, h: float = 1e-6) -> np.ndarray:
    theta = model.parameters
    cols = [(fn(_perturbed(model, theta + h * e)) - fn(_perturbed(model, theta - h * e))) / (2 * h)
            for e in np.eye(theta.size)]
    return np.stack(cols, axis=-1)


def _sd(jac: np.ndarray, P: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("ip,pq,iq->i", jac, P, jac))


def test_frequency_bounds_equal_finite_difference_propagation():
    m = _general_model()
    w = np.array([0.0, 3.0, 300.0, 1500.0, 3141.0])
    np.testing.assert_allclose(U.freqresp_jacobian(m, w), _finite_difference(m, lambda s: s.freqresp(w)),
                               atol=1e-7)
    fb = U.frequency_bounds(m, w, level=0.99)
    sd_mag = _sd(_finite_difference(m, lambda s: np.abs(s.freqresp(w))), m.covariance)
    sd_phase = _sd(_finite_difference(m, lambda s: np.angle(s.freqresp(w) / m.freqresp(w))), m.covariance)
    np.testing.assert_allclose(fb.sd_magnitude, sd_mag, rtol=1e-6)
    np.testing.assert_allclose(fb.sd_phase, np.degrees(sd_phase), rtol=1e-6)
    np.testing.assert_allclose(fb.magnitude_upper - fb.magnitude, norm.ppf(0.995) * sd_mag, rtol=1e-6)
    c, d = m.na + m.nb, m.na + m.nb + m.nc + m.nd
    assert not np.any(U.freqresp_jacobian(m, w)[:, c:d])  # the noise model does not move G


@pytest.mark.parametrize("kind", ["poles", "zeros"])
def test_root_covariance_equals_finite_difference_propagation(kind):
    m = _general_model()
    regions = U.root_regions(m, kind)
    roots = regions.roots

    def matched(s: PolyModel) -> np.ndarray:  # perturbed roots in the nominal order
        new = s.poles() if kind == "poles" else s.zeros()
        return np.array([new[np.argmin(np.abs(new - r))] for r in roots])

    jac = _finite_difference(m, matched)
    stacked = np.concatenate([jac.real, jac.imag])
    full = stacked @ m.covariance @ stacked.T
    n = roots.size
    for i in range(n):
        expected = full[np.ix_([i, n + i], [i, n + i])]
        np.testing.assert_allclose(regions.covariance[i], expected, rtol=1e-5, atol=1e-14)


def test_real_root_region_is_a_segment_and_complex_one_an_ellipse_at_the_chi2_radius():
    regions = U.root_regions(_general_model(), "poles", level=0.99)
    assert regions.is_real.sum() == 2 and (~regions.is_real).sum() == 2
    for i, r in enumerate(regions.roots):
        edge = regions.outline(i)
        C = regions.covariance[i]
        if regions.is_real[i]:
            assert C[1, 1] == 0.0 and edge.size == 2
            np.testing.assert_allclose(np.abs(edge - r), norm.ppf(0.995) * math.sqrt(C[0, 0]))
        else:
            d = np.stack([(edge - r).real, (edge - r).imag])
            np.testing.assert_allclose(np.einsum("in,ij,jn->n", d, np.linalg.inv(C), d), -2 * math.log(0.01))
            assert regions.contains(i, r + 0.99 * (edge[0] - r)) and not regions.contains(i, r + 1.01 * (edge[0] - r))


def test_a_real_roots_variance_rounded_below_zero_is_a_point_not_an_error():
    """P's quadratic form can round a real root's variance to a tiny negative number (an OE model of the default
    sweep's pole map): its segment is then the root itself."""
    r = U.RootRegions(kind="poles", roots=np.array([0.9 + 0j]), covariance=np.array([[[-1e-20, 0.0], [0.0, 0.0]]]),
                      k_complex=3.0, k_real=2.5, level_complex=0.99, level_real=0.99)
    np.testing.assert_array_equal(r.outline(0), [0.9, 0.9])
    assert r.contains(0, 0.9) and not r.contains(0, 0.9 + 1e-12)


def test_step_bounds_equal_finite_difference_propagation():
    m = _general_model()
    s, jac = U.step_jacobian(m, 60)
    np.testing.assert_allclose(jac, _finite_difference(m, lambda x: x.simulate(np.ones(60))), atol=1e-7)
    sb = U.step_bounds(m, 60, sd=2)
    np.testing.assert_allclose(sb.upper - sb.y, 2 * _sd(jac, m.covariance))
    np.testing.assert_allclose(sb.y, m.simulate(np.ones(60)))
    assert sb.t[1] == pytest.approx(m.Ts) and sb.y[: m.nk].tolist() == [0.0] * m.nk


def test_default_step_length_covers_the_settling():
    m = _general_model()
    sb = U.step_bounds(m)
    assert abs(sb.y[-1] - m.dcgain()) < 1e-2 * abs(m.dcgain())
    assert sb.t.size == U.step_length(m)


def test_bad_models_give_clear_errors():
    m = true_model("arx")
    with pytest.raises(ValueError, match="has no parameter covariance"):
        U.frequency_bounds(m, [1.0])
    with pytest.raises(TypeError, match="must be a PolyModel"):
        U.step_bounds("model")
    unstable = PolyModel(A=[1, -1.1], B=[0, 1.0], C=[1], D=[1], F=[1], nk=1, Ts=1.0, structure="arx",
                         covariance=np.eye(2) * 1e-4)
    with pytest.raises(ValueError, match="pass the number of samples n"):
        U.step_bounds(unstable)
    assert U.step_bounds(unstable, 10).sd[-1] > 0
    with pytest.raises(ValueError, match="kind must be"):
        U.root_regions(unstable, "modes")
    with pytest.raises(ValueError, match="frequencies"):
        U.frequency_bounds(unstable, [-1.0])
    broken = PolyModel(A=[1, -0.5], B=[0, 1.0], C=[1], D=[1], F=[1], nk=1, Ts=1.0, structure="arx",
                       covariance=np.full((2, 2), np.inf))
    with pytest.raises(ValueError, match="not finite"):
        U.root_regions(broken)
