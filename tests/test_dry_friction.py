"""Dry friction taken at the velocity the step ends with: it sticks exactly, dissipates F_c
times the path, and is stable at any F_c / J. The output bearing (``physics.load``) always; the
motor's static map with the exact sign (``StaticFriction(v_eps=0)``) as an option.

A Coulomb pendulum is the property test: released from A1, it swings to the far side and stops
at A2 where the gravity potential lost equals the bearing's work, m g l (cos A2 - cos A1) =
F_c (|A1| + |A2|), whatever the inertia; it comes to rest for good where m g l |sin theta| <= F_c.
A sign regularised as tanh(w / v_eps) never holds: it creeps towards the bottom.
"""
from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mjjoint.assets.builder import ArmSpec
from mjjoint.joint import JointParams
from mjjoint.experiments.convergence import free_rotor
from mjjoint.physics.load import LoadFriction
from mjjoint.physics.stribeck import StaticFriction
from mjjoint.physics.transmission import Transmission
from mjjoint.sim import FULL, Simulator

FC = 0.2          # [N m]
START = 0.5       # [rad] released at rest
RATE = 1000.0


def pendulum(h: float, segments: int = 0, v_eps: float = 0.0, seconds: float = 16.0, fc: float = FC):
    """The shipped arm, gravity on, no motor friction, a stiff linear gear, only the bearing's
    friction on the link; released at rest from START. Returns (trace, m g l)."""
    joint = JointParams(friction=None, load_friction=LoadFriction(fc=fc, viscous=0.0, v_eps=v_eps),
                        transmission=Transmission(hysteresis=None, k3=0.0))
    sim = Simulator(arm=ArmSpec(segments=segments, timestep=h), joint=joint, sample_rate=RATE)
    m, d, ji = sim.model, sim.data, sim.joints[0]
    mujoco.mj_resetData(m, d)
    d.qpos[ji.link_qpos] = np.pi / 2
    mujoco.mj_forward(m, d)
    mgl = float(d.qfrc_bias[ji.link_dof])  # gravity torque of the horizontal link, at rest
    mujoco.mj_resetData(m, d)
    d.qpos[ji.link_qpos] = START
    d.qpos[ji.motor_qpos] = ji.gear_ratio * START
    mujoco.mj_forward(m, d)
    x0 = np.empty(mujoco.mj_stateSize(m, FULL))
    mujoco.mj_getState(m, d, x0, FULL)
    return sim.run(np.zeros(int(seconds * RATE)), x0), abs(mgl)


