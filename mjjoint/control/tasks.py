"""Tasks a joint engineer sets an elastic arm: track a reference, hold a pose under gravity,
damp the flexible rod after a disturbance. Each joint's action is its motor current [A] (the
MJCF's actuators, within their ctrlrange); rewards are in [0, 1] (``rewards.tolerance``, the
mean over the joints), computed from the true state, not the sensors."""
from __future__ import annotations

import math
from collections import OrderedDict

import numpy as np
from dm_control.suite import base
from dm_control.utils import rewards

from ..params import check
from .physics import JointPhysics
from .sensors import JointSensors, SensorReadout


def interval(name: str, pair: tuple[float, float], lo: float, hi: float, *, lo_open: bool = False) -> tuple[float, float]:
    """A validated (low, high) range of a task's draw, both ends within [lo, hi]."""
    a, b = (check(name, x, lo, hi, lo_open=lo_open) for x in pair)
    if a > b:
        raise ValueError(f"{name}={pair!r} must be (low, high) with low <= high")
    return a, b


def closeness(error: np.ndarray, tolerance: float, margin: float) -> float:
    """1 within +-tolerance, a Gaussian falling to 0.1 at ``margin`` beyond it; joints averaged."""
    return float(np.mean(rewards.tolerance(error, bounds=(-tolerance, tolerance), margin=margin,
                                           sigmoid="gaussian", value_at_margin=0.1)))


class JointTask(base.Task):
    """Starts every episode at the model's first keyframe (hanging at rest), observes the
    sensors; subclasses set up the episode (``start``) and say what is rewarded: an error
    within +-``tolerance`` scores 1, one ``margin`` beyond it 0.1."""

    time_limit = 5.0  # [s] the episode's default length (``mjjoint.control.load``)

    def __init__(self, tolerance: float, margin: float, sensors: JointSensors = JointSensors(),
                 random=None) -> None:
        super().__init__(random=random)
        self.tolerance = check("tolerance", tolerance, 0.0, lo_open=True)
        self.margin = check("margin", margin, 0.0)
        if not isinstance(sensors, JointSensors):
            raise ValueError(f"sensors={sensors!r} must be a mjjoint.control.JointSensors")
        self.sensors = sensors
        self._readout = SensorReadout(sensors)

    def initialize_episode(self, physics: JointPhysics) -> None:
        physics.reset(0 if physics.model.nkey else None)
        self._readout.clear()
        self.start(physics)
        super().initialize_episode(physics)

    def start(self, physics: JointPhysics) -> None:
        """Draw the episode's goal or disturbance from ``self.random``."""

    def get_observation(self, physics: JointPhysics) -> OrderedDict:
        return self._readout.read(physics, self.random)


class Track(JointTask):
    """The links follow references theta_ref_i(t) = A sin(2 pi f_i t + phi_i) - A sin(phi_i)
    (0 at the start), f_i and phi_i drawn per episode. Observed: the sensors and the reference."""

    time_limit = 10.0

    def __init__(self, amplitude: float = 0.3, frequencies: tuple[float, float] = (0.2, 1.0),
                 tolerance: float = 0.01, margin: float = 0.1, **kwargs) -> None:
        super().__init__(tolerance, margin, **kwargs)
        self.amplitude = check("amplitude", amplitude, 0.0, math.pi, lo_open=True)
        self.frequencies = interval("frequencies", frequencies, 0.0, 50.0, lo_open=True)

    def start(self, physics: JointPhysics) -> None:
        n = len(physics.joints)
        self._f = self.random.uniform(*self.frequencies, n)
        self._phi = self.random.uniform(0.0, 2 * math.pi, n)

    def reference(self, t: float) -> np.ndarray:
        return self.amplitude * (np.sin(2 * math.pi * self._f * t + self._phi) - np.sin(self._phi))

    def get_observation(self, physics: JointPhysics) -> OrderedDict:
        obs = super().get_observation(physics)
        obs["reference"] = self.reference(physics.time())
        return obs

    def get_reward(self, physics: JointPhysics) -> float:
        return closeness(physics.link_angles() - self.reference(physics.time()), self.tolerance, self.margin)


class Hold(JointTask):
    """From hanging at rest, bring the links to a pose drawn per episode (each joint
    ``reach[0]`` to ``reach[1]`` rad either way) and hold it against gravity. Observed: the
    sensors and the target."""

    def __init__(self, reach: tuple[float, float] = (0.3, 0.8), tolerance: float = 0.005,
                 margin: float = 0.1, **kwargs) -> None:
        super().__init__(tolerance, margin, **kwargs)
        self.reach = interval("reach", reach, 0.0, math.pi)

    def start(self, physics: JointPhysics) -> None:
        n = len(physics.joints)
        self.target = self.random.uniform(*self.reach, n) * self.random.choice([-1.0, 1.0], n)

    def get_observation(self, physics: JointPhysics) -> OrderedDict:
        obs = super().get_observation(physics)
        obs["target"] = self.target.copy()
        return obs

    def get_reward(self, physics: JointPhysics) -> float:
        return closeness(physics.link_angles() - self.target, self.tolerance, self.margin)


class Damp(JointTask):
    """Every flexible rod starts bent (its segments evenly, the tip's slope ``bend[0]`` to
    ``bend[1]`` rad either way), link at rest; reward: the rods' vibration amplitude
    sqrt(b^2 + (b'/mode)^2) of the bend b back within ``tolerance`` (a bend passing zero at speed
    is no calm rod). ``mode`` [rad/s] scales the rate: the shipped rod's first bending mode, ~21 Hz
    (elastic_joint.xml). Links without flexible segments are not scored."""

    time_limit = 2.0

    def __init__(self, bend: tuple[float, float] = (0.02, 0.05), mode: float = 2 * math.pi * 21,
                 tolerance: float = 2e-4, margin: float = 0.01, **kwargs) -> None:
        super().__init__(tolerance, margin, **kwargs)
        self.bend = interval("bend", bend, 0.0, 0.5)
        self.mode = check("mode", mode, 0.0, 1e5, lo_open=True)

    def start(self, physics: JointPhysics) -> None:
        self._scored = np.array([len(r) > 0 for r in physics.rod_qpos])
        if not self._scored.any():
            raise ValueError("the model's links have no flexible segments: nothing to damp")
        for rod in physics.rod_qpos:
            slope = self.random.uniform(*self.bend) * self.random.choice([-1.0, 1.0])
            physics.data.qpos[rod] = slope / max(len(rod), 1)

    def vibration(self, physics: JointPhysics) -> np.ndarray:
        """Each scored rod's vibration amplitude [rad]."""
        return np.hypot(physics.rod_bends(), physics.rod_bend_rates() / self.mode)[self._scored]

    def get_reward(self, physics: JointPhysics) -> float:
        return closeness(self.vibration(physics), self.tolerance, self.margin)
