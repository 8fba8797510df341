"""The independent plant obeys its physics: energy, steady-state friction, its integrator's order."""
from __future__ import annotations

import numpy as np
import pytest

from mjjoint.benchmark.independent import (BoucWenLaw, JointPlant, LuGre, MaxwellSlip, Rod, StopHysteresis, TwoSEP,
                                          simulate)
from mjjoint.benchmark.independent.cases import CASES, make_case
from mjjoint.benchmark.independent.record import Excitation, low_pass, quantise


def _conservative(**over) -> JointPlant:
    values = dict(gear_ratio=100.0, motor_inertia=1e-4, link_inertia=0.2, stiffness=4000.0, damping=0.0,
                  gravity_moment=4.0, rod=Rod(tip_inertia=0.1, stiffness=500.0, damping=0.0, tip_gravity=2.0))
    values.update(over)
    return JointPlant(**values)


def _released(plant: JointPlant, duration: float, substeps: int) -> np.ndarray:
    """States of the plant released at rest from a wound-up gear and a raised link, u = 0."""
    s0 = plant.initial_state()
    s0[0], s0[2], s0[4] = 0.5 * plant.gear_ratio, 0.4, 0.45
    t = np.arange(0.0, duration, 1e-3)
    return simulate(plant, t, lambda k, s: 0.0, substeps, s0).states


def test_a_conservative_joint_keeps_its_energy():
    plant = _conservative()
    states = _released(plant, 1.0, 10)
    energy = np.array([plant.energy(s) for s in states])
    assert np.ptp(energy) < 1e-6 * energy[0]
    assert np.ptp(states[:, 2]) > 0.1  # it did move


def test_dissipation_only_removes_energy():
    """With gear damping, a load bearing and LuGre friction the stored energy never rises at u = 0
    beyond the bristle's small store."""
    plant = _conservative(damping=2.0, load_coulomb=0.3, load_viscous=0.05,
                          friction=LuGre(fc=0.03, fs=0.04, vs=1.0, sigma2=2e-4))
    energy = np.array([plant.energy(s) for s in _released(plant, 1.0, 10)])
    assert np.all(np.diff(energy) < 1e-6 * energy[0])
    assert energy[-1] < 0.5 * energy[0]


GEARS = {"linear": None,
         "bouc-wen": BoucWenLaw(mu=0.6, beta=400.0, gamma=100.0),
         "prandtl": StopHysteresis(elastic=2400.0, radii=(1e-3, 3e-3, 6e-3), weights=(540.0, 540.0, 540.0))}


@pytest.mark.parametrize("gear", GEARS.values(), ids=GEARS.keys())
def test_the_gear_is_passive_its_loops_dissipate(gear):
    """Over a deflection cycle (with minor loops) that ends where it began, the gear takes in the
    work W = int T d(de): none for the spring alone, the loop's area, positive, for a hysteretic
    gear (a passive gear gives nothing back over a cycle); its stored energy ends where it was."""
    plant = _conservative(hysteresis=gear)
    cycles = 2
    t = np.linspace(0.0, cycles * 2 * np.pi, 40001)
    de = 4e-3 * np.sin(t) + 1e-3 * np.sin(3 * t)  # minor loops inside the major one
    s = plant.initial_state()
    torque, stored = [], []
    for i, d in enumerate(de):
        s[0] = d * plant.gear_ratio
        if i and isinstance(gear, BoucWenLaw):  # the Bouc-Wen state over the deflection's step, exactly enough
            for _ in range(20):
                s[7] += gear.rate((de[i] - de[i - 1]) / 20, s[7])
        s = plant.project(s)
        torque.append(plant.transmission(s)[0])
        stored.append(plant.energy(s))
    torque, stored = np.array(torque), np.array(stored)
    half = len(t) // cycles  # the second cycle: the states on their loop
    work = np.sum(0.5 * (torque[half + 1:] + torque[half:-1]) * np.diff(de[half:]))
    scale = 0.5 * 4000.0 * 5e-3 ** 2
    if gear is None:
        assert abs(work) < 1e-6 * scale
    else:
        assert work > 0.01 * scale
    assert abs(stored[-1] - stored[half]) < 1e-3 * scale  # the cycle ends where it began


