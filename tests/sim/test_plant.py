"""Tests of maglev.sim.plant: statics against the force balance, stops, linearisation, noise, speed."""

import re
from dataclasses import fields, replace

import control as ct
import numpy as np
import pytest
from scipy import signal

from maglev.estimation import arx
from maglev.sim import plant as plant_mod
from maglev.sim.plant import (_REST_AGE, DEFAULT_PLANT, PLANTS, WANDER_STEP_REF, Levitator, LevitatorParams, _Damping,
                              plant_file, rig)
from maglev.sim.forces import force_slopes, friction, magnet_forces, stribeck_level
from maglev.lab.signals import random_binary

STICK_SLIP = PLANTS["stick_slip"]  # the plant these tests' numbers were measured on (light Coulomb friction)


def _forces(p: LevitatorParams, current: float, z: float, h: float) -> tuple[float, float]:
    """Net static force on the lower and upper magnet, written out from the force laws."""
    fm = p.c / (h - z + p.d) ** 4
    lower = current / (p.a * (z + p.b) ** p.n_coil) - fm - p.m * p.g
    upper = fm - p.kappa * current / (p.a * (h + p.b) ** p.n_coil) - p.m * p.g
    return lower, upper


@pytest.mark.parametrize("u0", [0.0, 1.0, 2.0, 2.75, 3.5])
def test_equilibrium_balances_forces_and_is_where_the_simulation_settles(u0):
    # without dry friction the simulation settles on the equilibrium; stick_slip's set-valued Coulomb friction
    # (0.003 / 0.0015 N) holds the magnets within its band of equilibria, a few hundredths of a mm short
    lev = Levitator(STICK_SLIP).with_params(**NO_DRY_FRICTION)
    eq = lev.equilibrium(u0)
    lower, upper = _forces(lev.params, eq.current, eq.z, eq.h)
    assert abs(upper) < 1e-9
    if eq.lower_seated:
        assert eq.z == 0.0 and lower <= 0.0  # the seat carries the rest
    else:
        assert abs(lower) < 1e-9
    data = lev.simulate(np.full(3000, u0), noise=False)
    assert data.meta["h"][-1] == pytest.approx(eq.h, abs=1e-6)
    assert data.meta["z"][-1] == pytest.approx(eq.z, abs=1e-6)
    assert data.y[-1] == pytest.approx(eq.y, abs=1e-6)
    held = Levitator(STICK_SLIP).simulate(np.full(3000, u0), noise=False)
    assert held.meta["h"][-1] == pytest.approx(eq.h, abs=0.01)
    assert held.meta["z"][-1] == pytest.approx(eq.z, abs=0.01)


def test_dead_zone_and_saturation_of_the_static_curve():
    lev = Levitator(STICK_SLIP)
    y = lev.static_curve(np.array([0.0, 0.5, 1.0, 2.0, 3.0, 5.0, 9.5]))
    assert np.ptp(y[:3]) < 0.1  # dead zone: lower magnet seated
    assert y[4] - y[3] > 0.2  # sensitive once levitated
    assert y[5] == pytest.approx(y[6], abs=1e-12)  # regulator saturation
    assert lev.equilibrium(0.5).lower_seated and not lev.equilibrium(2.0).lower_seated


def test_seat_and_top_stop_hold():
    lev = Levitator(STICK_SLIP)
    low = lev.simulate(random_binary(3000, 0.1, 0.0, 1.0, seed=1), noise=False)
    assert np.all(low.meta["z"] == 0.0)  # below lift-off the lower magnet never leaves its seat
    wild = lev.simulate(random_binary(5000, 0.02, 0.0, 4.0, seed=2), noise=False)
    assert wild.meta["z"].min() == 0.0 and wild.meta["z"].max() > 1.0
    capped = lev.with_params(h_top=8.6)
    data = capped.simulate(np.full(2000, 3.5), noise=False)
    assert data.meta["h"].max() <= 8.6
    assert data.meta["h"][-1] == 8.6 and capped.equilibrium(3.5).upper_at_top


