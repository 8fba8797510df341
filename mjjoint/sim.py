"""Open-loop simulation of the elastic joint: inputs in, traces out, no per-step Python.

``Simulator.run`` rolls the model out with ``mujoco.rollout`` (the plugin does the physics in
C-speed callbacks) and derives the traces a recording would hold — q, theta, the transmission
torque tau, friction torques and the internal states — from the recorded MuJoCo states with
the same numba kernels the plugin runs.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from .assets import load_model
from .coupling.kernels import joint_traces, settled_states, settled_transmission
from .coupling.layout import NSTATE, STATE_NAMES, WP, WPL
from .coupling.plugin import PLUGIN_NAME, block_for
from .joint import GROUND, JointParams
from .params import check, substeps

FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS


def held_controls(c: np.ndarray, substeps: int, before=0.0) -> np.ndarray:
    """Per-step controls of per-sample controls ``c`` ((n,) or (n, k)), each held over its sample
    period, the hold centred on the steps: the step a sample starts takes the mean of that
    sample and the one before (``before`` for the first).

    Semi-implicit Euler applies a step's force as an impulse at the position the step starts
    from, so each step stands for the half steps either side of its start. A plain hold puts
    every change of the input half a step early: an error of the order of h in every signal,
    the largest error of a linear joint at its lightly damped gear resonance. Centred, positions
    at the samples are second-order accurate (docs/design.md, "Integration").
    """
    c = np.asarray(c, float)
    out = np.repeat(c, substeps, axis=0)
    out[::substeps] = 0.5 * (c + np.concatenate([np.broadcast_to(before, c[:1].shape), c[:-1]]))
    return out


def step_held(model: mujoco.MjModel, data: mujoco.MjData, actuators, c, before, substeps: int) -> np.ndarray:
    """Step one sample period with controls ``c`` on ``actuators`` held over it (``held_controls``;
    ``before``: the controls of the sample before): the closed loops' per-sample step. Returns
    the velocities the last step started from (``sample_velocity``'s ``w_before``)."""
    rows = held_controls(np.asarray(c, float)[None], substeps, before)
    for k, row in enumerate(rows):
        if k == len(rows) - 1:
            w_before = data.qvel.copy()
        data.ctrl[actuators] = row
        mujoco.mj_step(model, data)
    return w_before


def state_velocity(v, a, h: float):
    """The velocity a semi-implicit Euler state of step h holds at a sample where the motion has
    velocity v and acceleration a: the mean over the step that ended there, v - a h / 2 (a
    state set from measured motion: window starts, prescribed joints)."""
    return v - 0.5 * h * a


def sample_velocity(w: np.ndarray, w_before: np.ndarray) -> np.ndarray:
    """The velocity at a sample instant from a semi-implicit Euler state's ``w``, the mean over
    the step that ended there, and ``w_before``, the one of the step before: half a step on,
    w + (w - w_before) / 2 (second order). Where no step came before (NaN): w."""
    return np.where(np.isnan(w_before), w, 1.5 * w - 0.5 * w_before)


@dataclass(frozen=True)
class JointIndex:
    """Where one plugin instance's joint lives in a model and in its full-physics state."""

    instance: int
    params: JointParams
    block: np.ndarray
    motor_qpos: int
    motor_dof: int
    link_qpos: int
    link_dof: int
    state_start: int      # first plugin-state entry of this instance in the FULLPHYSICS vector
    gear_ratio: float
    actuator: int         # actuator driving the motor joint (-1: none)
    k_m: float

    def require_actuator(self) -> None:
        """Raise ``ValueError`` saying why nothing drives this joint's motor, if nothing does."""
        if self.actuator >= 0:
            return
        motor = self.params.motor_joint
        if motor == GROUND:
            raise ValueError(f"joint instance {self.instance}'s motor_joint is {GROUND!r} (a fixed input): there is "
                             "no motor to drive; name the rotor's joint")
        raise ValueError(f"joint instance {self.instance} has no actuator on its motor joint {motor!r}")

    def steps(self, model: mujoco.MjModel) -> tuple[float, float, float]:
        """(h, h/J of the motor dof, h/J of the link dof; 0 for a side fixed to the world), as the
        plugin's compute reads them: the step arguments of the ``coupling.kernels``."""
        h, invw = model.opt.timestep, model.dof_invweight0
        return (float(h), float(h * invw[self.motor_dof]) if self.motor_dof >= 0 else 0.0,
                float(h * invw[self.link_dof]) if self.link_dof >= 0 else 0.0)

    def plugin_states(self, full: np.ndarray) -> np.ndarray:
        """This instance's internal states, (..., NSTATE), in full-physics state rows (..., nstate): a view."""
        return full[..., self.state_start:self.state_start + NSTATE]

    def motion(self, model: mujoco.MjModel, full: np.ndarray) -> tuple[np.ndarray, ...]:
        """(q, qd, theta, thetad), each (n,), of full-physics state rows ``full`` (n, nstate); a
        side fixed to the world reads 0."""
        nq, zero = model.nq, np.zeros(len(full))
        return (full[:, 1 + self.motor_qpos] if self.motor_qpos >= 0 else zero,
                full[:, 1 + nq + self.motor_dof] if self.motor_dof >= 0 else zero,
                full[:, 1 + self.link_qpos] if self.link_qpos >= 0 else zero,
                full[:, 1 + nq + self.link_dof] if self.link_dof >= 0 else zero)

    def settled(self, model: mujoco.MjModel, full: np.ndarray):
        """Internal states at each row's own instant, and ``motion``, of full-physics state rows
        ``full`` (n, nstate)."""
        motion = self.motion(model, full)
        st = settled_states(self.block, np.ascontiguousarray(self.plugin_states(full)), full[:, 0],
                            *motion, *self.steps(model))
        return st, motion

    def transmission(self, model: mujoco.MjModel, full: np.ndarray) -> np.ndarray:
        """The transmission torque at each of full-physics state rows ``full`` (n, nstate), from
        the internal states at its own instant (``settled``)."""
        return settled_transmission(self.block, self.plugin_states(full), full[:, 0], *self.motion(model, full),
                                    *self.steps(model))


def joint_indices(model: mujoco.MjModel) -> list[JointIndex]:
    """One ``JointIndex`` per joint the ``mjjoint.joint`` instances drive, in instance order."""
    from .coupling.layout import LD, LQ, MD, MQ
    plugin_start = mujoco.mj_stateSize(model, FULL) - model.npluginstate
    out = []
    for i in range(model.nplugin):
        for j, (params, blk) in enumerate(block_for(model._address, i)):
            motor = np.flatnonzero(model.jnt_qposadr == int(blk[MQ])) if blk[MQ] >= 0 else []
            acts = [a for a in range(model.nu) if len(motor) and model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
                    and model.actuator_trnid[a, 0] == motor[0]]
            act = acts[0] if acts else -1
            out.append(JointIndex(
                instance=i, params=params, block=blk, motor_qpos=int(blk[MQ]), motor_dof=int(blk[MD]),
                link_qpos=int(blk[LQ]), link_dof=int(blk[LD]),
                state_start=plugin_start + int(model.plugin_stateadr[i]) + NSTATE * j, gear_ratio=params.gear_ratio,
                actuator=act, k_m=float(model.actuator_gear[act, 0]) if act >= 0 else 1.0))
    if not out:
        raise ValueError(f"the model has no {PLUGIN_NAME} plugin instance")
    return out


@dataclass
class Trace:
    """Sampled traces of one joint (SI units; q motor side before the gear, theta link side)."""

    t: np.ndarray
    u: np.ndarray          # applied motor torque [N m] (the command clipped to the actuator range)
    q: np.ndarray
    theta: np.ndarray
    qd: np.ndarray         # motor and link velocities at the sample instants (``sample_velocity``)
    thetad: np.ndarray
    tau: np.ndarray        # transmission torque T [N m, link side]
    friction: np.ndarray   # motor friction torque [N m]
    load_friction: np.ndarray  # torque of the link-site terms against the link (bearing friction) [N m]
    states: np.ndarray     # (n, NSTATE) internal plugin states
    gear_ratio: float
    qpos: np.ndarray = field(repr=False, default=None)  # full generalised positions (n, nq)

    @property
    def delta(self) -> np.ndarray:
        return self.q / self.gear_ratio - self.theta

    def state(self, name: str) -> np.ndarray:
        return self.states[:, STATE_NAMES.index(name)]

    def columns(self) -> dict[str, np.ndarray]:
        """The recording columns ``t,u,q,theta,tau``."""
        return {"t": self.t, "u": self.u, "q": self.q, "theta": self.theta, "tau": self.tau}

    def to_csv(self, path: str | Path) -> Path:
        from .recordings import Recording, write_recording
        path = Path(path)
        write_recording(path, Recording(t=self.t, u=self.u, q=self.q, theta=self.theta, tau=self.tau,
                                        gear_ratio=self.gear_ratio, meta={}))
        return path


class Simulator:
    """A compiled model plus what is needed to roll it out and read its traces.

    >>> sim = Simulator()                       # the shipped arm, default physics
    >>> trace = sim.run(u=np.full(2000, 0.3))   # 2 s of 0.3 N m at 1 kHz
    """

    def __init__(self, model: mujoco.MjModel | None = None, *, sample_rate: float = 1000.0, **build):
        self.model = model if model is not None else load_model(None, **build)
        self.data = mujoco.MjData(self.model)
        self.joints = joint_indices(self.model)
        self.sample_rate = check("sample_rate", sample_rate, 0.0, lo_open=True)
        self.substeps = substeps(self.sample_rate, self.model.opt.timestep)

    def initial_state(self, key: str | int | None = "home") -> np.ndarray:
        """Full-physics state after ``mj_resetData`` (and the keyframe, if the model has it)."""
        d = self.data
        mujoco.mj_resetData(self.model, d)
        if key is not None and self.model.nkey:
            kid = key if isinstance(key, int) else mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_KEY, key)
            if kid >= 0:
                mujoco.mj_resetDataKeyframe(self.model, d, kid)
        mujoco.mj_forward(self.model, d)
        out = np.empty(mujoco.mj_stateSize(self.model, FULL))
        mujoco.mj_getState(self.model, d, out, FULL)
        return out

    def controls(self, u: np.ndarray, before: np.ndarray | float = 0.0) -> np.ndarray:
        """Per-step actuator controls for motor torques sampled at the rate, each held over its
        sample period (``held_controls``; ``before``: the torques held before the first sample).

        ``u`` is (n,) for one joint or (n, njoint); each joint's torque becomes its motor
        actuator's control u / k_m (a current when the actuator gear is k_m).
        """
        u = np.asarray(u, dtype=float)
        u2 = u[:, None] if u.ndim == 1 else u
        if u2.shape[1] != len(self.joints):
            raise ValueError(f"u has {u2.shape[1]} columns but the model has {len(self.joints)} joints")
        if not np.all(np.isfinite(u2)):
            raise ValueError("u contains NaN or inf")
        ctrl = np.zeros((u2.shape[0] * self.substeps, self.model.nu))
        first = self.applied(np.broadcast_to(before, u2[:1].shape))[0]
        for j, ji in enumerate(self.joints):
            ji.require_actuator()
            ctrl[:, ji.actuator] = held_controls(self.applied(u2)[:, j] / ji.k_m, self.substeps, first[j] / ji.k_m)
        return ctrl

    def applied(self, u: np.ndarray) -> np.ndarray:
        """The motor torques MuJoCo will apply: u clipped to each actuator's control range."""
        u2 = np.array(u, dtype=float, ndmin=2).reshape(len(u), -1)
        for j, ji in enumerate(self.joints):
            if ji.actuator >= 0 and self.model.actuator_ctrllimited[ji.actuator]:
                lo, hi = self.model.actuator_ctrlrange[ji.actuator] * ji.k_m
                u2[:, j] = np.clip(u2[:, j], lo, hi)
        return u2

    def run(self, u: np.ndarray, initial_state: np.ndarray | None = None) -> list[Trace] | Trace:
        """Roll out motor torques ``u`` sampled at ``sample_rate``; one Trace per joint."""
        states = self.rollout_states(u, initial_state)
        traces = self.traces(states, u)
        return traces[0] if len(traces) == 1 else traces

    def rollout_states(self, u: np.ndarray, initial_state: np.ndarray | None = None,
                       before: np.ndarray | float = 0.0) -> np.ndarray:
        """Full-physics states at the sample instants, (n, nstate); row 0 is the initial state.
        ``before``: the motor torques held before the first sample (a run continued)."""
        x0 = self.initial_state() if initial_state is None else np.asarray(initial_state, float)
        ctrl = self.controls(u, before)
        state, _ = mj_rollout.rollout(self.model, self.data, x0[None], ctrl[None])
        check_diverged(state[0], x0[0])
        picked = state[0, self.substeps - 1::self.substeps][:-1]
        return np.vstack([x0[None], picked])

    def traces(self, states: np.ndarray, u: np.ndarray) -> list[Trace]:
        u2 = self.applied(u)
        qpos = states[:, 1:1 + self.model.nq]
        out = []
        for j, ji in enumerate(self.joints):
            st, (q, qd, theta, thd) = ji.settled(self.model, states)
            tau, fric, load = joint_traces(ji.block, st, q, qd, theta, thd, *ji.steps(self.model))
            out.append(Trace(t=states[:, 0].copy(), u=u2[:, j].copy(), q=q.copy(), theta=theta.copy(),
                             qd=sample_velocity(qd, st[:, WP]), thetad=sample_velocity(thd, st[:, WPL]),
                             tau=tau, friction=fric, load_friction=load, states=st, gear_ratio=ji.gear_ratio,
                             qpos=qpos.copy()))
        return out