@pytest.mark.parametrize("gear", [g for g in GEARS.values() if g is not None], ids=["bouc-wen", "prandtl"])
def test_a_hysteretic_gear_only_removes_energy(gear):
    """Released from a wound-up gear at u = 0 the joint's kinetic, gravity and stored energy
    (the hysteretic gear's included) never rises, and the loops take a share of it."""
    plant = _conservative(hysteresis=gear)
    energy = np.array([plant.energy(s) for s in _released(plant, 1.0, 10)])
    assert np.all(np.diff(energy) < 1e-6 * energy[0])
    assert energy[-1] < 0.9 * energy[0]


SEED_2SEP = TwoSEP(fc=0.03, fs=0.05, vs=2.0, sigma2=1e-3, k=1000.0, b=20.0)


@pytest.mark.parametrize("friction, level", [
    (LuGre(fc=0.03, fs=0.05, vs=2.0, sigma2=1e-3, z0=0.05), 0.03),
    (MaxwellSlip(stiffness=(40.0, 10.0), slip=(0.02, 0.01), sigma2=1e-3), 0.03),
    (SEED_2SEP, 0.03)])
def test_steady_sliding_friction_is_the_coulomb_level_plus_viscous(friction, level):
    """A constant input on a joint without gravity ends at the speed where it balances the
    friction: u = Fc + sigma v + (Fl + dl v / N) / N (the Stribeck dip long decayed there)."""
    plant = JointPlant(gear_ratio=50.0, motor_inertia=1e-4, link_inertia=0.05, stiffness=2000.0, damping=1.0,
                       gravity_moment=0.0, load_coulomb=0.1, load_viscous=0.02, friction=friction)
    u = 0.05
    states = simulate(plant, np.arange(0.0, 1.5, 1e-3), lambda k, s: u, 10).states
    n = plant.gear_ratio
    v = (u - level - plant.load_coulomb / n) / (friction.sigma2 + plant.load_viscous / n ** 2)
    assert states[-1, 1] == pytest.approx(v, rel=1e-3)


def test_2sep_pre_sliding_follows_eq_12_from_the_memorised_reversal():
    """After a reversal at the Coulomb level, z1 = -Fc + 2 Fc (1 - exp(-K q_r)) along the new
    motion (Eq. 12 integrated over the travel q_r, Omega = 2 Fc from Eq. 13)."""
    f, w, h = SEED_2SEP, 0.05, 1e-5
    omega = f.reversal_memory(w, -f.fc, 0.0)
    z1, z2, qr = -f.fc, 0.0, 0.0
    for _ in range(400):  # explicit Euler over 0.2 mrad, 2 % of 1/K each step
        d1, d2, dq = f.rates(w, z1, z2, qr, omega)
        z1, z2, qr = z1 + h * d1, z2 + h * d2, qr + h * dq
    assert omega == pytest.approx(2 * f.fc)
    assert z1 == pytest.approx(-f.fc + 2 * f.fc * (1 - np.exp(-f.k * qr)), rel=0.02)


def test_2sep_stays_dissipative_through_reversals():
    """Under a sine drive just above break-away the rotor creeps and reverses, the friction stays
    within the drive plus the static level, and over the run it takes energy out. (With the lag
    state carried across reversals the same run reached 6.8 N m, 230 Fc: ``friction.TwoSEP``.)"""
    plant = JointPlant(gear_ratio=50.0, motor_inertia=1e-4, link_inertia=0.05, stiffness=2000.0, damping=1.0,
                       gravity_moment=0.0, load_coulomb=0.1, load_viscous=0.02, friction=SEED_2SEP)
    drive = 1.2 * SEED_2SEP.fs
    st = simulate(plant, np.arange(0.0, 1.0, 1e-3), lambda k, s: drive * np.sin(2 * np.pi * k * 1e-3), 10).states
    w = st[:, 1]
    force = np.array([SEED_2SEP.force(s[1], s[9], s[10]) for s in st])
    assert w.min() < 0 < w.max()
    assert np.abs(force).max() <= drive + SEED_2SEP.fs
    assert np.sum(force * w) > 0


