"""The preparation tasks (§4) as the report answers them: the derivation from the forces of the lab's Fig. 2, the
linearised model (checked against the equilibria it linearises), the structure with its noise-model argument
(which follows the noise measured at constant input), similar set-ups, and no simulator-only fitted term."""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest

from maglev.sim.plant import PLANTS, rig
from maglev.study.report import preparation as prep
from maglev.study.report.sections import attached_code, preparation

# words of the simulator's fitted extras (docs/simulator.md): class-dependent and aged-contact damping, the laser's
# stretch above its knee, the wander force, the stick-slip friction law
SIMULATOR_ONLY = ("quiet", "aged", "ageing", "stretch", "knee", "wander", "class", "sensor_pole", "Stribeck",
                  "set-valued", "simulator parameter set", "jitter")
U_STAR, TS = 2.75, 0.002


def staircase(noise: np.ndarray, levels: int = 21, per_level: int = 500) -> tuple[np.ndarray, np.ndarray]:
    """A noise-free staircase 0, 0.5, … A with a first-order response per level, plus ``noise``."""
    u = np.repeat(np.arange(levels) * 0.5, per_level)
    y = 8.0 + 0.6 * np.repeat(np.arange(levels) * 0.5, per_level)
    return u, y + noise[: u.size]


def line_noise(n: int, f: float, r: float, seed: int) -> np.ndarray:
    """Narrow-band AR(2) noise at ``f`` cycles/sample (the rig's mains-ripple line)."""
    rng = np.random.default_rng(seed)
    a1, a2 = -2 * r * np.cos(2 * np.pi * f), r * r
    e, x = rng.standard_normal(n), np.zeros(n)
    for k in range(2, n):
        x[k] = e[k] - a1 * x[k - 1] - a2 * x[k - 2]
    return 0.002 * x / x.std()


def test_noise_at_constant_input_is_measured_on_the_stationary_tails():
    white = 0.002 * np.random.default_rng(1).standard_normal(21 * 500)
    w = prep.stationary_noise(*staircase(white), levels=21, tail=50.0, u_min=1.5, u_max=4.0)
    assert w.n == 6 * 250 and w.std == pytest.approx(0.002, rel=0.1)
    assert abs(w.rho1) < 0.1 and w.outside < 0.1  # white: about 1 % of lags outside a 99 % band
    c = prep.stationary_noise(*staircase(line_noise(21 * 500, 0.32, 0.9, 2)), 21, 50.0, 1.5, 4.0)
    assert c.peak == pytest.approx(0.32, abs=0.01) and c.outside > 0.5
    with pytest.raises(ValueError, match=r"no staircase level inside the working region \[11, 12\] A"):
        prep.stationary_noise(*staircase(white), 21, 50.0, 11, 12)


@pytest.mark.parametrize("plant", sorted(PLANTS))
def test_linearisation_is_the_slope_of_the_first_principles_equilibria(plant):
    """The linearised model's static gain is the derivative of the equilibrium height with respect to the current
    (central difference), of the same first-principles model: viscous friction, a linear sensor."""
    lev = rig(plant).with_params(sensor_pole=0.0)
    lin = prep.first_principles(rig(plant), U_STAR, TS)
    h = 1e-4
    slope = (lev.equilibrium(U_STAR + h).y - lev.equilibrium(U_STAR - h).y) / (2 * h)
    assert lin.dc_gain == pytest.approx(slope, rel=1e-4)
    assert lin.sys_c.nstates == 4  # both magnets free at u*: z, y and their velocities


def derivation(noise):
    lev = rig()
    return prep.derivation(lev.params, prep.first_principles(lev, U_STAR, TS), noise, 5)


def test_derivation_has_the_equations_the_linear_model_and_the_structure_with_its_noise_model():
    coloured = prep.NoiseFacts(std=0.0019, rho1=-0.46, outside=0.6, peak=0.336, n=1500)
    d = derivation(coloured)
    model = " ".join(d["model"])
    for term in ("m z̈ = F_r(I, z) − F_m(y − z) − m g − γ_l ż", "m ÿ = F_m(y − z) − F_a(I, y) − m g − γ_u ẏ",
                 "F_m = c/(y − z + d)⁴", "∝ |y − z|⁻⁴", "State x = (z, y, ż, ẏ)", "gravity m g", "viscous friction"):
        assert term in model, term
    assert " ".join(d["nonlinear"]).startswith("No: the model is nonlinear.")
    linear = " ".join(d["linear"])
    lin = prep.first_principles(rig(), U_STAR, TS)
    assert re.search(r"G\(s\) = δY/δI = \(.+s² .+\) / \(s⁴ .+\)", linear)  # two zeros over four poles
    assert f"static gain {lin.dc_gain:.3f} cm/A" in linear and "4 poles" in linear
    structure = " ".join(d["structure"])
    assert "nf = 4, nb = 4 and nk ≈ 2" in structure and "delayest on the data gives nk = 5" in structure
    assert "a coloured disturbance added at the output" in structure
    assert "ARX (H = 1/A) and ARMAX (H = C/A) make the noise share the plant's poles" in structure
    assert "The physics suggests BJ with nf = 4" in structure
    assert " ".join(d["similar"]).startswith("Yes:")
    # white noise at constant input: OE is then efficient too, and the suggestion changes with it
    white = " ".join(derivation(prep.NoiseFacts(std=0.002, rho1=0.01, outside=0.04, peak=0.1, n=1500))["structure"])
    assert "a white disturbance" in white and "the physics suggests OE with nf = 4" in white and "BJ with" not in white


def test_preparation_section_has_no_simulator_only_term_and_attaches_the_code():
    lev = rig()
    noise = prep.NoiseFacts(std=0.0019, rho1=-0.46, outside=0.6, peak=0.336, n=1500)
    table = pd.DataFrame({"structure": ["bj", "oe"], "val_fit_sim": [30.0, 20.0]})
    html = preparation(lev.params, prep.first_principles(lev, U_STAR, TS), noise, {"lab.nk": 5}, table)
    for heading in ("State-space model", "Is the model linear?", "Linearisation at the working point",
                    "Does it suggest a model structure?", "Similar physical set-ups"):
        assert f"<h3>{heading}" in html, heading
    for word in SIMULATOR_ONLY:
        assert word.lower() not in html.lower(), word
    assert "mean simulation FIT by structure: BJ 30.00 %, OE 20.00 %" in html
    code = attached_code()
    assert "def get_average(" in code and "def get_stationary_averages(" in code


def test_preparation_without_a_working_point_says_so():
    html = preparation(rig().params, None, None, {}, pd.DataFrame())
    assert "No working point" in html