NO_DRY_FRICTION = dict(coulomb_lower=0.0, coulomb_upper=0.0)  # stick_slip's set-valued Coulomb friction off
IN_MOTION = dict(gamma_quiet_lower=0.0, gamma_quiet_upper=0.0, gamma_aged_lower=0.0, gamma_aged_upper=0.0,
                 **NO_DRY_FRICTION)  # the damping in motion alone: what linearize(dry_friction=False) has


@pytest.mark.parametrize("law", ["default", "smooth", "set-valued", "viscous", "stretched sensor"])
def test_batch_simulation_is_the_loop_over_records(law):
    """``simulate_batch`` (the BLA's many realisations at once) gives each record's noise-free reading,
    for each friction law, with records that stay seated, reach the top stop, or hop about."""
    lev = {"default": rig("stick_slip"),
           "smooth": Levitator(STICK_SLIP).with_params(coulomb_lower=0.007, coulomb_upper=0.05, stiction_lower=0.36,
                                             stiction_upper=0.09),
           "set-valued": Levitator(STICK_SLIP).with_params(v_creep=0.0, coulomb_lower=0.15, coulomb_upper=0.05),
           "viscous": Levitator(STICK_SLIP).with_params(**IN_MOTION),
           "stretched sensor": Levitator(STICK_SLIP).with_params(h_top=9.0, sensor_knee=8.5, sensor_pole=11.0)}[law].with_params(h_top=9.0)
    U = np.array([random_binary(1500, 0.1, 0.0, 1.0, seed=1), random_binary(1500, 0.02, 0.0, 4.0, seed=2),
                  np.full(1500, 4.5), random_binary(1500, 0.25, 1.5, 4.0, seed=3)])
    loop = np.array([lev.simulate(u, Ts=0.002, noise=False, start=1.0).y for u in U])
    batch = lev.simulate_batch(U, Ts=0.002, start=1.0)
    assert loop[2].max() == lev.reading(9.0)  # the top stop is reached
    np.testing.assert_allclose(batch, loop, rtol=0, atol=1e-9)


def test_levitator_and_rig_are_the_same_plant_the_default_one():
    # LevitatorParams' defaults are the default plant's file, so a Levitator() and the study's rig() simulate the
    # same physics; rig() only adds the logger's quirk of writing >= 10 A as 0 A
    assert LevitatorParams() == PLANTS[DEFAULT_PLANT] == rig().params == Levitator().params
    assert LevitatorParams() == LevitatorParams(**plant_file(DEFAULT_PLANT)["params"])
    u = random_binary(1500, 0.25, 1.5, 4.0, seed=4)
    np.testing.assert_array_equal(Levitator().simulate(u, seed=1).y, rig().simulate(u, seed=1).y)
    assert rig().zero_at_10 and not Levitator().zero_at_10


@pytest.mark.parametrize("name", sorted(PLANTS))
def test_a_named_plant_is_a_complete_file_with_its_provenance(name):
    """A study run names its plant (``dataset.plant``) so that it reproduces after the default changes: each
    plant's file sets every parameter (none taken from another plant) and says where its numbers came from."""
    data = plant_file(name)
    assert set(data["params"]) == {f.name for f in fields(LevitatorParams)}
    assert all(type(v) is float for v in data["params"].values())  # written as floats, read back bit for bit
    assert rig(name).params == LevitatorParams(**data["params"])
    assert data["description"] and {"fitted_by", "records", "passes"} <= set(data["provenance"])


def test_a_plant_file_that_misses_a_parameter_is_refused_naming_it(tmp_path, monkeypatch):
    text = (plant_mod.PLANTS_DIR / "stick_slip.toml").read_text()
    (tmp_path / "partial.toml").write_text(text.replace("\ng = 9.81\n", "\n"))
    monkeypatch.setattr(plant_mod, "PLANTS_DIR", tmp_path)
    with pytest.raises(ValueError, match=r"partial.toml: \[params\] must set every LevitatorParams field once; "
                       r"missing \['g'\], unknown \[\]"):
        plant_mod._load_plants()
    with pytest.raises(ValueError, match=r"plant must be one of \['partial'\], got 'nope'"):
        plant_file("nope")