@pytest.mark.parametrize("gain", [0.0, 0.3])
def test_steady_sliding_friction_grows_with_the_gear_torque(gain):
    """With a load-dependent level, u = Fc + g |T| / N + sigma v + T / N at a steady speed, where
    the gear carries the bearing's T = Fl + dl v / N."""
    lugre = LuGre(fc=0.03, fs=0.03, vs=1.0, sigma2=1e-3)
    plant = JointPlant(gear_ratio=50.0, motor_inertia=1e-4, link_inertia=0.05, stiffness=2000.0, damping=1.0,
                       gravity_moment=0.0, load_coulomb=0.1, load_viscous=2.0, friction=lugre, load_dependence=gain)
    u = 0.05
    states = simulate(plant, np.arange(0.0, 1.5, 1e-3), lambda k, s: u, 10).states
    n = plant.gear_ratio
    v = (u - lugre.fc - (1 + gain) * plant.load_coulomb / n) / (lugre.sigma2 + (1 + gain) * plant.load_viscous / n ** 2)
    assert states[-1, 1] == pytest.approx(v, rel=1e-3)


def test_rk4_converges_at_fourth_order():
    """On smooth physics each halving of the step cuts the error ~16x (a Bouc-Wen |.| or a dead
    zone's corner lower the order locally: those converge, more slowly)."""
    plant = _conservative(damping=1.0)
    ref = _released(plant, 0.2, 64)[-1]
    err = [np.abs(_released(plant, 0.2, m)[-1] - ref)[:4].max() for m in (2, 4, 8)]
    assert err[0] / err[1] > 12.0 and err[1] / err[2] > 12.0


def test_quantised_sensors_sit_on_their_grid():
    x = np.linspace(-3, 3, 1001)
    step = 2 * np.pi / 2 ** 12
    assert np.allclose(quantise(x, 12) / step, np.round(quantise(x, 12) / step))
    assert np.max(np.abs(quantise(x, 12) - x)) <= step / 2 + 1e-12


def test_the_torque_cells_low_pass_is_first_order_with_its_time_constant():
    """Sampled, a unit step's response is the continuous lag's (1 - 1/e after one time
    constant); a sine comes out late by the continuous lag's atan(w tc) / w as the rate grows."""
    tc, w = 2e-3, 2 * np.pi * 5.0
    step = low_pass(np.r_[0.0, np.ones(999)], tc, 1000.0)
    assert step[0] == 0.0 and np.allclose(step[1:], 1 - np.exp(-np.arange(1, 1000) / (1000.0 * tc)), rtol=1e-12)
    lags = []
    for rate in (1e3, 1e4, 1e5):
        t = np.arange(0.0, 1.0, 1.0 / rate)
        keep = t > 0.2  # the start's transient decayed
        out = low_pass(np.sin(w * t), tc, rate)[keep]
        a, b = np.linalg.lstsq(np.column_stack([np.sin(w * t[keep]), np.cos(w * t[keep])]), out, rcond=None)[0]
        lags.append(-np.arctan2(b, a) / w)
        assert np.hypot(a, b) == pytest.approx(1 / np.hypot(1, w * tc), abs=2e-3)
    errors = np.abs(np.array(lags) - np.arctan(w * tc) / w)
    assert errors[-1] < 0.01 * tc and errors[0] / errors[1] > 8 and errors[1] / errors[2] > 8
    assert np.array_equal(low_pass(np.arange(5.0), 0.0, 1000.0), np.arange(5.0))


