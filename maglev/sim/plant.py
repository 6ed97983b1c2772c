"""Nonlinear simulator of the KTH/ECP magnetic levitator and its exact linearisation.

Why: the identification core needs records with a known truth.  This module
simulates the lab's rig (two ring magnets on a glass rod above one drive coil, the
lab text's §2 and preparation task 1) and returns :class:`~maglev.data.IOData` that
look like the lab's files, and it gives the true linear model at any working point
to compare identified models with.

Physics (lengths in cm, forces in N, ECP Model 730 force laws, see docs/simulator.md):

* lower magnet at height z >= 0 (rests on its seat until lifted), upper magnet at
  height h <= ``h_top`` (top stop), both of mass ``m``;
* coil force on the lower magnet ``Fc = I / (a (z + b)^n)`` (repulsive, linear in
  the current), and a weaker pull on the upper magnet ``Fa = kappa I / (a (h + b)^n)``;
* magnet-magnet repulsion ``Fm = c / (h - z + d)^4`` (Gilbert far field with an offset);
* gravity and the friction of each bushing on the glass rod, a viscous damping that
  depends on what the magnets have been doing (:class:`_Damping`): ``gamma`` in motion,
  plus ``gamma_quiet`` while the input is quiet *for its class* (the band-passed current
  over its own jitter grades random binary α .25, α .5 and white noise apart, as the rig's
  damping does), plus ``gamma_aged`` on a contact that has rested (rate-and-state
  ageing: a step after a rest is damped more).  Small motions are heavily damped, large
  ones lightly (the rig's amplitude dependence, notes §4.6; docs/decisions/0001-friction-law.md).
  Dry friction (Coulomb + Stribeck, set-valued with ``v_creep = 0``, else
  tanh-regularised over ``v_creep``): the upper bushing stuck in the default plant
  (``DEFAULT_PLANT``), light Coulomb levels on both in ``stick_slip``;
* the current regulator saturates at ``i_sat`` (≈ 4.06 A on the rig) and, as an
  option, the lab's logging quirk "command >= 10 A is written as 0 A";
* a pure input delay; a laser reading ``y = y_off + h``, stretched above ``sensor_knee``
  (``Levitator.reading``), plus sensor noise (white +
  a narrow mains-ripple line) and a disturbance at each command switch, quantised to
  the ADC step; optional process (force) noise, white and, as an option, a slow wander that small
  command steps drive (``Levitator.wander``; on in the default plant and ``stuck_upper``, off in the others).

Time base.  One logged sample of the lab's records is labelled 1 ms but spans about
6-7 ms of physical time (notes §5).  By default the simulator reproduces the
records *as labelled*: each logged sample of length ``Ts`` integrates ``Ts * time_scale``
of physics with ``time_scale = t_phys / 1 ms`` (about 6, fitted by ``maglev.sim.calibrate``
together with the friction), so a 60 s-labelled record covers about 360 s of physics
and the transients have the real records' length in samples.  With
``physical_time=True`` the simulator is physically honest (``Ts`` of physics per
sample), and its transients are about 6.4 times longer in samples.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from scipy import optimize, signal

from maglev.data import IOData
from maglev.sim.forces import force_slopes, friction, magnet_forces, stribeck_level

if TYPE_CHECKING:  # python-control (and the matplotlib it imports, 0.8 s) only where a model is linearised
    import control as ct

__all__ = ["LevitatorParams", "Equilibrium", "LinearModel", "Levitator", "PLANTS", "DEFAULT_PLANT", "rig",
           "plant_file", "U_MIN", "U_MAX"]

U_MIN, U_MAX = 0.0, 10.0  # the rig's allowed command range [A]
LABEL_TS = 1e-3  # the sampling period the lab's records are labelled with [s]
_CM = 100.0  # cm per m: accelerations in cm/s^2 are 100 F/m
# the small-step wander (Levitator.wander)
WANDER_SMALL_STEP = 1.0  # A: a command step counts as small when nonzero and at most this
WANDER_WINDOW = 50  # samples: the share of small steps is low-passed through the pole e^(-1/WANDER_WINDOW)
WANDER_STEP_POLE = 0.95  # per sample: low pass (unit gain) of the command's |step|
WANDER_STEP_REF = 2.5 / 3  # A: mean |step| of white noise U(1.5, 4) A, the lab's widest uniform input
_WANDER_STREAM = 15  # the wander's random stream beside the record's seed


PLANTS_DIR = Path(__file__).resolve().parent / "plants"  # one TOML file per named plant (package data)
DEFAULT_PLANT = "stuck_stretched"


def plant_file(name: str) -> dict:
    """The named plant's file as data: ``description``, ``provenance`` (fitted by which command, on which
    records, which checks it passes) and ``params`` (every field of :class:`LevitatorParams`)."""
    path = PLANTS_DIR / f"{name}.toml"
    if not path.is_file():
        known = sorted(f.stem for f in PLANTS_DIR.glob("*.toml"))
        raise ValueError(f"plant must be one of {known}, got {name!r}")
    with path.open("rb") as f:
        return tomllib.load(f)


_DEFAULT = plant_file(DEFAULT_PLANT)["params"]


@dataclass(frozen=True)
class LevitatorParams:
    """Physical and sensor parameters of the rig.

    The field defaults are the default plant's (``DEFAULT_PLANT``, read from its file under
    ``maglev/sim/plants/``), so ``Levitator()`` and ``rig()`` simulate the same physics; other named
    plants are :data:`PLANTS`."""

    m: float = _DEFAULT["m"]  # kg, mass of each magnet
    g: float = _DEFAULT["g"]  # m/s^2
    a: float = _DEFAULT["a"]  # A/(N cm^n): coil force Fc = I / (a (z + b)^n)
    b: float = _DEFAULT["b"]  # cm, offset of the coil force law
    n_coil: float = _DEFAULT["n_coil"]  # exponent of the coil force law
    kappa: float = _DEFAULT["kappa"]  # coil pull on the upper magnet relative to the push on the lower one
    c: float = _DEFAULT["c"]  # N cm^4, magnet repulsion Fm = c / (gap + d)^4
    d: float = _DEFAULT["d"]  # cm, offset of the repulsion law
    # damping of each bushing [N s/m]: gamma in motion, plus gamma_quiet while the input is quiet
    # for its class, plus gamma_aged on a contact that has rested (docs/simulator.md, "Physics")
    gamma_lower: float = _DEFAULT["gamma_lower"]  # N s/m, viscous friction of the lower magnet in motion
    gamma_upper: float = _DEFAULT["gamma_upper"]  # N s/m, viscous friction of the upper magnet in motion
    gamma_quiet_lower: float = _DEFAULT["gamma_quiet_lower"]  # N s/m, extra damping of the lower magnet while its activity is 0
    gamma_quiet_upper: float = _DEFAULT["gamma_quiet_upper"]  # N s/m, same for the upper magnet
    quiet_level_lower: float = _DEFAULT["quiet_level_lower"]  # A, band-passed current at which the lower magnet's activity is 1
    quiet_level_upper: float = _DEFAULT["quiet_level_upper"]  # A, same for the upper magnet
    quiet_power_lower: float = _DEFAULT["quiet_power_lower"]  # gamma_quiet / (1 + activity^power): how sharply it fades
    quiet_power_upper: float = _DEFAULT["quiet_power_upper"]
    activity_fast_lower: float = _DEFAULT["activity_fast_lower"]  # s (physical), fast low pass of the current's band pass
    activity_fast_upper: float = _DEFAULT["activity_fast_upper"]
    activity_slow_lower: float = _DEFAULT["activity_slow_lower"]  # s (physical), slow low pass subtracted from it
    activity_slow_upper: float = _DEFAULT["activity_slow_upper"]
    activity_attack: float = _DEFAULT["activity_attack"]  # s (physical), the activity envelope's rise
    activity_release: float = _DEFAULT["activity_release"]  # s (physical), and its fall
    jitter_weight: float = _DEFAULT["jitter_weight"]  # share of the current's jitter added to quiet_level (class, not range)
    jitter_tau: float = _DEFAULT["jitter_tau"]  # s (physical), low pass of the current's |step| per sample (the jitter)
    gamma_aged_lower: float = _DEFAULT["gamma_aged_lower"]  # N s/m, extra damping of the lower bushing after a long rest
    gamma_aged_upper: float = _DEFAULT["gamma_aged_upper"]  # N s/m, same for the upper bushing
    age_half: float = _DEFAULT["age_half"]  # s (physical), contact age at which half of gamma_aged acts
    slip_renewal: float = _DEFAULT["slip_renewal"]  # cm, slip that renews a contact (ageing law, backward Euler)
    # dry friction: Coulomb level + Stribeck peak; set-valued (exact stick-slip) with v_creep = 0, as in the
    # default plant (the upper bushing stuck, with a static peak), else with a tanh-regularised sign
    coulomb_lower: float = _DEFAULT["coulomb_lower"]  # N, kinetic (Coulomb) dry friction of the lower magnet's bushing
    coulomb_upper: float = _DEFAULT["coulomb_upper"]  # N, kinetic (Coulomb) dry friction of the upper magnet's bushing
    stiction_lower: float = _DEFAULT["stiction_lower"]  # N, extra friction at low speed (Stribeck peak) on the lower magnet
    stiction_upper: float = _DEFAULT["stiction_upper"]  # N, extra friction at low speed (Stribeck peak) on the upper magnet
    v_stribeck: float = _DEFAULT["v_stribeck"]  # cm/s, speed over which the Stribeck peak decays, exp(-(v/v_stribeck)^2)
    v_creep: float = _DEFAULT["v_creep"]  # cm/s, tanh regularisation of the friction's sign (0 = exact stick-slip)
    h_top: float = _DEFAULT["h_top"]  # cm, top stop of the upper magnet: above the rig's highest free flight (docs/simulator.md)
    i_sat: float = _DEFAULT["i_sat"]  # A, current-regulator saturation
    delay: float = _DEFAULT["delay"]  # s (physical), pure input delay beyond the one-sample read-then-write lag
    t_phys: float = _DEFAULT["t_phys"]  # s of physics per logged sample labelled 1 ms
    y_off: float = _DEFAULT["y_off"]  # cm, reading y = y_off + h below the sensor's knee
    sensor_knee: float = _DEFAULT["sensor_knee"]  # cm, height h above which the laser's scale stretches
    sensor_pole: float = _DEFAULT["sensor_pole"]  # cm, D: reading y = y_off + h + (h - sensor_knee)^2 / (D - h) above the knee (0: linear)
    noise_std: float = _DEFAULT["noise_std"]  # cm, std of the sensor noise before quantisation
    noise_line_fraction: float = _DEFAULT["noise_line_fraction"]  # share of the noise variance in the mains-ripple line
    noise_line_hz: float = _DEFAULT["noise_line_hz"]  # Hz, ripple frequency (aliased by the logging rate)
    noise_line_radius: float = _DEFAULT["noise_line_radius"]  # pole radius of the AR(2) line (its sharpness)
    quant: float = _DEFAULT["quant"]  # cm, ADC step of the reading (0 = no quantisation)
    force_noise: float = _DEFAULT["force_noise"]  # N, std of a white force on the upper magnet (process noise)
    # a slow force on the upper magnet that small command steps drive (process noise, Levitator.wander; 0: off)
    wander_force: float = _DEFAULT["wander_force"]  # N, its std while every step is small, with WANDER_STEP_REF as mean |step|
    wander_tau: float = _DEFAULT["wander_tau"]  # s (physical), its correlation time
    wander_power: float = _DEFAULT["wander_power"]  # exponent of the share of small steps that scales it
    switch_noise: float = _DEFAULT["switch_noise"]  # cm per A of command step: a reading disturbance at each switch
    switch_noise_pole: float = _DEFAULT["switch_noise_pole"]  # its pole (per logged sample)

    @property
    def sticks(self) -> bool:
        """Whether the bushings' dry friction is set-valued (``v_creep = 0`` with a Coulomb or Stribeck level): it
        holds a magnet still under any force it can cancel, and has no slope at rest for ``linearize``."""
        dry = self.coulomb_lower + self.coulomb_upper + self.stiction_lower + self.stiction_upper
        return self.v_creep == 0 and dry > 0

    def __post_init__(self) -> None:
        positive = ("m", "g", "a", "b", "n_coil", "c", "d", "h_top", "i_sat", "t_phys", "v_stribeck",
                    "quiet_level_lower", "quiet_level_upper", "quiet_power_lower", "quiet_power_upper",
                    "age_half", "slip_renewal", "sensor_knee", "wander_tau")
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"LevitatorParams.{name} must be a positive number, got {value!r}")
        nonneg = ("kappa", "gamma_lower", "gamma_upper", "coulomb_lower", "coulomb_upper",
                  "stiction_lower", "stiction_upper", "v_creep", "delay",
                  "noise_std", "noise_line_hz", "quant", "force_noise", "gamma_quiet_lower",
                  "gamma_quiet_upper", "activity_fast_lower", "activity_fast_upper", "activity_slow_lower",
                  "activity_slow_upper", "activity_attack", "activity_release", "jitter_weight", "jitter_tau",
                  "gamma_aged_lower", "gamma_aged_upper", "switch_noise", "sensor_pole", "wander_force",
                  "wander_power")
        for name in nonneg:
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"LevitatorParams.{name} must be a number >= 0, got {value!r}")
        if not 0.0 <= self.noise_line_fraction <= 1.0:
            raise ValueError(
                f"LevitatorParams.noise_line_fraction must be in [0, 1], got {self.noise_line_fraction!r}"
            )
        if not 0.0 <= self.switch_noise_pole < 1.0:
            raise ValueError(
                f"LevitatorParams.switch_noise_pole must be in [0, 1), got {self.switch_noise_pole!r}"
            )
        if self.sensor_pole and not self.sensor_pole > max(self.h_top, self.sensor_knee):
            raise ValueError(
                f"LevitatorParams.sensor_pole must be 0 (a linear sensor) or above both h_top = {self.h_top!r} cm "
                f"and sensor_knee = {self.sensor_knee!r} cm (the reading diverges there), got {self.sensor_pole!r}"
            )
        if not 0.0 <= self.noise_line_radius < 1.0:
            raise ValueError(
                f"LevitatorParams.noise_line_radius must be in [0, 1), got {self.noise_line_radius!r}"
            )


@dataclass(frozen=True)
class Equilibrium:
    """Static state for a constant command ``u``: coil current, magnet heights, reading."""

    u: float  # A, command
    current: float  # A, coil current after the regulator
    z: float  # cm, lower magnet
    h: float  # cm, upper magnet
    y: float  # cm, noise-free reading of h (Levitator.reading)
    lower_seated: bool  # the lower magnet rests on its seat (z = 0)
    upper_at_top: bool  # the upper magnet rests on the top stop


@dataclass(frozen=True)
class LinearModel:
    """True linear model from command deviation [A] to reading deviation [cm] at ``equilibrium``.

    ``sys_c`` is continuous without the pure delay, ``sys_d`` is its ZOH discretisation
    at ``Ts`` with the delay of ``delay_samples`` samples appended as extra states.  Both
    use the simulator's time base: in the default (as-labelled) mode one second of
    ``sys_c`` is one labelled second, i.e. ``time_scale`` physical seconds.
    """

    equilibrium: Equilibrium
    sys_c: ct.StateSpace
    sys_d: ct.StateSpace
    Ts: float
    delay_samples: int
    time_scale: float

    @property
    def dc_gain(self) -> float:
        """Static gain dy/du in cm/A (zero where the regulator saturates)."""
        import control as ct

        return float(np.real(ct.dcgain(self.sys_c)))

    def modes(self) -> list[tuple[float, float]]:
        """(natural frequency [rad/s, model time base], damping ratio) of each mode of ``sys_c``: each real pole,
        and each complex pair once."""
        import control as ct

        return [(abs(p), -p.real / abs(p) if abs(p) > 0 else 1.0) for p in ct.poles(self.sys_c) if p.imag >= 0]


class Levitator:
    """The levitator rig: ``simulate`` a command record, find ``equilibrium``, ``linearize``.

    ``physical_time=False`` (default) reproduces the lab's records as labelled: every
    logged sample covers ``Ts / 1 ms * params.t_phys`` of physics (5.985 ms for Ts = 1 ms).
    ``physical_time=True`` integrates exactly ``Ts`` of physics per sample.
    ``zero_at_10=True`` reproduces the lab logger's quirk of writing 0 A for any
    command >= 10 A (the 10 A level of the real staircase reads as 0 A).
    """

    def __init__(
        self,
        params: LevitatorParams | None = None,
        *,
        physical_time: bool = False,
        zero_at_10: bool = False,
    ) -> None:
        self.params = params or LevitatorParams()
        self.physical_time = bool(physical_time)
        self.zero_at_10 = bool(zero_at_10)

    def __repr__(self) -> str:
        return (f"Levitator(physical_time={self.physical_time}, zero_at_10={self.zero_at_10}, "
                f"params={self.params})")

    def with_params(self, **changes: float) -> "Levitator":
        """A copy with some parameters replaced (same time-base and quirk flags)."""
        return Levitator(replace(self.params, **changes), physical_time=self.physical_time,
                         zero_at_10=self.zero_at_10)

    # ------------------------------------------------------------------ time base
    def time_scale(self) -> float:
        """Physical seconds per second of the simulator's time base (t_phys / 1 ms as labelled, 1 if physical)."""
        return 1.0 if self.physical_time else self.params.t_phys / LABEL_TS

    def delay_samples(self, Ts: float) -> int:
        """Pure input delay in samples of period ``Ts`` (rounded)."""
        return int(round(self.params.delay / (Ts * self.time_scale())))

    # ------------------------------------------------------------------ input path
    def current(self, u: float | np.ndarray) -> np.ndarray:
        """Coil current [A] for command ``u``: optional >=10 A quirk, then regulator saturation."""
        u = _checked_command(u, "u")
        if self.zero_at_10:
            u = np.where(u >= U_MAX, 0.0, u)
        return np.clip(u, 0.0, self.params.i_sat)

    # ------------------------------------------------------------------ statics
    def _upper_height(self, current: float, z: float) -> float:
        """Height h balancing the upper magnet above a lower magnet at z (ignoring the top stop)."""
        forces = magnet_forces(self.params)
        return optimize.brentq(lambda h: forces(current, z, h)[1], z, z + 1e3, xtol=1e-12)

    def equilibrium(self, u: float) -> Equilibrium:
        """Solve the static force balance (:func:`~maglev.sim.forces.magnet_forces`) for constant command ``u`` [A]."""
        u_val = float(_checked_command(u, "u"))
        p = self.params
        current = float(self.current(u_val))
        forces = magnet_forces(p)
        h0 = self._upper_height(current, 0.0)
        if forces(current, 0.0, h0)[0] <= 0.0:  # the coil cannot lift the lower magnet off its seat
            z, h, seated = 0.0, h0, True
        else:
            def lower(z_: float) -> float:
                return forces(current, z_, self._upper_height(current, z_))[0]

            z_hi = 1.0
            while lower(z_hi) > 0:
                z_hi *= 2.0
            z = optimize.brentq(lower, 0.0, z_hi, xtol=1e-12)
            h, seated = self._upper_height(current, z), False
        at_top = h >= p.h_top
        if at_top:
            h = p.h_top
            if not seated:
                z = optimize.brentq(lambda z_: forces(current, z_, p.h_top)[0], 0.0, p.h_top, xtol=1e-12)
        return Equilibrium(u=u_val, current=current, z=z, h=h, y=float(self.reading(h)),
                           lower_seated=seated, upper_at_top=at_top)

    def static_curve(self, u: np.ndarray) -> np.ndarray:
        """Noise-free steady reading [cm] for each constant command in ``u``."""
        return np.array([self.equilibrium(float(v)).y for v in np.asarray(u, float).reshape(-1)])

    # ------------------------------------------------------------------ linearisation
    def linearize(self, u0: float, Ts: float = LABEL_TS, *, dry_friction: bool = True) -> LinearModel:
        """Equilibrium at command ``u0`` and the true linear model there (continuous and ZOH at ``Ts``).

        States are (z, h, dz/dt, dh/dt) in cm and cm/s, or (h, dh/dt) while the lower
        magnet is seated; the output is the reading deviation in cm and the input the
        command deviation in A (zero gain where the regulator saturates).

        Friction at rest (``dry_friction=True``): the model of *infinitesimal* motion about
        a long rest, with the full quiet-input and aged-contact damping (``gamma_quiet``,
        ``gamma_aged``) and, with ``v_creep > 0``, the optional dry friction's slope at rest
        ``(coulomb + stiction) / v_creep``.  Records with real excitation see much less
        damping; ``dry_friction=False`` gives the model in motion (``gamma`` only).  Set-valued
        friction (``v_creep = 0``) has no derivative at rest and is left out.
        """
        Ts = _checked_ts(Ts)
        eq = self.equilibrium(u0)
        p = self.params
        k = _CM / p.m
        # d(force on lower, on upper) / d(current, z, h), exact derivatives of the integrators' force law
        (dl_di, dl_dz, dl_dh), (du_di, du_dz, du_dh) = force_slopes(p, eq.current, eq.z, eq.h)
        dy_dh = self.reading_slope(eq.h)
        gain_u = 0.0 if (self.zero_at_10 and eq.u >= U_MAX) or not 0.0 < eq.u < p.i_sat else 1.0
        gl, gu = p.gamma_lower / p.m, p.gamma_upper / p.m
        if dry_friction:  # at rest: a quiet input and contacts aged without bound
            gl += (p.gamma_quiet_lower + p.gamma_aged_lower) / p.m
            gu += (p.gamma_quiet_upper + p.gamma_aged_upper) / p.m
            if p.v_creep > 0:  # the smooth dry friction's slope at rest, (coulomb + stiction) / v_creep
                ivs2, ivc = 1.0 / p.v_stribeck ** 2, 1.0 / p.v_creep
                gl += k * friction(0.0, 0.0, p.coulomb_lower, p.stiction_lower, ivs2, ivc)[1]
                gu += k * friction(0.0, 0.0, p.coulomb_upper, p.stiction_upper, ivs2, ivc)[1]
        if eq.upper_at_top:
            # the upper magnet is pressed against its stop: the reading cannot move
            A = np.array([[-1.0]])
            B = np.zeros((1, 1))
            C = np.zeros((1, 1))
        elif eq.lower_seated:
            A = np.array([[0.0, 1.0], [k * du_dh, -gu]])
            B = np.array([[0.0], [k * du_di * gain_u]])
            C = np.array([[dy_dh, 0.0]])
        else:
            A = np.array([
                [0.0, 0.0, 1.0, 0.0],
                [0.0, 0.0, 0.0, 1.0],
                [k * dl_dz, k * dl_dh, -gl, 0.0],
                [k * du_dz, k * du_dh, 0.0, -gu],
            ])
            B = np.array([[0.0], [0.0], [k * dl_di * gain_u], [k * du_di * gain_u]])
            C = np.array([[0.0, dy_dh, 0.0, 0.0]])
        import control as ct

        scale = self.time_scale()
        sys_c = ct.ss(A * scale, B * scale, C, np.zeros((1, 1)))
        nd = self.delay_samples(Ts)
        sys_d = ct.sample_system(sys_c, Ts, method="zoh")
        if nd > 0:
            delay = ct.ss(np.eye(nd, k=-1), np.eye(nd, 1), np.eye(1, nd, nd - 1), np.zeros((1, 1)), Ts)
            sys_d = ct.series(delay, sys_d)
        return LinearModel(equilibrium=eq, sys_c=sys_c, sys_d=sys_d, Ts=Ts, delay_samples=nd,
                           time_scale=scale)

    # ------------------------------------------------------------------ simulation
    def simulate(
        self,
        u: np.ndarray,
        Ts: float = LABEL_TS,
        seed: int | None = 0,
        *,
        noise: bool = True,
        start: float = 0.0,
        substeps: int | None = None,
        name: str | None = None,
    ) -> IOData:
        """Apply the command ``u`` [A] (held constant over each sample) and log the reading.

        The record starts from rest at the equilibrium of command ``start`` (0 A: both
        magnets down, as every lab record does).  ``noise=False`` gives the exact,
        noise-free, unquantised reading.  ``substeps`` integration steps per sample
        (default: enough for steps of <= 1.7 ms of physics).  The same ``seed`` gives
        the same record.  ``meta`` holds the true heights ``z``, ``h`` and the current.
        """
        Ts = _checked_ts(Ts)
        u = _checked_command(np.asarray(u, dtype=float).reshape(-1), "u")
        if u.size < 10:
            raise ValueError(f"u must have at least 10 samples, got {u.size}")
        p = self.params
        dt, substeps, eq0, cur = self._drive(u[np.newaxis], Ts, start, substeps)
        cur = cur[0]
        rng = np.random.default_rng(seed)
        if noise and p.force_noise > 0:
            force = rng.standard_normal(u.size) * p.force_noise
        else:
            force = np.zeros(u.size)
        if noise and p.wander_force > 0:  # its own stream: the other noises stay those of the plant without it
            force = force + self.wander(u, dt, np.random.default_rng(None if seed is None else [seed, _WANDER_STREAM]))
        z, h = _integrate(p, cur, force, dt, substeps, eq0.z, eq0.h)
        y = self.reading(h)
        if noise:
            y = y + self._sensor_noise(u.size, dt, rng)
            if p.switch_noise > 0:
                y = y + self._switch_noise(u, rng)
            if p.quant > 0:
                y = np.round(y / p.quant) * p.quant
        return IOData(u=u, y=y, Ts=Ts, name=name,
                      meta={"z": z, "h": h, "current": cur, "seed": seed,
                            "physical_time": self.physical_time, "params": asdict(p)})

    def simulate_batch(self, U: np.ndarray, Ts: float = LABEL_TS, *, start: float = 0.0,
                       substeps: int | None = None) -> np.ndarray:
        """Noise-free readings for each row of ``U`` (commands [A], one record per row): the
        outputs ``simulate(row, Ts, noise=False, start=start).y`` would give, all records
        integrated at once (numpy over the rows; equal to within rounding).  For the
        many realisations a best linear approximation averages over (:mod:`maglev.sim.bla`).
        """
        Ts = _checked_ts(Ts)
        U = _checked_command(np.atleast_2d(np.asarray(U, dtype=float)), "U")
        if U.ndim != 2 or U.shape[1] < 10:
            raise ValueError(f"U must be records x samples with at least 10 samples, got shape {U.shape}")
        dt, substeps, eq0, cur = self._drive(U, Ts, start, substeps)
        return self.reading(_integrate_batch(self.params, cur, dt, substeps, eq0.z, eq0.h))

    def wander(self, u: np.ndarray, dt: float, rng: np.random.Generator) -> np.ndarray:
        """The slow force [N] on the upper magnet, per sample of the command ``u``, that small steps drive
        (``simulate`` adds it as process noise; 0 without ``wander_force``).

        White noise times s^k times the command's |step| low-passed (pole ``WANDER_STEP_POLE``, unit gain)
        over ``WANDER_STEP_REF``, through an Ornstein-Uhlenbeck filter of correlation time ``wander_tau``
        (``dt``: physical seconds per sample) scaled to std ``wander_force``.  s is the share of small
        steps (nonzero and at most ``WANDER_SMALL_STEP``) over the last ≈ ``WANDER_WINDOW`` samples and
        k = ``wander_power``, so a binary or constant input drives none.  Why: on the rig the output of
        small white noise is mostly incoherent below 30 rad/s, while the
        constant-current record and the staircase show no such wander.
        """
        p = self.params
        du = np.abs(np.diff(u, prepend=u[0]))
        a_s = math.exp(-1.0 / WANDER_WINDOW)
        share = signal.lfilter([1.0 - a_s], [1.0, -a_s], ((du > 0) & (du <= WANDER_SMALL_STEP)).astype(float))
        steps = signal.lfilter([1.0 - WANDER_STEP_POLE], [1.0, -WANDER_STEP_POLE], du) / WANDER_STEP_REF
        drive = rng.standard_normal(u.size) * share ** p.wander_power * steps
        a = math.exp(-dt / p.wander_tau)
        return signal.lfilter([math.sqrt(1.0 - a * a) * p.wander_force], [1.0, -a], drive)

    def reading(self, h: float | np.ndarray) -> np.ndarray:
        """Noise-free laser reading [cm] of the upper magnet's height ``h`` [cm]: ``y_off + h``, stretched
        above the knee h_k by ``(h - h_k)^2 / (D - h)`` (D = ``sensor_pole``; 0 leaves the sensor linear).
        The stretch starts smoothly (value and slope continuous at the knee) and steepens towards D, as a
        reading linear in 1 / (D - h) does: the sensor is calibrated at 8 and 10 cm only, and the rig reads
        hops up to 15.6 cm where ECP's coil spacing puts the top near 12 cm (docs/simulator.md)."""
        p = self.params
        h = np.asarray(h, dtype=float)
        if not p.sensor_pole:
            return p.y_off + h
        over = np.maximum(h - p.sensor_knee, 0.0)
        return p.y_off + h + over ** 2 / (p.sensor_pole - h)

    def reading_slope(self, h: float) -> float:
        """d reading / d h at the height ``h`` [cm] (1 below the knee): the output gain of ``linearize``."""
        p = self.params
        if not p.sensor_pole or h <= p.sensor_knee:
            return 1.0
        over, room = h - p.sensor_knee, p.sensor_pole - h
        return 1.0 + (2.0 * over * room + over ** 2) / room ** 2

    def _drive(self, U: np.ndarray, Ts: float, start: float,
               substeps: int | None) -> tuple[float, int, Equilibrium, np.ndarray]:
        """What every simulation starts from, for commands ``U`` (records x samples, checked): physical
        seconds per sample, integration steps per sample (default: steps of <= 1.7 ms of physics), the
        equilibrium of command ``start``, and the coil current of each record after the input delay."""
        dt = Ts * self.time_scale()
        if substeps is None:
            substeps = max(1, math.ceil(dt / 1.7e-3))
        elif not isinstance(substeps, int) or substeps < 1:
            raise ValueError(f"substeps must be a positive integer, got {substeps!r}")
        eq0 = self.equilibrium(start)
        nd = self.delay_samples(Ts)
        cur = np.concatenate([np.full((U.shape[0], nd), eq0.current), self.current(U)], axis=1)[:, : U.shape[1]]
        return dt, substeps, eq0, cur

    def _switch_noise(self, u: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """A reading disturbance at each command switch: white noise scaled by ``switch_noise`` x |Δu|,
        through the pole ``switch_noise_pole`` (the rig's records wobble after each switch, in proportion
        to the step: docs/simulator.md)."""
        p = self.params
        du = np.abs(np.diff(u, prepend=u[0]))
        return signal.lfilter([1.0], [1.0, -p.switch_noise_pole], p.switch_noise * du * rng.standard_normal(u.size))

    def _sensor_noise(self, n: int, dt: float, rng: np.random.Generator) -> np.ndarray:
        """White noise plus an AR(2) line at the mains ripple aliased by the sample period ``dt``."""
        p = self.params
        f_line = p.noise_line_hz * dt % 1.0
        f_line = min(f_line, 1.0 - f_line)  # aliased frequency, cycles/sample in [0, 0.5]
        r, th = p.noise_line_radius, 2 * math.pi * f_line
        a1, a2 = -2 * r * math.cos(th), r * r
        var_ar = (1 + a2) / ((1 - a2) * ((1 + a2) ** 2 - a1 ** 2))
        burn = 200
        line = signal.lfilter([1.0], [1.0, a1, a2], rng.standard_normal(n + burn))[burn:]
        line /= math.sqrt(var_ar)
        white = rng.standard_normal(n)
        frac = p.noise_line_fraction
        return p.noise_std * (math.sqrt(frac) * line + math.sqrt(1 - frac) * white)


def _load_plants() -> dict[str, LevitatorParams]:
    """Every plant file under ``PLANTS_DIR``, each complete: a file that misses or adds a parameter is refused
    (a plant must not silently take another plant's numbers)."""
    names = {f.name for f in fields(LevitatorParams)}
    out = {}
    for path in sorted(PLANTS_DIR.glob("*.toml")):
        params = plant_file(path.stem)["params"]
        missing, extra = sorted(names - set(params)), sorted(set(params) - names)
        if missing or extra:
            raise ValueError(f"{path.name}: [params] must set every LevitatorParams field once; "
                             f"missing {missing}, unknown {extra}")
        out[path.stem] = LevitatorParams(**params)
    return out


# Named plants of the lab's rig, so that a study's config names the plant its data came from and a run logged
# before the default changed still reproduces (``dataset.plant``; docs/simulator.md, "Plants").
PLANTS: dict[str, LevitatorParams] = _load_plants()


def rig(plant: str = DEFAULT_PLANT) -> Levitator:
    """The lab's rig as the study simulates it: the named plant of ``PLANTS``, with the logger's quirk of
    writing a command >= 10 A as 0 A."""
    if plant not in PLANTS:
        raise ValueError(f"plant must be one of {sorted(PLANTS)}, got {plant!r}")
    return Levitator(PLANTS[plant], zero_at_10=True)


_REST_AGE = 10.0  # s (physical): contact age of both bushings when a record starts (at rest since long)


def _rate(hs: float, tau: float) -> float:
    """Update weight of a first-order low pass with time constant ``tau`` over a step ``hs`` (1: no lag)."""
    return min(hs / tau, 1.0) if tau > 0 else 1.0


class _Damping:
    """Viscous damping of both magnets [N per cm/s], substep by substep, for one record or many.

    ``gamma`` (in motion) + ``gamma_quiet / (1 + activity^power)`` + ``gamma_aged θ / (θ + age_half)``.
    The activity grades the input's class: the coil current band-passed between the low passes
    ``activity_slow`` and ``activity_fast``, over ``quiet_level + jitter_weight * jitter`` (the
    jitter: the current's |step| per sample, low-passed over ``jitter_tau``), through an envelope
    (attack ``activity_attack``, release ``activity_release``).  It depends on the input alone.
    θ is each bushing's contact age, the ageing law of rate-and-state friction
    ``dθ/dt = 1 - θ |v| / slip_renewal`` (backward Euler), so a magnet that has rested is damped
    more.  The same code runs on floats (one record) and on arrays (one element per record):
    :meth:`sample` at each logged sample, :attr:`lower`/:attr:`upper` for the velocity update,
    then :meth:`substep` with the new velocities.
    """

    def __init__(self, p: LevitatorParams, hs: float, dt: float, cur0: float | np.ndarray) -> None:
        # The state lives in the closures below, not in attributes: the integrator calls them once per
        # substep, and with attribute lookups there a record took 1.12 times as long (the same numbers).
        quiet = p.gamma_quiet_lower > 0 or p.gamma_quiet_upper > 0
        aged = p.gamma_aged_lower > 0 or p.gamma_aged_upper > 0
        fast_l, fast_u = _rate(hs, p.activity_fast_lower), _rate(hs, p.activity_fast_upper)
        slow_l, slow_u = _rate(hs, p.activity_slow_lower), _rate(hs, p.activity_slow_upper)
        up, down = _rate(hs, p.activity_attack), _rate(hs, p.activity_release)
        jitter_rate = _rate(dt, p.jitter_tau)
        inv_renewal = 1.0 / p.slip_renewal
        gamma_l, gamma_u = p.gamma_lower, p.gamma_upper
        quiet_l, quiet_u = p.gamma_quiet_lower, p.gamma_quiet_upper
        power_l, power_u = p.quiet_power_lower, p.quiet_power_upper
        level_l, level_u, weight = p.quiet_level_lower, p.quiet_level_upper, p.jitter_weight
        aged_l, aged_u, half = p.gamma_aged_lower, p.gamma_aged_upper, p.age_half
        f0 = f1 = f2 = f3 = cur0  # fast and slow low passes of the current, lower then upper
        env_l = env_u = 0.0 * cur0
        jitter, cur = 0.0 * cur0, cur0
        age_l = age_u = _REST_AGE + 0.0 * cur0

        def gammas() -> None:
            gl, gu = gamma_l, gamma_u
            if quiet:
                gl = gl + quiet_l / (1.0 + env_l ** power_l)
                gu = gu + quiet_u / (1.0 + env_u ** power_u)
            if aged:
                gl = gl + aged_l * age_l / (age_l + half)
                gu = gu + aged_u * age_u / (age_u + half)
            self.lower, self.upper = gl / _CM, gu / _CM

        def sample(new: float | np.ndarray) -> None:
            """A new logged sample with coil current ``new`` begins: update the jitter."""
            nonlocal jitter, cur
            jitter = jitter + jitter_rate * (abs(new - cur) - jitter)
            cur = new

        def substep(vz: float | np.ndarray, vh: float | np.ndarray) -> None:
            """After the velocity update: age the contacts, follow the activity, refresh the damping."""
            nonlocal age_l, age_u, f0, f1, f2, f3, env_l, env_u
            if aged:
                age_l = (age_l + hs) / (1.0 + hs * abs(vz) * inv_renewal)
                age_u = (age_u + hs) / (1.0 + hs * abs(vh) * inv_renewal)
            if quiet:
                c = cur
                f0 = f0 + fast_l * (c - f0)
                f1 = f1 + slow_l * (c - f1)
                f2 = f2 + fast_u * (c - f2)
                f3 = f3 + slow_u * (c - f3)
                spread = weight * jitter
                act_l = abs(f0 - f1) / (level_l + spread)
                act_u = abs(f2 - f3) / (level_u + spread)
                env_l = env_l + (down + (up - down) * (act_l > env_l)) * (act_l - env_l)
                env_u = env_u + (down + (up - down) * (act_u > env_u)) * (act_u - env_u)
            if quiet or aged:
                gammas()

        def ages() -> tuple[float | np.ndarray, float | np.ndarray]:
            """The contact ages θ of the lower and the upper bushing now [s of physics]."""
            return age_l, age_u

        self.lower: float | np.ndarray  # the dampings of the lower and the upper magnet now, set by gammas()
        self.upper: float | np.ndarray
        gammas()
        self.sample, self.substep, self.ages = sample, substep, ages


def _velocity_step(hk: float, fc: float, fs: float, ivs2: float, ivc: float, smooth: bool, batch: bool = False):
    """The velocity update of one magnet over one substep, for its dry-friction parameters.

    ``hk`` is the substep times the force-to-acceleration factor; the returned function maps (velocity,
    external force, viscous damping) to the new velocity (see :func:`_integrate`), on floats or, with
    ``batch``, on arrays with one element per record.  The friction is :mod:`maglev.sim.forces`' law.
    """
    exp, tanh = (np.exp, np.tanh) if batch else (math.exp, math.tanh)
    if fc + fs <= 0.0:  # viscous only: implicit Euler
        return lambda v, a, gamma: (v + hk * a) / (1.0 + hk * gamma)
    if smooth:  # one Newton step of backward Euler about the old velocity, the negative slope left explicit
        if batch:
            def step(v, a, gamma):
                force, slope = friction(v, gamma, fc, fs, ivs2, ivc, exp, tanh)
                return v + hk * (a - force - gamma * v) / (1.0 + hk * np.maximum(slope, 0.0))
        else:
            def step(v, a, gamma):
                force, slope = friction(v, gamma, fc, fs, ivs2, ivc, exp, tanh)
                return v + hk * (a - force - gamma * v) / (1.0 + hk * (slope if slope > 0.0 else 0.0))
        return step

    # set-valued: the magnet sticks when the trial velocity lies within the band the friction can cancel
    if batch:
        def stick_slip(v, a, gamma):
            damp = 1.0 + hk * gamma
            band = hk * (stribeck_level(v, fc, fs, ivs2, exp) if fs else fc) / damp  # the same numbers
            v = (v + hk * a) / damp
            return v - np.clip(v, -band, band)  # v - band above the band, v + band below it, 0.0 within
    else:
        def stick_slip(v, a, gamma):
            damp = 1.0 + hk * gamma
            band = hk * stribeck_level(v, fc, fs, ivs2, exp) / damp
            v = (v + hk * a) / damp
            return v - band if v > band else (v + band if v < -band else 0.0)
    return stick_slip


def _integrate(p: LevitatorParams, cur: np.ndarray, force: np.ndarray, dt: float, substeps: int,
               z0: float, h0: float) -> tuple[np.ndarray, np.ndarray]:
    """Semi-implicit Euler on plain floats: (linearly) implicit friction, explicit forces.

    Velocities are updated first with the forces at the current positions (:func:`~maglev.sim.forces.magnet_forces`)
    and the friction treated implicitly, then positions with the new velocities; the seat (z >= 0) and the top
    stop (h <= h_top) are inelastic.  The viscous damping varies from substep to substep (:class:`_Damping`)
    and is implicit.  With ``v_creep > 0`` the dry friction (Coulomb + Stribeck, tanh-regularised,
    :func:`~maglev.sim.forces.friction`) is linearised about the old velocity,
    ``v' = v + hs (a_ext - k F(v)) / (1 + hs k max(F'(v), 0))`` - one Newton step of backward Euler, stable however
    steep the tanh is (the velocity-weakening part, whose slope is negative, stays explicit).  With
    ``v_creep = 0`` the dry friction is set-valued (exact stick-slip): a magnet sticks when the trial velocity
    lies within the band the friction level at the old speed can cancel in one step.  Returns the heights at
    the start of every sample (sample-then-actuate, as the lab's logging loop and the ZOH model assume).
    """
    hs = dt / substeps
    hk = hs * (_CM / p.m)  # as the force-to-acceleration factor k = 100 / m, times the substep
    top = p.h_top
    step_l, step_u = _velocity_steps(p, hk, batch=False)
    forces = magnet_forces(p)
    cur_list = cur.tolist()
    damping = _Damping(p, hs, dt, cur_list[0])
    sample, substep = damping.sample, damping.substep
    z, h, vz, vh = z0, h0, 0.0, 0.0
    zs = [0.0] * len(cur)
    hs_out = [0.0] * len(cur)
    for i, (i_c, f_n) in enumerate(zip(cur_list, force.tolist())):
        zs[i] = z  # the reading is taken at the start of the sample, then the new current acts
        hs_out[i] = h
        sample(i_c)
        for _ in range(substeps):
            az, ah = forces(i_c, z, h)  # N, external force on the lower and the upper magnet
            vz = step_l(vz, az, damping.lower)
            vh = step_u(vh, ah + f_n, damping.upper)
            substep(vz, vh)
            z += hs * vz
            h += hs * vh
            if z < 0.0:
                z, vz = 0.0, 0.0
            if h > top:
                h, vh = top, 0.0
    return np.array(zs), np.array(hs_out)


def _velocity_steps(p: LevitatorParams, hk: float, batch: bool):
    """The lower and the upper magnet's :func:`_velocity_step` for the plant ``p``."""
    ivs2 = 1.0 / (p.v_stribeck * p.v_stribeck)
    smooth = p.v_creep > 0.0
    ivc = 1.0 / p.v_creep if smooth else 0.0
    return (_velocity_step(hk, p.coulomb_lower, p.stiction_lower, ivs2, ivc, smooth, batch),
            _velocity_step(hk, p.coulomb_upper, p.stiction_upper, ivs2, ivc, smooth, batch))


def _integrate_batch(p: LevitatorParams, cur: np.ndarray, dt: float, substeps: int, z0: float,
                     h0: float) -> np.ndarray:
    """:func:`_integrate` without the force disturbance, for every row of ``cur`` at once; returns
    the upper magnet's heights (records x samples).  Each substep costs a few dozen numpy
    operations on the rows, so a batch of a few hundred records runs ≈ 10x faster than a loop."""
    hs = dt / substeps
    hk = hs * (_CM / p.m)  # as the force-to-acceleration factor k = 100 / m, times the substep
    step_l, step_u = _velocity_steps(p, hk, batch=True)
    forces = magnet_forces(p)
    rows = cur.shape[0]
    z, h = np.full(rows, z0), np.full(rows, h0)
    vz, vh = np.zeros(rows), np.zeros(rows)
    damping = _Damping(p, hs, dt, cur[:, 0].copy())
    out = np.empty_like(cur)
    for i in range(cur.shape[1]):
        out[:, i] = h
        i_c = cur[:, i]
        damping.sample(i_c)
        for _ in range(substeps):
            az, ah = forces(i_c, z, h)
            vz = step_l(vz, az, damping.lower)
            vh = step_u(vh, ah, damping.upper)
            damping.substep(vz, vh)
            z = z + hs * vz
            h = h + hs * vh
            seated = z < 0.0
            if seated.any():
                z, vz = np.where(seated, 0.0, z), np.where(seated, 0.0, vz)
            stopped = h > p.h_top
            if stopped.any():
                h, vh = np.where(stopped, p.h_top, h), np.where(stopped, 0.0, vh)
    return out


def _checked_command(u: float | np.ndarray, name: str) -> np.ndarray:
    """The command as a float array, refusing values outside the rig's 0-10 A range."""
    arr = np.asarray(u, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite currents in A, got NaN/inf")
    bad = (arr < U_MIN) | (arr > U_MAX)
    if bad.any():
        first = arr[bad].reshape(-1)[0]
        raise ValueError(
            f"{name} must stay within the rig's current range [{U_MIN:g}, {U_MAX:g}] A, "
            f"got {first!r} ({int(bad.sum())} value(s) outside)"
        )
    return arr


def _checked_ts(Ts: float) -> float:
    Ts_f = float(Ts)
    if not (math.isfinite(Ts_f) and Ts_f > 0):
        raise ValueError(f"Ts must be a positive number of seconds, got {Ts!r}")
    return Ts_f
