"""Stream simulated traces and the arm's motion to Rerun (rerun-sdk 0.41).

Every signal goes in one ``send_columns`` call on the ``sim_time`` timeline (``joint/q``,
``joint/tau``, ``joint/state/x``, ...). The arm is drawn as ``world/arm/<body>``: body poses
from ``mj_kinematics`` over the qpos trajectory, decimated to ``body_rate`` (the viewer needs
no more than video rate), each carrying static shapes built from the model's geoms. Several
traces (e.g. measured / simulated) each get their own subtree ``<name>/joint/...``.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import mujoco
import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from ..coupling.layout import STATE_NAMES
from ..sim import Trace
from .viewer import display_problem

APP_ID = "mjjoint"
TIMELINE = "sim_time"
BODY_RATE = 50.0  # [Hz] of the logged 3D poses


def trace_signals(trace: Trace) -> dict[str, np.ndarray]:
    """Entity name (below ``joint/``) -> samples of every signal a Trace holds."""
    out = {"u": trace.u, "q": trace.q, "q_over_N": trace.q / trace.gear_ratio, "theta": trace.theta,
           "delta": trace.delta, "qd": trace.qd, "thetad": trace.thetad, "tau": trace.tau,
           "friction": trace.friction, "load_friction": trace.load_friction}
    out.update({f"state/{name}": trace.state(name) for name in STATE_NAMES})
    return out


def body_poses(model: mujoco.MjModel, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World positions (n, nbody, 3) and MuJoCo wxyz quaternions (n, nbody, 4) per qpos row."""
    data = mujoco.MjData(model)
    pos = np.empty((len(qpos), model.nbody, 3))
    quat = np.empty((len(qpos), model.nbody, 4))
    for k, row in enumerate(qpos):
        data.qpos[:] = row
        mujoco.mj_kinematics(model, data)
        pos[k], quat[k] = data.xpos, data.xquat
    return pos, quat


def sim_time(t: np.ndarray) -> rr.TimeColumn:
    """The ``sim_time`` column for times t [s], rounded to whole ns (a float would be truncated)."""
    return rr.TimeColumn(TIMELINE, duration=np.round(np.asarray(t) * 1e9).astype("timedelta64[ns]"))


def _xyzw(wxyz: np.ndarray) -> np.ndarray:
    return np.asarray(wxyz)[..., [1, 2, 3, 0]]


def geom_shape(model: mujoco.MjModel, g: int):
    """A Rerun archetype drawing geom ``g`` in its own frame, or None (planes, meshes, ...)."""
    size = model.geom_size[g]
    color = np.round(255 * model.geom_rgba[g]).astype(np.uint8)[None]
    kind = model.geom_type[g]
    if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        return rr.Ellipsoids3D(half_sizes=[[size[0]] * 3], colors=color, fill_mode="solid")
    if kind == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
        return rr.Ellipsoids3D(half_sizes=[size], colors=color, fill_mode="solid")
    if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:  # MuJoCo: centred, half-length size[1]; Rerun: from 0 to +z
        return rr.Capsules3D(lengths=[2 * size[1]], radii=[size[0]], translations=[[0, 0, -size[1]]], colors=color)
    if kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        return rr.Cylinders3D(lengths=[2 * size[1]], radii=[size[0]], colors=color, fill_mode="solid")
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        return rr.Boxes3D(half_sizes=[size], colors=color, fill_mode="solid")
    return None


def _name(model: mujoco.MjModel, obj: mujoco.mjtObj, i: int, prefix: str) -> str:
    return rr.escape_entity_path_part(mujoco.mj_id2name(model, obj, i) or f"{prefix}{i}")


def log_arm(rec: rr.RecordingStream, root: str, model: mujoco.MjModel, t: np.ndarray, qpos: np.ndarray,
            body_rate: float = BODY_RATE) -> list[str]:
    """Log the arm's bodies under ``{root}world/arm``; returns the moving bodies' entity paths."""
    stride = max(1, int(round(1.0 / (body_rate * np.median(np.diff(t)))))) if len(t) > 1 else 1
    pos, quat = body_poses(model, qpos[::stride])
    time = [sim_time(t[::stride])]
    paths = []
    for b in range(model.nbody):
        path = f"{root}world/arm/{_name(model, mujoco.mjtObj.mjOBJ_BODY, b, 'body')}"
        if b > 0:  # the world body never moves
            rec.send_columns(path, indexes=time,
                             columns=rr.Transform3D.columns(translation=pos[:, b], quaternion=_xyzw(quat[:, b])))
            paths.append(path)
        for g in np.flatnonzero(model.geom_bodyid == b):
            shape = geom_shape(model, g)
            if shape is not None:
                gpath = f"{path}/{_name(model, mujoco.mjtObj.mjOBJ_GEOM, g, 'geom')}"
                rec.log(gpath, rr.Transform3D(translation=model.geom_pos[g], quaternion=_xyzw(model.geom_quat[g])),
                        shape, static=True)
    return paths


def log_series(rec: rr.RecordingStream, path: str, name: str, t: np.ndarray, values: np.ndarray) -> None:
    """One named scalar series at times t, in one column batch."""
    rec.log(path, rr.SeriesLines(names=name), static=True)
    rec.send_columns(path, indexes=[sim_time(t)], columns=rr.Scalars.columns(scalars=np.asarray(values, float)))


