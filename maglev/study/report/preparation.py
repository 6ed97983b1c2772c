"""The lab's preparation tasks (§4) derived from first principles, with the numbers of the rig.

Newton's law for both magnets with the forces of the lab's Fig. 2 — the coil's push on the
lower magnet and pull on the upper one, Gilbert's repulsion ∝ |y − z|⁻⁴, gravity, viscous
friction γ — gives a four-state model; its linearisation at the working point u* gives the
transfer function whose orders suggest the structure, and the output's noise measured at
constant input suggests the noise model (OE vs ARMAX vs BJ).  Only first-principles terms
appear: the simulator's fitted extras (its class-dependent damping, its sensor stretch, its
wander) belong to docs/simulator.md, not to this answer, so the linearisation here uses the
viscous damping in motion and a linear sensor.  The constants are the rig's, fitted by
``maglev calibrate`` to the static curve and the records (the force-law exponent of the coil
is fitted, the repulsion's is Gilbert's 4).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

LAGS = 25  # autocorrelation lags of the noise test


@dataclass(frozen=True)
class NoiseFacts:
    """The output's variation at constant input: the staircase's stationary tails inside the working region."""

    std: float  # cm
    rho1: float  # lag-1 autocorrelation
    outside: float  # share of lags 1..LAGS outside the 99 % band of white noise
    peak: float  # frequency of the largest periodogram peak, cycles/sample
    n: int  # samples used


def stationary_noise(u: np.ndarray, y: np.ndarray, levels: int, tail: float, u_min: float,
                     u_max: float) -> NoiseFacts:
    """Deviations of y from each level's stationary mean (the last ``tail`` % of each level with u inside
    [u_min, u_max]): what the output does while the input is constant — the measurement and process noise."""
    n = len(y) - len(y) % levels
    segs_u, segs_y = np.asarray(u[:n], float).reshape(levels, -1), np.asarray(y[:n], float).reshape(levels, -1)
    k = max(2, int(round(segs_y.shape[1] * tail / 100.0)))
    parts = [s[-k:] - s[-k:].mean() for su, s in zip(segs_u, segs_y) if u_min - 1e-9 <= su[-1] <= u_max + 1e-9]
    if not parts:
        raise ValueError(f"no staircase level inside the working region [{u_min}, {u_max}] A")
    e = np.concatenate(parts)
    var = float(np.mean(e ** 2))
    acf = [float(np.mean(np.concatenate([p[j:] * p[:-j] for p in parts]))) / var for j in range(1, LAGS + 1)]
    band = 2.58 / math.sqrt(e.size)
    spectrum = np.mean([np.abs(np.fft.rfft(p)) ** 2 / p.size for p in parts if p.size == k], axis=0)
    freqs = np.fft.rfftfreq(k)
    peak = float(freqs[1:][int(np.argmax(spectrum[1:]))])
    return NoiseFacts(std=math.sqrt(var), rho1=acf[0], outside=float(np.mean(np.abs(acf) > band)), peak=peak,
                      n=int(e.size))


def first_principles(lev, u_star: float, Ts: float):
    """The linearisation of the first-principles model at ``u_star``: the rig's constants with viscous damping only
    and a linear sensor (``maglev.sim.plant.Levitator.linearize`` with ``dry_friction=False``)."""
    return lev.with_params(sensor_pole=0.0).linearize(float(u_star), Ts=Ts, dry_friction=False)


def _poly(c: np.ndarray, var: str) -> str:
    """A polynomial in ``var`` from its coefficients, highest power first, 3 significant digits."""
    deg = len(c) - 1
    terms = []
    for i, a in enumerate(c):
        p = deg - i
        if abs(a) < 1e-12 * max(1.0, float(np.max(np.abs(c)))):
            continue
        mono = "" if p == 0 else var if p == 1 else f"{var}{str(p).translate(str.maketrans('0123456789', '⁰¹²³⁴⁵⁶⁷⁸⁹'))}"
        coef = f"{abs(a):.3g}" if (abs(abs(a) - 1) > 1e-9 or p == 0) else ""
        terms.append(("− " if a < 0 else "+ ") + coef + ("·" if coef and mono else "") + mono)
    text = " ".join(terms)
    return text[2:] if text.startswith("+ ") else text


def derivation(p, lin, noise: NoiseFacts | None, nk_data: int | None = None) -> dict[str, list[str]]:
    """The preparation answer as plain-text sentences by topic: ``model``, ``nonlinear``, ``linear``,
    ``structure``, ``similar``.  ``p``: the rig's LevitatorParams; ``lin``: :func:`first_principles`'s
    LinearModel; ``noise``: :func:`stationary_noise` of the staircase (None: not measured)."""
    import control as ct

    eq = lin.equilibrium
    gap = eq.h - eq.z
    k_rep = 4.0 * p.c / (gap + p.d) ** 5  # N/cm: the repulsion's stiffness at the working point
    model = [
        "Forces (Fig. 2), heights in cm above the lower magnet's seat: the coil pushes the lower magnet up with "
        "F_r = I/(a (z + b)ⁿ) and pulls the upper one down with F_a = κ I/(a (y + b)ⁿ) (a permanent magnet in a "
        "coil's field: linear in I); the magnets repel each other with Gilbert's far-field law "
        "F_m = c/(y − z + d)⁴ (∝ |y − z|⁻⁴, d the offset of the magnets' effective poles); gravity m g; viscous "
        "friction γ ż and γ ẏ on the glass rod.",
        "Newton's law for each magnet (mass m):  m z̈ = F_r(I, z) − F_m(y − z) − m g − γ_l ż,   "
        "m ÿ = F_m(y − z) − F_a(I, y) − m g − γ_u ẏ.",
        "State x = (z, y, ż, ẏ), input I (the current regulator follows the command u), output y:  ẋ₁ = x₃, "
        "ẋ₂ = x₄, ẋ₃ = [F_r(I, x₁) − F_m(x₂ − x₁) − m g − γ_l x₃]/m, ẋ₄ = [F_m(x₂ − x₁) − F_a(I, x₂) − m g − "
        "γ_u x₄]/m,  y = x₂.",
        f"The rig's constants (maglev calibrate): m = {p.m:.3g} kg, a = {p.a:.3g} A/(N cmⁿ), b = {p.b:.3g} cm, "
        f"n = {p.n_coil:.3g}, κ = {p.kappa:.3g}, c = {p.c:.4g} N cm⁴, d = {p.d:.3g} cm, γ_l = {p.gamma_lower:.3g} "
        f"and γ_u = {p.gamma_upper:.3g} N s/m, g = {p.g:.3g} m/s².",
    ]
    nonlinear = [
        "No: the model is nonlinear. The repulsion falls with the fourth power of the gap and the coil forces with "
        f"the n = {p.n_coil:.3g} power of the distance to the coil (state-dependent stiffness), the input multiplies "
        "a function of the state (I/(a (z + b)ⁿ)), the lower magnet rests on its seat below lift-off and the upper "
        f"one meets a stop (contacts), the current regulator saturates at {p.i_sat:.3g} A, and the bushings' "
        "friction on the glass rod need not be viscous (dry friction holds small motions, so the response depends "
        "on the input's amplitude)."
    ]
    s_poles = ct.poles(lin.sys_c)
    num, den = (np.atleast_1d(np.squeeze(x)) for x in ct.tfdata(ct.ss2tf(lin.sys_c))[:2])
    num = np.trim_zeros(np.where(np.abs(num) < 1e-9 * np.max(np.abs(num)), 0.0, num), "f")
    n_poles, n_zeros = len(s_poles), len(num) - 1
    modes = "; ".join(f"ωn = {w:.1f} rad/s, ζ = {z:.2f}" for w, z in lin.modes())
    linear = [
        f"At the working point u* = {eq.u:.2f} A the forces balance at z* = {eq.z:.3f} cm, y* = {eq.h:.3f} cm "
        f"(gap {gap:.3f} cm){', the lower magnet seated' if eq.lower_seated else ''}. With δx = x − x*, δI = I − u*: "
        "δẋ = A δx + B δI, δy = C δx, where A holds the stiffnesses ∂F/∂z, ∂F/∂y over m and the damping −γ/m, and "
        f"B the force per ampere over m (the repulsion alone is a spring of {k_rep:.3g} N/cm between the magnets).",
        f"G(s) = δY/δI = ({_poly(num, 's')}) / ({_poly(den / den[0], 's')})  [cm/A], in the records' time base "
        f"(one logged 1 ms sample spans {1000 * p.t_phys:.2f} ms of physics, docs/simulator.md): {n_poles} poles "
        f"({modes}), {n_zeros} zero(s), static gain {lin.dc_gain:.3f} cm/A.",
    ]
    nb = n_poles  # a ZOH discretisation of n poles has n − 1 finite zeros: B needs n coefficients
    nk = 1 + lin.delay_samples
    structure = [
        f"Yes. G has {n_poles} poles and relative degree {n_poles - n_zeros} (the current acts on accelerations); "
        f"sampled with a zero-order hold at Ts = {1000 * lin.Ts:.2f} ms it becomes B(q⁻¹)/F(q⁻¹) with "
        f"nf = {n_poles}, nb = {nb} and nk ≈ {nk} (the logger's one-sample lag plus {lin.delay_samples} sample(s) of "
        "pure delay)" + (f"; delayest on the data gives nk = {nk_data}" if nk_data is not None else "") + "."
    ]
    if noise is not None:
        coloured = noise.outside > 0.1
        structure.append(
            f"The noise model: at constant input (the staircase's stationary tails, {noise.n} samples) the output "
            f"still varies by {noise.std:.2g} cm (std), with lag-1 autocorrelation {noise.rho1:.2f} and "
            f"{100 * noise.outside:.0f} % of lags 1–{LAGS} outside the 99 % band of white noise"
            + (f", strongest at {noise.peak:.3f} cycles/sample" if coloured else "") + ": "
            + ("a coloured" if coloured else "a white") + " disturbance added at the output by the sensor, not a "
            "force driving the magnets through their dynamics. ARX (H = 1/A) and ARMAX (H = C/A) make the noise "
            "share the plant's poles, which it does not; OE (H = 1) estimates G without bias in open loop but "
            + ("leaves the colour in the residuals; BJ (H = C/D, poles of its own) models both. The physics "
               "suggests BJ with nf = " + str(n_poles) + ", or OE when only G matters (simulation)."
               if coloured else "is then also efficient: the physics suggests OE with nf = " + str(n_poles) + "."))
    similar = [
        f"Yes: the pair is two masses coupled by a magnetic spring ({k_rep:.3g} N/cm here) and damped by the rod — "
        "the two-mass spring–damper of a car's quarter-suspension or of a tuned mass damper; the coil's force on a "
        "permanent magnet, linear in the current, is a loudspeaker's or voice-coil actuator's; and the ECP Model 730 "
        "itself is a magnetic-levitation rig like those of maglev trains and magnetic bearings, though those levitate "
        "by attraction and are open-loop unstable, while this repulsive set-up is open-loop stable."
    ]
    return {"model": model, "nonlinear": nonlinear, "linear": linear, "structure": structure, "similar": similar}


def noise_from_staircase(cfg: dict, lab: dict) -> NoiseFacts | None:
    """:func:`stationary_noise` of the sweep's staircase (``cfg``: a run config with its ``lab`` group; ``lab``: the
    parent's lab metrics); None when either is missing."""
    from maglev.sim.plant import DEFAULT_PLANT
    from maglev.study.datasets import plant_name
    from maglev.study.lab import staircase

    if "lab" not in cfg or "lab.u_min" not in lab:
        return None
    ds = cfg["dataset"]
    stairs = staircase(cfg["lab"], cfg["data_dir"], plant_name(ds) if ds["source"] == "sim" else DEFAULT_PLANT)
    return stationary_noise(stairs.u, stairs.y, int(cfg["lab"]["levels"]), float(cfg["lab"]["tail"]),
                            float(lab["lab.u_min"]), float(lab["lab.u_max"]))