def test_the_wander_is_an_ornstein_uhlenbeck_force_scaled_by_the_small_steps():
    # every step of U(2, 2.75) A is small (at most 1 A), and their mean |step| is a third of the range, 0.25 A:
    # 0.3 of WANDER_STEP_REF. After the share of small steps has settled at 1, the force is white noise times
    # the low-passed |step| (≈ 0.3, scattering by ≈ 1 % of its power) through a first-order filter that keeps
    # the variance: std 0.3 x wander_force, autocorrelation a^k at lag k with a = e^(-dt/τ)
    lev = Levitator(replace(STICK_SLIP, wander_force=0.02, wander_tau=0.3, wander_power=2.0))
    u = np.random.default_rng(0).uniform(2.0, 2.75, 400_000)
    assert 0.25 / WANDER_STEP_REF == pytest.approx(0.3)
    force = lev.wander(u, 0.006, np.random.default_rng(1))[1000:]
    assert force.std() == pytest.approx(0.3 * 0.02, rel=0.03)
    a = np.exp(-0.006 / 0.3)
    for lag, tol in ((1, 0.002), (50, 0.03)):
        assert np.corrcoef(force[:-lag], force[lag:])[0, 1] == pytest.approx(a ** lag, abs=tol)
    # a random binary input steps by its whole range or not at all: no small step, no force; the same for a
    # constant input, and for any input without wander_force (the default)
    binary = random_binary(5000, 0.25, 1.5, 3.0, seed=3)
    assert not lev.wander(binary, 0.006, np.random.default_rng(1)).any()
    assert not lev.wander(np.full(5000, 3.0), 0.006, np.random.default_rng(1)).any()
    assert STICK_SLIP.wander_force == 0.0
    assert not Levitator(STICK_SLIP).wander(u[:5000], 0.006, np.random.default_rng(1)).any()


def test_the_wander_is_process_noise_that_leaves_binary_records_and_the_exact_response_alone():
    base = Levitator(STICK_SLIP)
    wandering = base.with_params(wander_force=0.05)
    binary = random_binary(3000, 0.25, 1.5, 4.0, seed=2)
    np.testing.assert_array_equal(wandering.simulate(binary, seed=3).y, base.simulate(binary, seed=3).y)
    small = np.random.default_rng(4).uniform(1.75, 2.5, 3000)
    assert not np.array_equal(wandering.simulate(small, seed=3).y, base.simulate(small, seed=3).y)
    np.testing.assert_array_equal(wandering.simulate(small, seed=3).y, wandering.simulate(small, seed=3).y)
    np.testing.assert_array_equal(wandering.simulate(small, noise=False).y, base.simulate(small, noise=False).y)


def test_logging_quirk_zero_at_10():
    quirky = rig("stick_slip")
    assert quirky.equilibrium(10.0).y == pytest.approx(quirky.equilibrium(0.0).y)
    assert Levitator(STICK_SLIP).equilibrium(10.0).y == pytest.approx(Levitator(STICK_SLIP).equilibrium(5.0).y)


def _dominant(poles, Ts):
    """(ωn, ζ) of the slowest complex pair, else of the slowest real pole (ζ = 1); poles at the
    origin (the delay's) have no continuous counterpart and are left out."""
    poles = np.asarray(poles, dtype=complex)
    s = np.log(poles[poles != 0]) / Ts
    cplx = s[s.imag > 1e-9]
    pick = cplx if cplx.size else s
    p = pick[np.argmin(np.abs(pick))]
    return abs(p), -p.real / abs(p)