def check_diverged(states: np.ndarray, t0: float) -> None:
    """Raise if MuJoCo hit an instability: it then resets the data, so time jumps back."""
    t = np.concatenate([[t0], states[:, 0]])
    bad = np.flatnonzero(np.diff(t) <= 0)  # index of the last good time before each reset
    if bad.size or not np.isfinite(states).all():
        at = t[bad[0]] if bad.size else t[1 + np.flatnonzero(~np.isfinite(states).all(axis=1))[0]]
        raise ValueError(f"simulation diverged near t = {at:.4f} s: the input or a parameter makes the "
                         "joint unstable at this timestep (reduce the input or the timestep)")


def simulate(u: np.ndarray, model: mujoco.MjModel | None = None, sample_rate: float = 1000.0,
             **build) -> Trace | list[Trace]:
    """One-call simulation: ``simulate(u)`` -> Trace of the default arm driven by torques ``u``.

    Args:
        u: motor torques [N m], shape (n,) for one joint or (n, njoint), each held over its
            sample period; row k acts over [k, k+1) / sample_rate.
        model: a compiled model with ``mjjoint.joint`` instances; default: the shipped arm,
            built with ``build`` (``ArmSpec`` and ``JointParams`` as ``arm=``, ``joint=``).
        sample_rate: samples per second [Hz]; 1/timestep must be a whole multiple of it.
        **build: passed to ``load_model`` when ``model`` is None.

    Returns:
        A ``Trace`` (arrays of shape (n,): t, u, q, theta, tau, friction, ...; states (n, 13)),
        or one per joint for a multi-joint model.

    Raises:
        ValueError: a bad parameter or rate, ``u`` of the wrong shape or not finite, or a run
            that diverged.
    """
    return Simulator(model, sample_rate=sample_rate, **build).run(u)
