"""Energy bookkeeping of the full MuJoCo model: conservation without losses, decay with them.

Energy = MuJoCo's potential (gravity, rod-segment springs) + kinetic energy, read with the
energy flag on, PLUS what the plugin's forces store, which MuJoCo cannot see:
  * the transmission spring, V(delta_e) = k1 d^2/2 + k2 |d|^3/3 + k3 d^4/4 (the integral of
    Eq. 16's polynomial), weighted by mu when Bouc-Wen hysteresis is on;
  * the Bouc-Wen plastic state, (1 - mu) V(x) / A. Eq. 17 gives
    Gamma_p(x) delta' - V(x)'/A = Gamma_p(x)(beta|delta'| + gamma sgn(x) delta')|x|^n / A >= 0
    for |gamma| <= beta (which BoucWen enforces): with this storage the hysteretic spring is
    passive at every instant, not only over closed cycles, so the total may be required to
    never increase. (With the elastic part alone, the check would only hold cycle-wise.)
  * the 2SEP pre-sliding state, z1^2 / (2 K Fc): Eq. 12 after a reversal reads
    z1' = K (Fc w - |w| z1) (a Dahl element), so F w - (z1^2/2KFc)' = |w| z1^2 / Fc >= 0.
Samples are 1 ms apart; the model's own integrator (implicitfast) is used throughout.
"""
from __future__ import annotations

import functools

import mujoco
import numpy as np
import pytest

import reference as ref
from mjjoint.assets import ArmSpec, build_arm, load_model
from mjjoint.joint import JointParams
from mjjoint.physics.load import LoadFriction
from mjjoint.physics.stribeck import StaticFriction
from mjjoint.physics.transmission import Transmission
from mjjoint.physics.twosep import TwoSEP
from mjjoint.sim import FULL, Simulator

DURATION = 2.0
RATE = 1000.0
LOSSLESS = dict(friction=None, load_friction=None, transmission=Transmission(damping=0.0, hysteresis=None))


def arm_simulator(dt: float, segment_damping: float = 0.0, **joint) -> tuple[Simulator, JointParams]:
    params = JointParams(**{**LOSSLESS, **joint})
    arm = ArmSpec(segment_damping=segment_damping, timestep=dt)
    sim = Simulator(load_model(build_arm(arm, params)), sample_rate=RATE)
    sim.model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    return sim, params


@functools.lru_cache(maxsize=None)
def balanced_pose(theta0: float) -> tuple[float, ...]:
    """qpos with the link swung to theta0 and held there by the transmission and the bent rod.

    Starting from static balance keeps the rod's and hub's fast modes (up to ~3000 rad/s,
    where semi-implicit Euler's energy error is largest) nearly unexcited; the motion is put
    in through velocities instead. Fixed point of: flex_i = -G_i / k_i, T(delta) = G_link.
    """
    sim, params = arm_simulator(5e-4)
    m, d, ji = sim.model, sim.data, sim.joints[0]
    t = params.transmission
    flex = [j for j in range(m.njnt) if j not in (m.dof_jntid[ji.motor_dof], m.dof_jntid[ji.link_dof])]
    delta = 0.0
    for _ in range(30):
        d.qpos[ji.link_qpos] = theta0
        d.qpos[ji.motor_qpos] = ji.gear_ratio * (theta0 + delta)
        mujoco.mj_forward(m, d)
        gravity = d.qfrc_bias.copy()  # zero velocity: gravity only
        for j in flex:
            d.qpos[m.jnt_qposadr[j]] = -gravity[m.jnt_dofadr[j]] / m.jnt_stiffness[j]
        for _ in range(20):  # Newton on T(delta) = G_link
            residual = ref.restoring_torque(delta, 0.0, 1.0, t.k1, t.k2, t.k3) - gravity[ji.link_dof]
            delta -= residual / (t.k1 + 2 * t.k2 * abs(delta) + 3 * t.k3 * delta ** 2)
    d.qpos[ji.motor_qpos] = ji.gear_ratio * (theta0 + delta)
    return tuple(d.qpos)