@pytest.mark.parametrize("viscous_only", [False, True])
def test_linearisation_matches_small_signal_identification(viscous_only):
    # a small input about a rest sees the friction's full damping at rest, which the Jacobian
    # includes; without the quiet-input and aged-contact damping the modes are a light complex pair.
    # The Jacobian leaves out the set-valued Coulomb friction, which has no slope at rest: with it, as in
    # stick_slip, a ±0.01 A input does not move the magnets at all
    u = 2.75 + 0.01 * (random_binary(8000, 0.5, -1.0, 1.0, seed=4))
    assert np.ptp(Levitator(STICK_SLIP).simulate(u, noise=False, start=2.75).y) == 0.0
    lev = Levitator(STICK_SLIP).with_params(**NO_DRY_FRICTION)
    if viscous_only:
        lev = lev.with_params(**IN_MOTION)
        assert np.iscomplex(ct.poles(lev.linearize(2.75).sys_c)).any()
    lin = lev.linearize(2.75)
    data = lev.simulate(u, noise=False, start=2.75, substeps=16)
    data = data.trim(500).detrend()
    nd = lin.delay_samples
    model = arx(data, 4, 4, nd + 1)  # ZOH: one sample of lag plus the pure delay
    wn_id, z_id = _dominant(model.poles(), data.Ts)
    wn_true, z_true = _dominant(ct.poles(lin.sys_d), lin.Ts)
    assert wn_id == pytest.approx(wn_true, rel=0.03)
    assert z_id == pytest.approx(z_true, rel=0.05)
    # the continuous model's poles map onto the discrete ones
    pc = np.sort_complex(np.exp(ct.poles(lin.sys_c) * lin.Ts))
    pd = np.sort_complex(ct.poles(lin.sys_d)[np.abs(ct.poles(lin.sys_d)) > 1e-9])
    assert np.allclose(pc, pd, atol=1e-9)


def test_friction_law_levels_and_slopes():
    fc, fs, vs, vc, gamma = 0.05, 0.03, 2.0, 0.4, 0.015  # gamma in N s/cm

    def law(v: float) -> tuple[float, float]:
        return friction(v, gamma, fc, fs, 1 / vs ** 2, 1 / vc)

    force0, slope0 = law(0.0)
    assert force0 == 0.0
    assert slope0 == pytest.approx((fc + fs) / vc + gamma)  # creep regime: heavy damping at rest
    fast, _ = law(50.0)
    assert fast == pytest.approx(fc, rel=1e-9)  # Stribeck peak gone: the Coulomb level
    assert stribeck_level(50.0, fc, fs, 1 / vs ** 2) == pytest.approx(fc) and stribeck_level(0.0, fc, fs, 1.0) == fc + fs
    peak = max(law(v)[0] for v in np.linspace(0.01, 10, 500))
    assert fc < peak < fc + fs  # velocity weakening: the dry part peaks above the Coulomb level
    for v in (-3.0, 0.3, 1.1, 4.0):
        f, s = law(v)
        assert law(-v)[0] == pytest.approx(-f)
        num = (law(v + 1e-6)[0] - law(v - 1e-6)[0]) / 2e-6 + gamma  # the slope includes the viscous part
        assert s == pytest.approx(num, rel=1e-5, abs=1e-9)
    # the batch integrator's arrays give the scalar integrator's numbers (numpy's tanh to rounding)
    v = np.array([-3.0, 0.3, 1.1])
    forces, slopes = friction(v, gamma, fc, fs, 1 / vs ** 2, 1 / vc, np.exp, np.tanh)
    assert forces == pytest.approx([law(x)[0] for x in v], rel=1e-14)
    assert slopes == pytest.approx([law(x)[1] for x in v], rel=1e-14)


@pytest.mark.parametrize("name", ["stuck_stretched", "dry_friction"])
def test_the_force_law_is_coil_push_and_pull_repulsion_and_weight_and_linearize_its_exact_slopes(name):
    """One force law for the equilibrium, linearize and both integrators: written out here from the physics
    (``_forces``), on floats and arrays alike, with complex-step slopes equal to the hand-derived ones."""
    p = PLANTS[name]
    forces = magnet_forces(p)
    for current, z, h in ((2.5, 0.4, 7.9), (0.0, 0.0, 6.0), (3.9, 1.2, 9.5)):
        assert forces(current, z, h) == pytest.approx(_forces(p, current, z, h), rel=1e-14)
        gap = h - z
        dfm = -4.0 * p.c / (gap + p.d) ** 5
        dfc_dz = -p.n_coil * current / (p.a * (z + p.b) ** (p.n_coil + 1))
        dfa_dh = -p.n_coil * p.kappa * current / (p.a * (h + p.b) ** (p.n_coil + 1))
        by_hand = [[1 / (p.a * (z + p.b) ** p.n_coil), dfc_dz + dfm, -dfm],
                   [-p.kappa / (p.a * (h + p.b) ** p.n_coil), -dfm, dfm - dfa_dh]]
        np.testing.assert_allclose(force_slopes(p, current, z, h), by_hand, rtol=1e-12, atol=1e-15)
    lower, upper = forces(np.array([2.5, 3.9]), np.array([0.4, 1.2]), np.array([7.9, 9.5]))
    assert lower == pytest.approx([forces(2.5, 0.4, 7.9)[0], forces(3.9, 1.2, 9.5)[0]], rel=1e-14)
    assert upper == pytest.approx([forces(2.5, 0.4, 7.9)[1], forces(3.9, 1.2, 9.5)[1]], rel=1e-14)
    eq = Levitator(p).equilibrium(2.75)  # the equilibrium is where this law balances
    assert abs(forces(eq.current, eq.z, eq.h)[1]) < 1e-9