def log_signals(rec: rr.RecordingStream, root: str, trace: Trace) -> None:
    """Log every signal of ``trace`` under ``{root}joint/``."""
    for name, values in trace_signals(trace).items():
        log_series(rec, f"{root}joint/{name}", f"{root}{name}", trace.t, values)


def blueprint(roots: list[str], with_arm: bool, sensed: Sequence[str] = ()) -> rrb.Blueprint:
    """Arm in 3D beside stacked plots: angles, deflection, torques, friction and input, states;
    ``sensed`` signals (``/sensed/<name>``) join the plots of their quantity."""
    def view(name: str, signals: tuple[str, ...], also: tuple[str, ...] = ()) -> rrb.TimeSeriesView:
        return rrb.TimeSeriesView(name=name, origin="/",
                                  contents=[f"/{r}joint/{s}" for r in roots for s in signals]
                                  + [f"/sensed/{s}" for s in (*signals, *also) if s in sensed])
    plots = rrb.Vertical(
        view("q/N and theta [rad]", ("q_over_N", "theta"), also=("theta_ref",)),
        view("deflection delta [rad]", ("delta",)),
        view("transmission torque tau [N m]", ("tau",)),
        view("input and friction [N m]", ("u", "friction", "load_friction")),
        view("internal states", ("state/**",)),
    )
    if not with_arm:
        return rrb.Blueprint(plots)
    arm = rrb.Spatial3DView(name="arm", origin="/", contents=[f"/{r}world/**" for r in roots])
    return rrb.Blueprint(rrb.Horizontal(arm, plots, column_shares=[1, 2]))


def log_traces(traces: Mapping[str, Trace] | Trace, *, model: mujoco.MjModel | None = None,
               qpos: Mapping[str, np.ndarray] | np.ndarray | None = None, recording_name: str = APP_ID,
               rrd_path: str | Path | None = None, spawn: bool = False,
               body_rate: float = BODY_RATE, sensed: Mapping[str, np.ndarray] | None = None) -> Path | None:
    """Log ``traces`` (one, or several by name) to an .rrd file and/or a spawned viewer.

    With ``model``, the arm is drawn from ``qpos`` (default: each trace's own ``qpos``).
    ``sensed``: what a recording's sensors made of one trace's signals (name -> samples at its
    times: q_over_N, theta, tau, theta_ref), drawn as ``/sensed/<name>`` beside the true ones.
    Returns the .rrd path, if any.
    """
    named = {"": traces} if isinstance(traces, Trace) else {f"{k}/": v for k, v in traces.items()}
    if qpos is None or isinstance(qpos, Mapping):
        poses = {root: (qpos or {}).get(root.rstrip("/"), tr.qpos) for root, tr in named.items()}
    else:
        if len(named) != 1:
            raise ValueError("qpos must be a mapping by trace name when several traces are logged")
        poses = {root: np.asarray(qpos) for root in named}
    sensed = dict(sensed or {})
    if sensed and (len(named) != 1 or any(np.shape(v) != np.shape(next(iter(named.values())).t)
                                          for v in sensed.values())):
        raise ValueError("sensed signals go with one trace, one value per sample")
    if not spawn and rrd_path is None:
        raise ValueError("log_traces needs rrd_path or spawn=True")
    if model is not None:  # checked before any sink opens, so a bad call leaves no partial file
        for root, trace in named.items():
            shape = None if poses[root] is None else np.shape(poses[root])
            if shape != (len(trace.t), model.nq):
                raise ValueError(f"qpos of trace {root.rstrip('/') or '0'} has shape {shape}, "
                                 f"expected ({len(trace.t)}, {model.nq}) for the model's nq")

    rec = rr.RecordingStream(APP_ID)
    sinks = []
    if spawn and display_problem() is not None:
        raise OSError(f"cannot spawn the Rerun viewer: {display_problem()}; write an .rrd (rrd_path) and "
                      f"open it with 'rerun FILE' on a machine with a display")
    if spawn:
        try:
            rec.spawn(connect=False)
        except RuntimeError as exc:  # no viewer executable: a setup problem, not a bug
            reason = str(exc).strip().splitlines()[0]
            raise OSError(f"cannot spawn the Rerun viewer: {reason} (put the environment's bin folder on "
                          "PATH, or write an .rrd and open it with 'rerun FILE')") from None
        sinks.append(rr.GrpcSink())
    if rrd_path is not None:
        rrd_path = Path(rrd_path)
        sinks.append(rr.FileSink(str(rrd_path)))
    rec.set_sinks(*sinks, default_blueprint=blueprint(list(named), model is not None, list(sensed)))
    rec.send_recording_name(recording_name)
    for root, trace in named.items():
        log_signals(rec, root, trace)
        for name, values in sensed.items():
            log_series(rec, f"sensed/{name}", f"sensed {name}", trace.t, values)
        if model is not None:
            log_arm(rec, root, model, trace.t, np.asarray(poses[root]), body_rate)
    try:
        rec.flush()
    except RuntimeError as exc:  # the spawned viewer went away (e.g. no display)
        raise OSError(f"the Rerun viewer did not take the data: {str(exc).strip().splitlines()[0]}") from None
    finally:
        rec.disconnect()  # finishes the .rrd (footer) before the path is handed back
    return rrd_path