def start_state(sim: Simulator, *, link_rate: float = 0.0, deflection_rate: float = 0.0,
                flex_rate: float = 0.0) -> np.ndarray:
    """Full-physics state: balanced pose at theta0 = 0.5 rad, rigid swing, transmission and rod motion."""
    m, d, ji = sim.model, sim.data, sim.joints[0]
    mujoco.mj_resetData(m, d)
    d.qpos[:] = balanced_pose(0.5)
    d.qvel[:] = flex_rate
    d.qvel[ji.link_dof] = link_rate
    d.qvel[ji.motor_dof] = ji.gear_ratio * (link_rate + deflection_rate)
    mujoco.mj_forward(m, d)
    out = np.empty(mujoco.mj_stateSize(m, FULL))
    mujoco.mj_getState(m, d, out, FULL)
    return out


def stored_energy(sim: Simulator, params: JointParams, states: np.ndarray) -> np.ndarray:
    """Mechanical energy plus what the plugin's spring, Bouc-Wen and 2SEP z1 states hold."""
    m, ji = sim.model, sim.joints[0]
    d = mujoco.MjData(m)
    t = params.transmission
    hyst = t.hysteresis
    presliding = params.friction if isinstance(params.friction, TwoSEP) else None
    out = np.empty(len(states))
    for i, s in enumerate(states):
        mujoco.mj_setState(m, d, s, FULL)
        mujoco.mj_forward(m, d)  # brings the plugin states to the state's time
        plugin = d.plugin_state[m.plugin_stateadr[ji.instance]:]
        delta = ref.engaged(d.qpos[ji.motor_qpos] / ji.gear_ratio - d.qpos[ji.link_qpos], t.backlash)
        e = d.energy[0] + d.energy[1] + t.mu * ref.spring_potential(delta, t.k1, t.k2, t.k3)
        if hyst is not None:
            e += (1 - hyst.mu) * ref.spring_potential(plugin[5], t.k1, t.k2, t.k3) / hyst.a
        if presliding is not None:
            e += plugin[0] ** 2 / (2 * presliding.k * presliding.fc)
        out[i] = e
    return out


def rest_energy(sim: Simulator) -> float:
    d = mujoco.MjData(sim.model)
    mujoco.mj_forward(sim.model, d)
    return float(d.energy[0] + d.energy[1])


def free_run(sim: Simulator, params: JointParams, x0: np.ndarray) -> np.ndarray:
    """Energy at 1 kHz over DURATION with no input, checking MuJoCo raised no instability."""
    states = sim.rollout_states(np.zeros(int(DURATION * RATE)), x0)
    assert np.all(np.isfinite(states))
    assert np.ptp(states[:, 0]) == pytest.approx(DURATION - 1 / RATE)  # no reset mid-run
    return stored_energy(sim, params, states)


# ---- without losses: conserved to the integrator's accuracy --------------------------------
def test_lossless_energy_is_conserved_and_converges():
    """No friction, damping or hysteresis, no input: the total stays put; halving h halves the error.

    The start stores energy in the tilted link (gravity), the deflecting transmission (a 1.2
    rad/s deflection rate gives ~2 mrad, so k1, k2 and k3 all matter) and the moving rotor.
    implicitfast without damping is semi-implicit Euler, whose energy error is first order
    and oscillatory: the largest deviation must halve with h, and the secular drift (mean
    of the last 0.2 s against the first 0.2 s) stay below 1e-3 of the energy above rest.
    """
    err, drift = [], []
    for dt in (2e-4, 1e-4, 5e-5):
        sim, params = arm_simulator(dt, transmission=Transmission(damping=0.0, hysteresis=None, k2=2e6))
        e = free_run(sim, params, start_state(sim, deflection_rate=1.2))
        scale = e[0] - rest_energy(sim)
        window = int(0.2 * RATE)
        err.append(np.max(np.abs(e - e[0])) / scale)
        drift.append(abs(e[-window:].mean() - e[:window].mean()) / scale)
    assert max(drift) < 1e-3, drift
    assert err[1] < 0.6 * err[0] and err[2] < 0.6 * err[1], err  # first-order convergence
    assert err[2] < 1e-3, err