def test_friction_makes_the_gain_amplitude_dependent():
    lev = Levitator(STICK_SLIP)
    base = lev.with_params(**IN_MOTION)

    def gain(plant, amp):
        u = random_binary(6000, 0.25, 2.75 - amp, 2.75 + amp, seed=3)
        d = plant.simulate(u, noise=False, start=2.75).trim(1000)
        return np.std(d.y) / np.std(d.u)

    small, large = gain(lev, 0.05), gain(lev, 1.25)
    assert large > 2.0 * small  # small motions are held back by the quiet-input and aged-contact damping
    assert gain(base, 1.25) / gain(base, 0.05) < 1.5  # without them the plant is nearly linear
    # small-signal (Jacobian) damping includes the friction's damping at rest
    zeta = [_dominant(ct.poles(lev.linearize(2.75, dry_friction=dry).sys_d), 1e-3)[1] for dry in (True, False)]
    assert zeta[0] > zeta[1]


def _mean_damping(p: LevitatorParams, u: np.ndarray, substeps: int = 4) -> float:
    """Mean quiet-input damping of the upper magnet [N s/m] over the command ``u``, magnets held still."""
    hs = p.t_phys / substeps
    damping = _Damping(p, hs, p.t_phys, float(u[0]))
    total = []
    for c in u:
        damping.sample(float(c))
        for _ in range(substeps):
            damping.substep(0.0, 0.0)
            total.append(damping.upper)
    return 100 * float(np.mean(total)) - p.gamma_upper - p.gamma_aged_upper * 1.0


def test_quiet_damping_grades_the_input_class_not_its_range():
    """The rig's damping depends on the input's class (binary α .25 < α .5 < white noise; notes §4.6,
    docs/simulator.md), not on its range: the activity divides the band-passed current by its jitter."""
    p = replace(STICK_SLIP, gamma_aged_upper=0.0)
    rng = np.random.default_rng(5)
    classes = {"α .25": random_binary(6000, 0.25, 1.5, 4.0, seed=1),
               "α .5": random_binary(6000, 0.5, 1.5, 4.0, seed=2),
               "white": rng.uniform(1.5, 4.0, 6000)}
    damping = {k: _mean_damping(p, u) for k, u in classes.items()}
    assert damping["α .25"] < damping["α .5"] < damping["white"] < p.gamma_quiet_upper
    narrow = random_binary(6000, 0.25, 2.25, 3.25, seed=1)  # same class, 40 % of the range
    assert _mean_damping(p, narrow) < 0.25 * damping["α .5"]  # still graded as α .25
    # without the jitter the band pass alone cannot tell the classes apart: all are active
    unscaled = replace(p, jitter_weight=0.0)
    assert max(_mean_damping(unscaled, u) for u in classes.values()) < 0.05 * p.gamma_quiet_upper
    assert _mean_damping(p, np.full(500, 2.75)) == pytest.approx(p.gamma_quiet_upper)  # a constant input is quiet


