"""Polynomials in q⁻¹: stability projection and the free responses used for initial states."""

from __future__ import annotations

import numpy as np
from scipy.signal import freqz, lfilter

from maglev.polynomials import MAX_RADIUS, free_responses, roots_within, stabilize


def test_fast_stability_check_agrees_with_roots():
    rng = np.random.default_rng(0)
    for _ in range(5000):
        p = np.r_[1.0, rng.uniform(-2.5, 2.5, rng.integers(1, 5))]
        assert roots_within(p, MAX_RADIUS) == bool(np.all(np.abs(np.roots(p)) <= MAX_RADIUS)), p
    for _ in range(1000):  # degrees 3…8 near the circle, where the Schur–Cohn recursion decides
        n_pairs = rng.integers(1, 5)
        pairs = rng.uniform(0.5, 1.1, n_pairs) * np.exp(1j * rng.uniform(0, np.pi, n_pairs))
        real = rng.uniform(-1.1, 1.1, rng.integers(0, 2))
        p = np.real(np.poly(np.r_[pairs, pairs.conj(), real]))
        radius = np.abs(np.roots(p)).max()
        if p.size > 3 and abs(radius - 0.95) > 1e-6:
            assert roots_within(p, 0.95) == (radius <= 0.95), p


def test_stabilize_reflects_outside_roots_and_keeps_the_magnitude_shape():
    p = np.real(np.poly([2.0, 0.5 + 0.3j, 0.5 - 0.3j]))  # one root outside
    q = stabilize(p)
    assert q[0] == 1.0 and np.all(np.abs(np.roots(q)) <= MAX_RADIUS)
    np.testing.assert_allclose(np.sort(np.abs(np.roots(q))), np.sort([0.5, abs(0.5 + 0.3j), abs(0.5 + 0.3j)]))
    _, hp = freqz(p, worN=64)
    _, hq = freqz(q, worN=64)
    ratio = np.abs(hp) / np.abs(hq)
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-9)  # |P| = const · |Q| on the unit circle


def test_stabilize_pulls_unit_circle_roots_inside_and_leaves_stable_ones_alone():
    on_circle = np.array([1.0, 1.0])  # root at z = -1, as for band-limited noise
    assert np.all(np.abs(np.roots(stabilize(on_circle))) <= MAX_RADIUS)
    stable = np.array([1.0, -1.5, 0.7])
    np.testing.assert_array_equal(stabilize(stable), stable)


def test_free_responses_reproduce_lfilter_initial_states():
    b, a = np.array([1.0, 0.5, 0.2]), np.array([1.0, -1.2, 0.5, 0.1])
    zi = np.array([0.3, -0.2, 0.7])
    y, _ = lfilter(b, a, np.zeros(50), zi=zi)
    np.testing.assert_allclose(free_responses(b, a, 50) @ zi, y, atol=1e-14)