def test_linear_spring_matches_a_native_mujoco_spring():
    """The plugin's k1 spring is exactly MuJoCo's own: a fixed tendon q/N - theta of stiffness k1.

    Same model, plugin instance swapped for the tendon: the two trajectories agree to
    round-off, so what energy error remains is the integrator's, not the coupling's.
    """
    arm = ArmSpec(segment_damping=0.0, gravity=False)
    tr = Transmission(k1=1e4, k2=0.0, k3=0.0, damping=0.0, hysteresis=None)
    params = JointParams(**{**LOSSLESS, "transmission": tr})
    plugin = load_model(build_arm(arm, params))
    spec = build_arm(arm, params)
    spec.delete(spec.plugins[0])
    tendon = spec.add_tendon(name="transmission")
    tendon.stiffness[0] = tr.k1
    tendon.wrap_joint("motor", 1.0 / tr.gear_ratio)
    tendon.wrap_joint("link", -1.0)
    native = spec.compile()
    qpos = []
    for m in (plugin, native):
        d = mujoco.MjData(m)
        d.qpos[0] = tr.gear_ratio * 0.002  # 2 mrad of deflection, link at rest
        for _ in range(2000):
            mujoco.mj_step(m, d)
        qpos.append(d.qpos.copy())
    assert np.abs(qpos[0][1]) > 1e-4  # the link did move
    assert np.allclose(qpos[0], qpos[1], rtol=1e-9, atol=1e-12)


# ---- with losses: never gains energy, and loses it overall ---------------------------------
LOSSES = {
    "segment_damping": dict(segment_damping=0.5),
    "transmission_damping": dict(transmission=Transmission(hysteresis=None)),
    "load_friction": dict(load_friction=LoadFriction()),
    "static_friction": dict(friction=StaticFriction()),
    "2sep_presliding_only": dict(friction=TwoSEP(b=0.0)),
    "2sep": dict(friction=TwoSEP()),
    "hysteresis": dict(transmission=Transmission(damping=0.0)),
    "hysteresis_backlash": dict(transmission=Transmission(damping=0.0, backlash=1e-3)),
    "all_but_2sep_lag": dict(segment_damping=0.5, friction=TwoSEP(b=0.0), load_friction=LoadFriction(),
                             transmission=Transmission(backlash=1e-3)),
    "all": dict(segment_damping=0.5, friction=TwoSEP(), load_friction=LoadFriction(), transmission=Transmission()),
}
MOTION = dict(link_rate=3.0, deflection_rate=0.3, flex_rate=0.3)


def net_change(e: np.ndarray) -> float:
    """Energy of the last 0.2 s (mean, past the O(h) oscillation) minus the initial energy."""
    return float(e[-int(0.2 * RATE):].mean() - e[0])


@functools.lru_cache(maxsize=None)
def integrator_noise(dt: float, backlash: float) -> tuple[float, float]:
    """(largest rise between samples, |net change|) of the lossless run from the same start.

    Backlash is kept: engaging the stiff spring is an impact, where the integrator's energy
    error is larger than in smooth motion.
    """
    sim, params = arm_simulator(dt, transmission=Transmission(damping=0.0, hysteresis=None, backlash=backlash))
    e = free_run(sim, params, start_state(sim, **MOTION))
    return float(np.max(np.diff(e))), abs(net_change(e))


@pytest.mark.parametrize("name", list(LOSSES))
def test_losses_never_add_energy(name):
    """Each loss alone and all together: no rise beyond integrator noise, and a net decrease.

    The tolerance between samples is twice the largest rise the lossless run (same start,
    timestep and backlash) shows: semi-implicit Euler's own O(h) fluctuation, which a lossy
    run, with the same fast modes less excited, does not exceed by much. The net loss over
    2 s must exceed twice the lossless run's net drift. Checked at the shipped 0.5 ms and at
    half of it; with backlash at half and a quarter, since at 0.5 ms the impacts' integrator
    error (9 mJ net over 2 s) rivals the vibration energy (~20 mJ) there is to dissipate.
    """
    kw = dict(LOSSES[name])
    backlash = "transmission" in kw and kw["transmission"].backlash > 0
    for dt in (2.5e-4, 1.25e-4) if backlash else (5e-4, 2.5e-4):
        sim, params = arm_simulator(dt, **kw)
        rise, drift = integrator_noise(dt, params.transmission.backlash)
        e = free_run(sim, params, start_state(sim, **MOTION))
        assert np.max(np.diff(e)) <= 2 * rise, (dt, np.max(np.diff(e)), rise)
        assert net_change(e) < -2 * drift, (dt, net_change(e), drift)