def test_every_case_draws_a_plant_and_the_reference_is_continuous():
    for name in CASES:
        case = make_case(name, 0)
        assert case.plant.gear_ratio > 1 and case.plant.motor_inertia > 0
    t = np.arange(0.0, 6.0, 1e-3)
    ref = Excitation(seed=3).reference(t)
    assert np.max(np.abs(np.diff(ref))) < 2e-3   # no jumps: a closed loop would kick the joint


def test_moves_rest_between_minimum_jerk_profiles_within_the_sweep():
    """The point-to-point program: from 0, each move at rest where it starts and ends (velocity and
    acceleration zero at the joins: no jump for the loop to kick at), targets within +-sweep and at
    least sweep/2 apart, several moves in 6 s; an unknown program refused with the allowed ones."""
    t = np.arange(0.0, 6.0, 1e-3)
    ex = Excitation(seed=3, program="moves")
    ref = ex.reference(t)
    v = np.diff(ref) / 1e-3
    assert ref[0] == 0.0 and np.max(np.abs(v)) < 1.875 * 2 * ex.sweep / 0.8 + 1e-9
    assert np.max(np.abs(np.diff(v))) < 1e-2                    # smooth: no step in the velocity
    moving = np.abs(v) > 1e-9
    starts, stops = np.flatnonzero(moving[1:] & ~moving[:-1]) + 1, np.flatnonzero(~moving[1:] & moving[:-1]) + 1
    rests = ref[np.concatenate([[0], stops])]
    assert len(stops) >= 3 and np.all(np.abs(rests) <= ex.sweep)
    assert np.all(np.abs(np.diff(rests)) >= ex.sweep / 2)
    assert len(starts) == len(stops) or len(starts) == len(stops) + 1
    with pytest.raises(ValueError, match="allowed: sweep, moves"):
        Excitation(program="steps")


def test_a_case_records_at_the_rate_asked_and_a_rate_of_none_is_refused():
    """The sample rate (and the PD loop's) is the case's: 250 Hz gives 4 ms samples, the same
    plant and reference; no rate is refused with its range."""
    from mjjoint.benchmark.independent.record import record
    slow, fast = make_case("control", 0, 0.5, rate=250.0), make_case("control", 0, 0.5)
    assert slow.plant == fast.plant and slow.excitation.rate == 250.0
    cols = record(slow.plant, slow.excitation, slow.sensors, 0)
    assert len(cols["t"]) == 125 and np.allclose(np.diff(cols["t"]), 4e-3)
    assert np.all(np.isfinite(cols["q"])) and np.all(np.isfinite(cols["tau"]))
    with pytest.raises(ValueError, match="allowed: > 0"):
        make_case("control", 0, 0.5, rate=0.0)


def test_a_plant_whose_samples_are_too_long_for_its_steps_says_where_it_diverged():
    """The chapter's 2SEP plant at 250 Hz: its lag state, at rest when each sample's RK4 steps are
    sized, speeds up past their stability within the first 4 ms sample. One error naming the time
    and the reason, not a math domain error from inside a step."""
    from mjjoint.benchmark.independent.record import record
    case = make_case("twosep", 1, 1.0, rate=250.0)
    with np.errstate(all="ignore"), pytest.raises(FloatingPointError, match="diverged at t = .* too long"):
        record(case.plant, case.excitation, case.sensors, 1)


def test_every_right_or_tolerated_name_is_an_effect_the_tool_can_name():
    """A scored name outside the tool's vocabulary could never count; a periodic structure of the
    motor angle counts as its generic form too (the plant's cogging runs at a real period)."""
    from mjjoint.identify.effects import EFFECTS
    for name in CASES:
        case = make_case(name, 0)
        assert set(case.right) | set(case.tolerated) <= set(EFFECTS), name
    assert "motor_periodic_q" in make_case("cogging", 0).right
