"""The levitator's force laws, written once: coil push and pull, magnet repulsion, gravity, bushing friction.

Why: the equilibrium, ``linearize`` and both integrators of :mod:`maglev.sim.plant` must simulate one
plant; with a copy of the laws in each, a change to one copy would silently make the linear model (the
study's truth) describe another plant than the records.  So every one of them calls these functions:
the integrators and the equilibrium :func:`magnet_forces`, ``linearize`` its exact derivatives
(:func:`force_slopes`, by complex-step differentiation of the same function), and the velocity updates
:func:`friction` and :func:`stribeck_level`.

Lengths in cm, forces in N, speeds in cm/s.  The laws (ECP Model 730, fitted to the KTH records):

* coil push on the lower magnet at height z: ``I / (a (z + b)^n)``, linear in the coil current I;
* coil pull on the upper magnet at height h: ``kappa I / (a (h + b)^n)``;
* magnet repulsion ``c / (h - z + d)^4`` (Gilbert's far field with an offset d);
* gravity ``m g`` on each magnet;
* bushing friction: a viscous part ``gamma v`` and dry friction of magnitude ``fc + fs exp(-(v/vs)^2)``
  (Coulomb level and Stribeck peak) with the sign ``tanh(v / v_creep)``, or set-valued when v_creep = 0.

The functions work on floats, numpy arrays and complex numbers alike (plain arithmetic; the
exponential and tanh are passed in), so the scalar integrator, the batch integrator and the
complex-step derivatives run the same code.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = ["magnet_forces", "force_slopes", "friction", "stribeck_level"]

Forces = Callable[[Any, Any, Any], tuple[Any, Any]]
_STEP = 1e-20  # complex-step size: the derivative is exact to rounding for any step this small


def magnet_forces(p) -> Forces:
    """The net external force on each magnet, ``forces(current, z, h) -> (on the lower, on the upper)`` [N],
    for the parameters ``p`` (a :class:`~maglev.sim.plant.LevitatorParams`): coil push minus repulsion
    minus weight on the lower magnet, repulsion minus coil pull minus weight on the upper one.

    A closure with the parameters bound: the integrators call it once per substep."""
    ia, b, n, kap, c, d, w = 1.0 / p.a, p.b, p.n_coil, p.kappa, p.c, p.d, p.m * p.g

    def forces(current, z, h):
        ci = current * ia
        fm = c / (h - z + d) ** 4
        return ci / (z + b) ** n - fm - w, fm - kap * ci / (h + b) ** n - w

    return forces


def force_slopes(p, current: float, z: float, h: float) -> np.ndarray:
    """d(force on the lower, force on the upper) / d(current, z, h) at one state: a 2 x 3 array [N/A, N/cm].

    Complex-step derivatives of :func:`magnet_forces` (f(x + i s) = f(x) + i s f'(x) + O(s^2)), exact to
    rounding, so ``linearize`` differentiates the very law the integrators integrate."""
    forces = magnet_forces(p)
    out = np.empty((2, 3))
    for k in range(3):
        x = [complex(current), complex(z), complex(h)]
        x[k] += 1j * _STEP
        out[:, k] = [f.imag / _STEP for f in forces(*x)]
    return out


def stribeck_level(v, fc: float, fs: float, ivs2: float, exp: Callable = math.exp):
    """The dry friction's magnitude at speed ``v`` [N]: the Coulomb level ``fc`` plus the Stribeck peak ``fs``
    decaying as exp(-(v/vs)^2) (``ivs2`` = 1/vs^2).  The set-valued law's band; ``exp=np.exp`` on arrays."""
    return fc + fs * exp(-v * v * ivs2)


def friction(v, gamma, fc: float, fs: float, ivs2: float, ivc: float, exp: Callable = math.exp,
             tanh: Callable = math.tanh) -> tuple[Any, Any]:
    """The smooth friction law at speed ``v`` [cm/s]: (dry force [N], slope of dry + viscous force [N s/cm]).

    Dry force ``(fc + fs exp(-(v/vs)^2)) tanh(v / v_creep)`` (``ivc`` = 1/v_creep): below v_creep it acts
    like a heavy damping (fc + fs)/v_creep (creep); the viscous part ``gamma v`` (gamma in N s/cm) is the
    caller's, its slope included here, so the implicit velocity update needs one call.  The slope's
    velocity-weakening part (the Stribeck peak's fall) is negative."""
    e = exp(-v * v * ivs2)
    th = tanh(v * ivc)
    level = fc + fs * e
    return level * th, level * (1.0 - th * th) * ivc + gamma - 2.0 * fs * e * v * ivs2 * th