def test_contact_ageing_law():
    """θ grows one second per second at rest and settles at slip_renewal / |v| in steady sliding."""
    p = STICK_SLIP
    hs = 1e-3
    damping = _Damping(p, hs, hs, 2.75)
    for _ in range(2000):
        damping.substep(0.0, 0.0)
    age_l, _ = damping.ages()
    assert age_l == pytest.approx(_REST_AGE + 2.0)
    aged = p.gamma_lower + p.gamma_quiet_lower + p.gamma_aged_lower * age_l / (age_l + p.age_half)
    assert 100 * damping.lower == pytest.approx(aged)
    v = 5.0  # cm/s
    for _ in range(20000):
        damping.substep(v, -v)
    _, age_u = damping.ages()
    assert age_u == pytest.approx(p.slip_renewal / v, rel=1e-3)
    fresh = p.gamma_aged_upper * age_u / (age_u + p.age_half)
    assert 100 * damping.upper == pytest.approx(p.gamma_upper + p.gamma_quiet_upper + fresh)


def test_set_valued_stiction_holds_then_releases():
    sticky = Levitator(STICK_SLIP).with_params(**{**IN_MOTION, "v_creep": 0.0, "coulomb_lower": 0.15, "coulomb_upper": 0.05,
                                        "stiction_lower": 0.0, "stiction_upper": 0.0, "gamma_lower": 2.0,
                                        "gamma_upper": 0.5})
    held = sticky.simulate(np.full(500, 2.8), start=2.75, noise=False)
    eq = sticky.equilibrium(2.75)
    assert np.all(held.meta["h"] == eq.h) and np.all(held.meta["z"] == eq.z)  # stuck: no creep at all
    moved = sticky.simulate(np.full(500, 3.5), start=2.75, noise=False)
    jump = sticky.equilibrium(3.5).h - eq.h
    assert abs(moved.meta["h"][-1] - eq.h - jump) < 0.5 * jump  # a large force breaks it free
    smooth = sticky.with_params(v_creep=0.713)
    creeping = smooth.simulate(np.full(3000, 2.8), start=2.75, noise=False)  # smooth law: creeps home
    assert creeping.meta["h"][-1] == pytest.approx(smooth.equilibrium(2.8).h, abs=1e-6)


@pytest.mark.parametrize("knee", [None, 8.4])
def test_linear_gain_equals_static_slope(knee):
    """Also where the working point lies above the sensor's knee, whose stretch steepens the reading."""
    lev = Levitator(STICK_SLIP) if knee is None else Levitator(STICK_SLIP).with_params(sensor_knee=knee, sensor_pole=20.0)
    for u0 in (2.0, 3.0):
        slope = (lev.equilibrium(u0 + 1e-4).y - lev.equilibrium(u0 - 1e-4).y) / 2e-4
        lin = lev.linearize(u0)
        assert lin.dc_gain == pytest.approx(slope, rel=1e-4)
        assert float(np.real(ct.dcgain(lin.sys_d))) == pytest.approx(slope, rel=1e-4)
    if knee is not None:  # 3 A sits above the knee, 2 A below it
        assert lev.equilibrium(3.0).h > knee > lev.equilibrium(2.0).h
    assert lev.linearize(6.0).dc_gain == 0.0  # saturated regulator: no small-signal gain


def test_reading_is_linear_below_the_knee_and_stretched_above():
    """y = y_off + h up to the knee h_k; above it, a reading linear in 1 / (D - h) that meets the linear one in
    value and slope at the knee, y_off + h_k + (D - h_k) ((D - h_k) / (D - h) - 1), written out by hand on a
    record whose hops cross the knee; the stretch leaves the motion itself unchanged."""
    u = random_binary(4000, 0.25, 1.5, 4.0, seed=3)
    plain = Levitator(STICK_SLIP).simulate(u, noise=False)
    knee, D = float(np.percentile(plain.meta["h"], 70)), 18.0
    lev = Levitator(STICK_SLIP).with_params(sensor_knee=knee, sensor_pole=D)
    data = lev.simulate(u, noise=False)
    h, y0 = data.meta["h"], lev.params.y_off
    np.testing.assert_array_equal(h, plain.meta["h"])
    above = h > knee
    assert 0.1 < above.mean() < 0.5 and (h[above] - knee).max() > 0.5
    np.testing.assert_allclose(data.y[~above], y0 + h[~above], rtol=0, atol=1e-12)
    by_hand = y0 + knee + (D - knee) * ((D - knee) / (D - h[above]) - 1.0)
    np.testing.assert_allclose(data.y[above], by_hand, rtol=0, atol=1e-12)
    for x in (knee - 0.1, knee + 1e-9, knee + 1.0, 12.0):  # the slope linearize uses, continuous at the knee
        fd = (lev.reading(x + 1e-6) - lev.reading(x - 1e-6)) / 2e-6
        assert lev.reading_slope(x) == pytest.approx(float(fd), rel=1e-6)
    eq = lev.with_params(sensor_knee=Levitator(STICK_SLIP).equilibrium(3.0).h - 0.2).equilibrium(3.0)
    assert eq.y == pytest.approx(y0 + eq.h + 0.2 ** 2 / (D - eq.h), abs=1e-9)
    with pytest.raises(ValueError, match=r"sensor_pole must be 0 \(a linear sensor\) or above both h_top = 16.0"):
        Levitator(STICK_SLIP).with_params(sensor_pole=15.0)


