"""Joint j simulated inside the whole arm, the other joints made to follow their measured motion.

The arm of a ``[[joint]]`` model file is rebuilt for every structure the fit tries, joint j's
physics and bodies taken from it (``arm_for``), and every other joint's motor and link dof is
made HEAVY (an armature of HEAVY kg m^2) and pushed by HEAVY times its measured acceleration
every step, plus a slow correction onto its measured angle (FOLLOW_HZ; an actuator per dof).
A dof that heavy accelerates as pushed whatever the arm does to it (the rest of its dynamics
is a part in HEAVY / its inertia), and MuJoCo's multibody
dynamics carries that motion to joint j exactly: M_JK q''_K with the measured q''_K, the
Coriolis and gravity terms at the simulated configuration, and the rods no encoder sees
(flexible segments of any link) simulated, not assumed at rest. Each window starts the other
joints at their measured angles and velocities (from there they follow the pushes), the rods
as one run along the whole recording leaves them
(``ArmPredictor._hidden``).

This is the route for arms with flexible links, where the load computed once along the
measured motion (``manipulator.load``) cannot know the rods' bending (docs/multijoint.md).
"""
from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np

from ..assets.joint_view import _subtree
from ..assets.serial import add_elastic_joint, add_home_key, new_spec
from ..assets.serial_file import SerialArmFile
from ..coupling.plugin import register_model
from ..identify.stages import for_prediction
from ..identify.structure import Structure
from ..identify.windows import Measured, Predictor, WindowDesign
from ..sim import FULL, joint_indices, state_velocity

# Armature of the prescribed dofs [kg m^2]: 1e6 puts the other joints' response to joint j and
# to their own forces below 1e-8 of their motion on the shipped arms (inertias 1e-5 to 1e-1).
HEAVY = 1e6
# Bandwidth [Hz] of the correction that keeps a prescribed dof on its measured angle: pushed by
# its measured acceleration alone it integrates the derivative's error (~1e-2 rad over 3 s on
# arm3), which a free run of the recording (the noise floor's twin) would carry. On a dof this
# heavy the correction's dynamics are its own (critically damped), whatever the arm does. Kept
# slow: it also feeds the smoothed velocity's error back (parallel-axes test arm, held-out delta
# NRMSE at the true values: 0.015 at 1 Hz, 0.017 at 3 Hz, 0.03 at 10 Hz, 0.014 without).
FOLLOW_HZ = 1.0
_CACHE: dict = {}


def arm_for(arm: SerialArmFile, j: int, structure: Structure, view: Structure) -> tuple[SerialArmFile, float]:
    """(``arm`` with joint j's physics from ``structure`` and its bodies moved as far as the
    structure's single-joint bodies are from ``view``'s, the weight to add at joint j's rod end
    [kg]). ``view`` is joint j's single-joint view where the fit started: its lumped values (tip
    weight, hub inertia) are the chain's plus joint j's own, so a change is joint j's; gravity
    scales the whole arm's. The weight is added to the load at the rod end (``_add_weight``), not
    to the drawn weight: the arm draws it as a steel sphere, which a fit's small steps would
    shrink to nothing, and a joint without one could not lose weight."""
    single, joint = structure.model_params()
    start, _ = view.model_params()
    js = arm.joints[j - 1]
    shared = {f.name for f in dataclasses.fields(js)} & {f.name for f in dataclasses.fields(single)}
    # Rounding in the structure's round trip is no change.
    changed = {n for n in shared - {"segments"} if not math.isclose(getattr(single, n), getattr(start, n), rel_tol=1e-9)}
    moved = {n: max(0.0, getattr(js, n) + (getattr(single, n) - getattr(start, n))) for n in changed - {"tip_mass"}}
    weight = single.tip_mass - start.tip_mass if "tip_mass" in changed else 0.0
    joints = list(arm.joints)
    joints[j - 1] = dataclasses.replace(js, joint=joint, **moved)
    ratio = single.gravity / start.gravity if start.gravity else 1.0
    g = arm.world.gravity * (1.0 if math.isclose(ratio, 1.0, rel_tol=1e-9) else ratio)
    return dataclasses.replace(arm, joints=tuple(joints), world=dataclasses.replace(arm.world, gravity=g)), weight