def extremes(theta: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The link angle at the end of each swing: where its velocity changes sign or comes to
    rest, the last such point on each side (the gear winds up at the release, a stop and go)."""
    turns = theta[np.flatnonzero((np.sign(w[1:]) != np.sign(w[:-1])) & (w[:-1] != 0)) + 1]
    return np.array([a for a, b in zip(turns, [*turns[1:], -turns[-1]]) if np.sign(a) != np.sign(b)])


@pytest.fixture(scope="module")
def rigid():
    return pendulum(5e-4)


def test_each_swing_loses_the_bearings_work(rigid):
    trace, mgl = rigid
    a = extremes(trace.theta, trace.thetad)
    # swings that end clear of the band: a stop inside it leaves the gear ringing, whose damping
    # then takes the rest
    swings = [(a1, a2) for a1, a2 in zip(a[:-1], a[1:]) if mgl * abs(np.sin(a2)) > 2 * FC]
    assert len(swings) >= 3
    for a1, a2 in swings:
        lost = mgl * (np.cos(a2) - np.cos(a1))
        assert lost == pytest.approx(FC * (abs(a1) + abs(a2)), rel=0.02), (a1, a2)


def test_the_link_comes_to_rest_inside_the_band_and_stays(rigid):
    trace, mgl = rigid
    last = slice(-int(2 * RATE), None)
    assert np.all(trace.thetad[last] == pytest.approx(0.0, abs=1e-12))
    assert np.ptp(trace.theta[last]) < 1e-12
    assert mgl * abs(np.sin(trace.theta[-1])) <= FC
    assert abs(trace.theta[-1]) > 0.1 * FC / mgl  # held off the bottom, where it stopped


def test_the_rest_angle_is_the_converged_one(rigid):
    trace, mgl = rigid
    fine, _ = pendulum(5e-5)
    assert trace.theta[-1] == pytest.approx(fine.theta[-1], abs=0.01 * FC / mgl)


def test_a_flexible_link_sticks_where_the_fine_step_does():
    """On the 4-segment rod the hub's other torques (the rod's) change within a step; they are
    extrapolated from the last two steps. The rest angle still agrees with a 10x finer step."""
    coarse, mgl = pendulum(5e-4, segments=4)
    fine, _ = pendulum(5e-5, segments=4)
    assert coarse.theta[-1] == pytest.approx(fine.theta[-1], abs=0.02 * FC / mgl)
    assert np.abs(coarse.thetad[-int(RATE):]).max() < 1e-3


def test_a_regularised_sign_creeps_to_the_bottom():
    """The contrast: tanh(w / 0.15 rad/s) is a damper near rest, so the link never stops where
    the exact bearing holds it."""
    trace, mgl = pendulum(5e-4, v_eps=0.15)
    exact, _ = pendulum(5e-4)
    assert abs(trace.theta[-1]) < 0.5 * abs(exact.theta[-1])
    assert np.abs(trace.thetad[-int(RATE):]).max() > 1e-3


def test_any_friction_level_is_stable_on_a_light_hub():
    """A bearing 250x the shipped one on the flexible rod's 2e-3 kg m^2 hub: an explicit
    regularised sign would need v_eps > 30 rad/s at 0.5 ms; held at the step's end it holds the
    link against the whole swing."""
    trace, mgl = pendulum(5e-4, segments=4, seconds=2.0, fc=50.0)
    assert np.all(np.isfinite(trace.theta))
    assert np.abs(trace.theta - START).max() < 1e-3


# ---- the motor's static map with the exact sign -----------------------------------------------
def rotor_under(amplitude: float, v_eps: float, h: float = 5e-4, fc: float = 0.08, fs: float = 0.12):
    """The shipped rotor, output cut free, under a 1 Hz sine of ``amplitude`` times Fs."""
    t = np.arange(int(2 * RATE)) / RATE
    joint = JointParams(friction=StaticFriction(fc=fc, fs=fs, v_eps=v_eps))
    return free_rotor(h, joint, amplitude * fs * np.sin(2 * np.pi * t))


def lag_bound(trace, h: float = 5e-4) -> float:
    """The largest velocity a held rotor takes in a step: the rotor's other torques (the drive)
    are known one step late (``kernels.known_other``), so each step's change of the held input,
    up to half a sample's change (``sim.held_controls``), moves it by h/J times that change; the
    sample's velocity extrapolates two such steps (``sim.sample_velocity``)."""
    return 2.0 * h / ArmSpec().motor_inertia * 0.5 * np.abs(np.diff(trace.u)).max()


def test_a_rotor_below_break_away_holds_to_within_the_drives_one_step_lag():
    """0.8 Fs is above the Coulomb level but below break-away: the exact map holds the rotor
    but for the one-step lag of the drive it sees, a creep that vanishes at first order with
    the step; the regularised one (tanh over 1 rad/s) lets it spin up."""
    held = rotor_under(0.8, 0.0)
    assert np.abs(held.qd).max() <= lag_bound(held) * (1 + 1e-9)
    finer = rotor_under(0.8, 0.0, h=2.5e-4)
    assert np.ptp(finer.q) < 0.6 * np.ptp(held.q) and np.ptp(held.q) < 2e-3  # against 10 rad and more sliding
    # the friction takes the whole drive, as the last step showed it, to the same lag (measured 0.3 %)
    assert np.abs(held.friction[1:] - held.u[:-1]).max() <= 0.01 * np.abs(held.u).max()
    assert np.abs(rotor_under(0.8, 1.0).qd).max() > 1.0


def test_a_sliding_rotor_converges_at_first_order():
    fine = rotor_under(1.25, 0.0, h=5e-6)
    err = [np.sqrt(np.mean((rotor_under(1.25, 0.0, h=h).qd - fine.qd) ** 2)) / np.sqrt(np.mean(fine.qd ** 2))
           for h in (5e-4, 2.5e-4)]
    assert err[0] < 0.02 and err[1] < 0.7 * err[0], err


def test_exact_map_is_stable_at_any_friction_level():
    """Fc 25x the shipped rotor's: a regularised sign would need v_eps > 10 rad/s at 0.5 ms
    (the drive stays inside the amplifier's 5 N m)."""
    held = rotor_under(0.9, 0.0, fc=2.0, fs=3.0)
    assert np.all(np.isfinite(held.qd)) and np.abs(held.qd).max() <= lag_bound(held) * (1 + 1e-9)
    slides = rotor_under(1.5, 0.0, fc=2.0, fs=3.0)
    assert np.all(np.isfinite(slides.qd)) and np.abs(slides.qd).max() > 1.0