def test_time_base_flag_stretches_transients():
    labelled, physical = Levitator(STICK_SLIP), Levitator(STICK_SLIP, physical_time=True)
    scale = labelled.params.t_phys / 1e-3
    assert labelled.time_scale() == pytest.approx(scale) and physical.time_scale() == 1.0
    wn_l = max(abs(p) for p in ct.poles(labelled.linearize(2.75).sys_c))
    wn_p = max(abs(p) for p in ct.poles(physical.linearize(2.75).sys_c))
    assert wn_l / wn_p == pytest.approx(scale)
    u = np.r_[np.full(1000, 2.5), np.full(3000, 3.0)]
    t_l = np.argmax(labelled.simulate(u, start=2.5, noise=False).y > labelled.equilibrium(2.75).y)
    t_p = np.argmax(physical.simulate(u, start=2.5, noise=False).y > physical.equilibrium(2.75).y)
    assert (t_p - 1000) / (t_l - 1000) == pytest.approx(scale, rel=0.25)


def test_noise_level_spectrum_quantisation_and_seed():
    lev = Levitator(STICK_SLIP)
    d1 = lev.simulate(np.full(20000, 3.0), seed=7)
    d2 = lev.simulate(np.full(20000, 3.0), seed=7)
    d3 = lev.simulate(np.full(20000, 3.0), seed=8)
    assert np.array_equal(d1.y, d2.y) and not np.array_equal(d1.y, d3.y)
    y = d1.y[5000:]
    p = lev.params
    assert np.std(y) == pytest.approx(p.noise_std, rel=0.15)
    grid = y / p.quant
    assert np.allclose(grid, np.round(grid), atol=1e-6)
    f, psd = signal.welch(y - y.mean(), nperseg=512)
    assert 0.30 <= f[np.argmax(psd)] <= 0.34  # mains ripple aliased as in the real records


@pytest.mark.parametrize("bad", [-0.5, 10.5])
def test_current_outside_range_is_refused(bad):
    u = np.full(100, 2.0)
    u[10] = bad
    with pytest.raises(ValueError, match=r"u must stay within .*\[0, 10\] A.*" + re.escape(repr(bad))):
        Levitator(STICK_SLIP).simulate(u)
    with pytest.raises(ValueError, match="u must stay within"):
        Levitator(STICK_SLIP).linearize(bad)


def test_bad_parameters_are_named():
    with pytest.raises(ValueError, match="LevitatorParams.m must be a positive number, got -1"):
        LevitatorParams(m=-1.0)
    with pytest.raises(ValueError, match="Ts must be"):
        Levitator(STICK_SLIP).simulate(np.full(100, 2.0), Ts=0.0)


def test_linearisation_lists_each_mode_once():
    # four states: in motion two complex pairs (two modes); at rest the slow pair is overdamped (two real poles)
    lev = Levitator(STICK_SLIP)
    in_motion = lev.linearize(2.75, dry_friction=False)
    poles = ct.poles(in_motion.sys_c)
    assert np.sum(poles.imag > 0) == 2 and len(in_motion.modes()) == 2
    assert sorted(w for w, _ in in_motion.modes()) == pytest.approx(sorted(abs(x) for x in poles if x.imag > 0))
    at_rest = lev.linearize(2.75).modes()
    assert len(at_rest) == 3 and sum(z == pytest.approx(1.0) for _, z in at_rest) == 2
