"""Tests of maglev.lab.signals: the lab's input signals and the binary signal's spectrum."""

import re

import numpy as np
import pytest
from scipy import integrate

from maglev.lab.signals import random_binary, rbs_spectrum, staircase, step, uniform_noise


@pytest.mark.parametrize("alpha", [0.1, 0.25, 0.5, 0.75, 0.9])
def test_binary_switching_rate_is_alpha(alpha):
    n = 100_000
    u = random_binary(n, alpha, 1.5, 4.0, seed=3)
    assert set(np.unique(u)) == {1.5, 4.0}
    rate = np.mean(u[1:] != u[:-1])
    assert abs(rate - alpha) < 4 * np.sqrt(alpha * (1 - alpha) / n)


def test_binary_edge_cases_follow_the_definition():
    # s_0 = 1 maps to high; alpha = 0 never switches, alpha = 1 switches every sample
    assert np.all(random_binary(50, 0.0, 1.0, 2.0, seed=0) == 2.0)
    alt = random_binary(50, 1.0, 1.0, 2.0, seed=0)
    assert alt[0] == 1.0 and np.all(alt[1:] != alt[:-1])


@pytest.mark.parametrize("alpha", [0.25, 0.5, 0.75])
def test_binary_periodogram_matches_rbs_spectrum(alpha):
    seg, nseg = 128, 800
    s = random_binary(seg * nseg, alpha, -1.0, 1.0, seed=11).reshape(nseg, seg)
    pgram = np.mean(np.abs(np.fft.rfft(s, axis=1)) ** 2, axis=0) / seg
    w = 2 * np.pi * np.arange(pgram.size) / seg
    theory = rbs_spectrum(alpha, w[1:])
    # averaged periodogram of 800 segments: relative scatter about 1/sqrt(800) per bin
    rel = pgram[1:] / theory - 1
    assert abs(np.mean(rel)) < 0.03
    assert np.sqrt(np.mean(rel ** 2)) < 0.12


def test_rbs_spectrum_is_unit_power_and_flat_at_half():
    assert np.allclose(rbs_spectrum(0.5, np.linspace(0, np.pi, 7)), 1.0)
    for alpha in (0.1, 0.25, 0.75):
        total, _ = integrate.quad(lambda w: rbs_spectrum(alpha, w), 0, np.pi)
        assert total == pytest.approx(np.pi, rel=1e-6)  # variance of a ±1 signal is 1
    assert rbs_spectrum(0.25, 0.1) > rbs_spectrum(0.25, 3.0)  # small alpha: low-pass
    assert rbs_spectrum(0.75, 0.1) < rbs_spectrum(0.75, 3.0)  # large alpha: high-pass


def test_uniform_noise_stays_in_range_and_fills_it():
    u = uniform_noise(50_000, 1.75, 2.5, seed=1)
    assert u.min() >= 1.75 and u.max() <= 2.5
    assert u.min() < 1.76 and u.max() > 2.49
    assert np.mean(u) == pytest.approx(2.125, abs=0.01)


def test_random_signals_are_deterministic_per_seed():
    assert np.array_equal(uniform_noise(100, 0, 1, seed=5), uniform_noise(100, 0, 1, seed=5))
    assert not np.array_equal(random_binary(100, 0.5, 0, 1, seed=5), random_binary(100, 0.5, 0, 1, seed=6))


def test_staircase_and_step_shapes():
    u = staircase([0.0, 0.5, 1.0], 4)
    assert u.tolist() == [0.0] * 4 + [0.5] * 4 + [1.0] * 4
    s = step(10, 2.0, 3.0, at=4)
    assert s.tolist() == [2.0] * 4 + [3.0] * 6


@pytest.mark.parametrize("alpha", [-0.1, 1.5])
def test_bad_alpha_is_named(alpha):
    with pytest.raises(ValueError, match=r"alpha.*\[0, 1\].*" + re.escape(str(alpha))):
        random_binary(10, alpha, 0, 1)
    with pytest.raises(ValueError, match="alpha"):
        rbs_spectrum(alpha, 0.5)


def test_bad_ranges_and_lengths_are_named():
    with pytest.raises(ValueError, match="low/high"):
        uniform_noise(10, 3.0, 2.0)
    with pytest.raises(ValueError, match="dwell"):
        staircase([1, 2], 0)
    with pytest.raises(ValueError, match="at must"):
        step(10, 0, 1, at=11)
