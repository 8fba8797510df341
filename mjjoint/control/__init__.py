"""dm_control environments of the elastic arms, in the conventions of ``dm_control.suite``::

    from mjjoint import control
    env = control.load("hold", model="arm2_planar.xml", task_kwargs={"random": 0})
    time_step = env.reset()
    while not time_step.last():
        time_step = env.step(controller(time_step.observation))   # motor currents [A]

The joint physics is the MJCF's ``mjjoint.joint`` plugin, as everywhere else in mjjoint. See
docs/control.md for the tasks, observations and rewards.
"""
from __future__ import annotations

from pathlib import Path

import mujoco
from dm_control.rl import control

from .physics import JointPhysics
from .rigid import build_rigid_arm
from .sensors import JointSensors, SensorReadout
from .tasks import Damp, Hold, JointTask, Track

TASKS = {"track": Track, "hold": Hold, "damp": Damp}
CONTROL_TIMESTEP = 1e-3  # [s] 1 kHz, the rate of the lab's recordings (Sec. 4)


def load(task_name: str, model: str | Path | mujoco.MjSpec | mujoco.MjModel = "scene.xml", *,
         task_kwargs: dict | None = None, environment_kwargs: dict | None = None) -> control.Environment:
    """The ``control.Environment`` of task ``task_name`` (one of ``TASKS``) on ``model``: a
    shipped MJCF by its name (the single arm ``scene.xml``, ``arm2_planar.xml``, ``arm3.xml``),
    an MJCF or model-file path, or an ``MjSpec`` (``mjjoint.build_arm(...)``).

    ``task_kwargs`` go to the task (``random``: a seed or ``RandomState``; ``sensors``: a
    ``JointSensors``; the task's own ranges), ``environment_kwargs`` to ``control.Environment``
    (``time_limit`` defaults to the task's, ``control_timestep`` to 1 ms).
    """
    if task_name not in TASKS:
        raise ValueError(f"task_name={task_name!r} is not a task (allowed: {', '.join(TASKS)})")
    task = TASKS[task_name](**(task_kwargs or {}))
    kwargs = {"time_limit": task.time_limit, "control_timestep": CONTROL_TIMESTEP, **(environment_kwargs or {})}
    return control.Environment(JointPhysics.load(model), task, **kwargs)


__all__ = ["CONTROL_TIMESTEP", "Damp", "Hold", "JointPhysics", "JointSensors", "JointTask", "SensorReadout",
           "TASKS", "Track", "build_rigid_arm", "load"]