def _heavy_arm(arm: SerialArmFile, j: int, weight: float = 0.0) -> mujoco.MjModel:
    """The compiled arm, every joint's motor and link dof but joint j's HEAVY, ``weight`` [kg]
    added at joint j's rod end (memoised)."""
    key = (arm, j, weight)
    model = _CACHE.get(key)
    if model is None:
        if len(_CACHE) > 256:
            _CACHE.clear()
        # As build_serial_arm, without its stability check: a fit's unstable candidates are
        # scored (NaN), not rejected (``Predictor.predict``), as the single joint's are.
        spec = new_spec(arm.world)
        parent = spec.worldbody
        for k, js in enumerate(arm.joints, start=1):
            parent = add_elastic_joint(spec, parent, k, js)
        add_home_key(spec)
        w = 2 * math.pi * FOLLOW_HZ
        for k in range(1, len(arm.joints) + 1):
            if k != j:
                for name in (f"motor{k}", f"link{k}"):
                    spec.joint(name).armature = spec.joint(name).armature + HEAVY
                    # HEAVY (ctrl - w^2 q - 2 w q'), ctrl = a + w^2 q_meas + 2 w q'_meas (``ArmPredictor._controls``)
                    act = spec.add_actuator(name=f"follow_{name}", target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
                    act.gaintype, act.biastype = mujoco.mjtGain.mjGAIN_FIXED, mujoco.mjtBias.mjBIAS_AFFINE
                    act.gainprm[0] = HEAVY
                    act.biasprm[:3] = [0.0, -HEAVY * w * w, -2 * HEAVY * w]
                    act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        model = for_prediction(spec.compile())
        if weight:
            _add_weight(model, model.body(f"tip{j}").id, weight)
        register_model(model)
        _CACHE[key] = model
    return model


def _add_weight(model: mujoco.MjModel, tip: int, weight: float) -> None:
    """``weight`` [kg] more at the rod end ``tip``, in place. The view's rod-end weight stands for
    everything the rod end carries, so the whole load there is scaled (masses and inertias, COMs
    kept), which a fit may also lower; a bare rod end gets a point mass."""
    bodies = _subtree(model, tip)
    total = float(model.body_mass[bodies].sum())
    if total > 0:
        scale = max(total + weight, 0.0) / total
        model.body_mass[bodies] *= scale
        model.body_inertia[bodies] *= scale
    else:  # nothing there: the inertial frame of an empty body is arbitrary
        model.body_ipos[tip], model.body_iquat[tip] = 0.0, (1.0, 0.0, 0.0, 0.0)
        model.body_mass[tip] = max(weight, 0.0)
    mujoco.mj_setConst(model, mujoco.MjData(model))  # what MuJoCo derives from masses and inertias


class ArmPredictor(Predictor):
    """``Predictor`` of joint j of ``arm`` with the other joints following ``motion``
    (``manipulator.load.measured_motion``: per joint q, q', q'', theta, theta', theta'')."""

    def __init__(self, measured: Measured, arm: SerialArmFile, j: int, view: Structure, motion: list,
                 design: WindowDesign = WindowDesign(), nthread: int | None = None,
                 fit_signals: tuple[str, ...] | None = None, describe: str = ""):
        super().__init__(measured, design, nthread, fit_signals)
        self.arm, self.j, self.view, self.motion = arm, j, view, motion
        self.describe = describe
        self._prescribed: list | None = None  # ``_others``
        self._hidden_run: tuple | None = None  # ``_hidden``

    def on(self, measured: Measured, fit_signals: tuple[str, ...] | None = None) -> "ArmPredictor":
        """The same arm and other joints' motion for other measurements of joint j (a twin)."""
        return ArmPredictor(measured, self.arm, self.j, self.view, self.motion, self.design, self.nthread,
                            fit_signals, describe=self.describe)

    def _model(self, structure: Structure):
        arm, weight = arm_for(self.arm, self.j, structure, self.view)
        return _heavy_arm(arm, self.j, weight)

    def _joint(self, model):
        return joint_indices(model)[self.j - 1]

    def _others(self, model):
        """(qpos address, dof, (position, velocity, acceleration), follower actuator) of every
        prescribed dof; the same in every arm this predictor builds (only joint j's values change)."""
        if self._prescribed is None:
            out = []
            for k, ji in enumerate(joint_indices(model)):
                if k != self.j - 1:
                    q, qd, qdd, th, thd, thdd = self.motion[k]
                    for qadr, dof, x, name in ((ji.motor_qpos, ji.motor_dof, (q, qd, qdd), f"motor{k + 1}"),
                                               (ji.link_qpos, ji.link_dof, (th, thd, thdd), f"link{k + 1}")):
                        out.append((qadr, dof, x, model.actuator(f"follow_{name}").id))
            self._prescribed = out
        return self._prescribed

    def _measured_others(self, model, i0: np.ndarray, x: np.ndarray) -> np.ndarray:
        """``x`` (state rows at samples ``i0``) with the other joints put on their measured motion."""
        for qadr, dof, (p, v, a), _ in self._others(model):
            x[:, 1 + qadr], x[:, 1 + model.nq + dof] = p[i0], state_velocity(v[i0], a[i0], model.opt.timestep)
        return x

    def _flexible_rows(self, model, ji, i0: np.ndarray) -> np.ndarray:
        return np.zeros(0, int)  # the rods' states come from the history run (``_hidden``)

    def _initial_states(self, model, i0: np.ndarray, ji, skew: float = 0.0) -> np.ndarray:
        x0 = self._measured_others(model, i0, super()._initial_states(model, i0, ji, skew))
        qadr, vadr, hq, hv = self._hidden()
        x0[:, 1 + qadr], x0[:, 1 + model.nq + vadr] = hq[i0], hv[i0]
        return x0

    def _hidden(self) -> tuple[np.ndarray, ...]:
        """(qpos addresses, dofs, positions (n, k), velocities (n, k)) of the coordinates no
        encoder sees (the rods' segments), at every sample: one run along the recording with
        every encoder's joint put back on its measurement each sample.

        The rods' bending is the memory of the whole motion: lightly damped, it outlasts any
        short lead-in (on the shipped arm3, starts bent by a 0.1 s lead-in left the yaw joint's
        windows at deflection NRMSE 0.2-0.5 where this run's states give 0.01-0.05). Run once,
        on the starting structure's arm: with joint j's encoders on the record each sample, its
        fitted physics hardly enter the rods' motion."""
        if self._hidden_run is None:
            start = self._model(self.view)
            sji = self._joint(start)
            seen = {sji.motor_qpos, sji.link_qpos} | {o[0] for o in self._others(start)}
            seen_v = {sji.motor_dof, sji.link_dof} | {o[1] for o in self._others(start)}
            qadr = np.array([a for a in range(start.nq) if a not in seen], int)
            vadr = np.array([a for a in range(start.nv) if a not in seen_v], int)
            m, n = self.m, len(self.m.t)
            hq, hv = np.zeros((n, len(qadr))), np.zeros((n, len(vadr)))
            x = Predictor._initial_states(self, start, np.array([0]), sji)
            x[:, 1 + qadr] = start.qpos0[qadr]
            every, h = np.arange(n), start.opt.timestep
            put = [(1 + sji.motor_qpos, m.q), (1 + start.nq + sji.motor_dof, m.step_velocity("q", h, every)),
                   (1 + sji.link_qpos, m.theta), (1 + start.nq + sji.link_dof, m.step_velocity("theta", h, every))]
            ctrl = self._controls(start, np.array([0]), n, 0.0, sji)[0]
            sub = self._substeps(start)
            d = mujoco.MjData(start)
            for k in range(n):
                for col, meas in put:
                    x[:, col] = meas[k]
                self._measured_others(start, np.array([k]), x)
                hq[k], hv[k] = x[0, 1 + qadr], x[0, 1 + start.nq + vadr]
                if k + 1 < n and len(qadr):  # one row, sample by sample: plain steps beat rollout calls
                    mujoco.mj_setState(start, d, x[0], FULL)
                    for c in ctrl[k * sub:(k + 1) * sub]:
                        d.ctrl[:] = c
                        mujoco.mj_step(start, d)
                    mujoco.mj_getState(start, d, x[0], FULL)
            self.rollouts += 1.0
            self._hidden_run = (qadr, vadr, hq, hv)
        return self._hidden_run

    def _controls(self, model, i0: np.ndarray, n: int, delay: float, ji) -> np.ndarray:
        ctrl = super()._controls(model, i0, n, delay, ji)
        at = i0[:, None] + np.arange(ctrl.shape[1])[None, :] / self._substeps(model)  # each step's start [samples]
        samples = np.arange(len(self.m.t))
        w, h = 2 * math.pi * FOLLOW_HZ, model.opt.timestep
        for _, _, (p, v, a), act in self._others(model):
            # The follower's damping is implicit in the integrator: it acts on the velocity the
            # step ends with, the measured one half a step on.
            ctrl[:, :, act] = np.interp(at, samples, a + w * w * p + 2 * w * (v + 0.5 * h * a))
        return ctrl


def arm_predictor(measured: Measured, structure: Structure, arm_file: SerialArmFile | None, arm: mujoco.MjModel,
                  rec, j: int, design: WindowDesign, fit_signals: tuple[str, ...] | None = None,
                  describe: str = "") -> Predictor:
    """Joint j's predictor in a moving arm: inside the whole arm when its ``[[joint]]`` file is
    given (``ArmPredictor``: rebuilt per structure); for an MJCF, which cannot be rebuilt from a
    single joint's parameters, the view with the load of the others' measured motion
    (``predictor.loaded_predictor``)."""
    from .load import measured_motion
    from .predictor import loaded_predictor
    if arm_file is None:
        return loaded_predictor(measured, structure, arm, rec, j, design, fit_signals, describe)
    grid, motion = measured_motion(rec)
    if len(grid) != len(measured.t):
        raise ValueError(f"joint {j}: the other joints' motion and the recording are on different time grids")
    return ArmPredictor(measured, arm_file, j, structure, motion, design, fit_signals=fit_signals, describe=describe)
