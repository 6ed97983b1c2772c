"""Known true systems for the estimator tests, and data simulated from them."""

from __future__ import annotations

import numpy as np

from maglev.data import IOData
from maglev.model import PolyModel

ONE = np.ones(1)


def levitator_like_F() -> np.ndarray:
    """Lightly damped 4th-order denominator: poles 0.95 ± 0.2j and 0.98 ± 0.07j (Ts = 1 ms)."""
    return np.real(np.poly([0.95 + 0.2j, 0.95 - 0.2j, 0.98 + 0.07j, 0.98 - 0.07j]))


TRUE = {
    "arx": dict(A=[1, -1.5, 0.7], B=[0, 1.0, 0.5], C=ONE, D=ONE, F=ONE, nk=1, sigma=0.3,
                orders=(2, 2, 1)),
    "armax": dict(A=[1, -1.5, 0.7], B=[0, 1.0, 0.5], C=[1, -0.3, 0.2], D=ONE, F=ONE, nk=1, sigma=0.5,
                  orders=(2, 2, 2, 1)),
    "oe": dict(A=ONE, B=[0, 0, 1.0, 0.5], C=ONE, D=ONE, F=[1, -1.2, 0.5], nk=2, sigma=0.3,
               orders=(2, 2, 2)),
    "bj": dict(A=ONE, B=[0, 1.0, 0.5], C=[1, 0.5], D=[1, -0.8], F=[1, -1.5, 0.7], nk=1, sigma=0.5,
               orders=(2, 1, 1, 2, 1)),
    # general structure: A shared by G = B/(AF) and H = C/(AD); roots well apart so that
    # A and F cannot trade places (with A, D, F roots 0.5, 0.6, 0.7 they nearly can at N = 2000)
    "pem": dict(A=[1, -0.3], B=[0, 1.0, 0.4], C=[1, 0.3], D=[1, 0.6], F=[1, -0.85], nk=1, sigma=0.3,
                orders=(1, 2, 1, 1, 1, 1)),
    # the levitator-like plant, as an OE model with a two-sample dead time
    "lev": dict(A=ONE, B=[0, 0, 0.01, 0.005], C=ONE, D=ONE, F=levitator_like_F(), nk=2, sigma=0.01,
                orders=(2, 4, 2)),
}


def true_model(name: str) -> PolyModel:
    s = TRUE[name]
    structure = "oe" if name == "lev" else name
    return PolyModel(A=s["A"], B=s["B"], C=s["C"], D=s["D"], F=s["F"], nk=s["nk"], Ts=1e-3,
                     structure=structure, noise_variance=s["sigma"] ** 2)


def simulate(name: str, N: int, seed: int, binary: bool = False) -> IOData:
    """Data from the true system: white Gaussian (or ±1 binary) input, Gaussian innovations."""
    rng = np.random.default_rng(seed)
    u = np.sign(rng.standard_normal(N)) if binary else rng.standard_normal(N)
    e = TRUE[name]["sigma"] * rng.standard_normal(N)
    y = true_model(name).simulate(u, e)
    return IOData(u, y, 1e-3, name=f"{name}-seed{seed}")
