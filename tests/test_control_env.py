"""The dm_control environments (mjjoint.control): dm_env's contract on every task, episodes a
function of their seed, the full state (plugin states included) saved and restored, sensors as
specified, and a stiff frictionless joint that moves as the rigid arm does."""
from __future__ import annotations

import dataclasses
import unittest

import mujoco
import numpy as np
import pytest
from dm_control import mujoco as dm_mujoco
from dm_control.mujoco import wrapper
from dm_env import test_utils

from mjjoint import ASSETS_DIR, ArmSpec, JointParams, Transmission, build_arm
from mjjoint.rehearse import lsb
from mjjoint.control import TASKS, JointPhysics, JointSensors, build_rigid_arm, load


EXACT = JointSensors(resolver_bits=None, encoder_bits=None, torque_noise=0.0)


def short(task: str, model: str = "scene.xml", steps: int = 10, **task_kwargs):
    """An episode of ``steps`` control steps (1 ms each)."""
    return load(task, model, task_kwargs={"random": 0, **task_kwargs},
                environment_kwargs={"time_limit": steps * 1e-3})


def actions(env, n: int, seed: int = 0) -> list[np.ndarray]:
    spec = env.action_spec()
    rng = np.random.default_rng(seed)
    return [rng.uniform(spec.minimum, spec.maximum) * 0.2 for _ in range(n)]


def episode(env, acts) -> list[dict]:
    out = [env.reset().observation]
    for a in acts:
        ts = env.step(a)
        out.append(ts.observation)
    return out


# dm_env's own contract (reset/step types, specs matched, end of episode), per task and arm.
CONTRACT = [("track", "scene.xml"), ("hold", "scene.xml"), ("damp", "scene.xml"),
            ("hold", "arm2_planar.xml"), ("damp", "arm3.xml")]


def _contract(task: str, model: str):
    class Contract(test_utils.EnvironmentTestMixin, unittest.TestCase):
        def make_object_under_test(self):
            return short(task, model)

        def make_action_sequence(self):
            # Past the episode's end, so the contract at the last step is checked too.
            return actions(self.environment, 25)
    Contract.__name__ = Contract.__qualname__ = f"TestContract_{task}_{model.split('.')[0]}"
    return Contract


for _task, _model in CONTRACT:
    globals()[f"TestContract_{_task}_{_model.split('.')[0]}"] = _contract(_task, _model)


@pytest.mark.parametrize("task", list(TASKS))
def test_same_seed_same_episode_bit_identical(task):
    sensors = JointSensors(delay=2)  # quantised, noisy, late: every random draw is in play
    a, b, c = (short(task, steps=30, random=seed, sensors=sensors) for seed in (5, 5, 6))
    acts = actions(a, 30)
    ea, eb, ec = episode(a, acts), episode(b, acts), episode(c, acts)
    for oa, ob in zip(ea, eb):
        for key in oa:
            np.testing.assert_array_equal(oa[key], ob[key])
    assert any(not np.array_equal(oa["joint_torque"], oc["joint_torque"]) for oa, oc in zip(ea, ec))
    # A second episode of the same environment is drawn afresh, not a replay of the first.
    assert any(not np.array_equal(x["joint_torque"], y["joint_torque"]) for x, y in zip(ea, episode(a, acts)))


def _continue(physics: JointPhysics, acts) -> tuple[np.ndarray, np.ndarray]:
    qpos, plugin = [], []
    for u in acts:
        physics.set_control(u)
        physics.step(2)
        qpos.append(physics.data.qpos.copy())
        plugin.append(physics.data.plugin_state.copy())
    return np.array(qpos), np.array(plugin)


@pytest.mark.parametrize("model", ["scene.xml", "arm2_planar.xml", "input_delay"])
def test_state_round_trip_continues_bit_identical(model):
    delayed = model == "input_delay"
    if delayed:  # the actuator's input history is state too
        model = build_arm(ArmSpec(input_delay=1.2e-3))
    env = short("hold", model, steps=200)
    physics = env.physics
    acts = actions(env, 200)
    env.reset()
    for u in acts[:100]:
        env.step(u)
    state = physics.get_state()
    # The state is MuJoCo's full physics: time, actuator history and the plugin's states too.
    assert state.shape == (mujoco.mj_stateSize(physics.model.ptr, mujoco.mjtState.mjSTATE_FULLPHYSICS),)
    assert state[0] == physics.time()
    np.testing.assert_array_equal(state[-physics.model.npluginstate:], physics.data.plugin_state)
    assert np.any(physics.data.plugin_state != 0)
    copy = physics.copy()
    first = _continue(physics, acts[100:])
    for restored in ("in reset_context", "plain", "copy"):
        if restored == "copy":
            physics = copy
        elif restored == "plain":
            physics.set_state(state)
        else:
            with physics.reset_context():
                physics.set_state(state)
        again = _continue(physics, acts[100:])
        np.testing.assert_array_equal(first[0], again[0], err_msg=restored)
        np.testing.assert_array_equal(first[1], again[1], err_msg=restored)
    # dm_control's default state (qpos, qvel, act, plugin_state; no time) does not continue the
    # episode: the plugin's states hold at a time the restored data no longer has.
    with physics.reset_context():
        physics.set_state(state)
    partial = dm_mujoco.Physics.get_state(physics)
    physics.step(40)
    with physics.reset_context():
        dm_mujoco.Physics.set_state(physics, partial)
    assert not np.array_equal(_continue(physics, acts[100:])[0], first[0])
    if delayed:  # and without the input history neither, even at the right time
        no_history = int(mujoco.mjtState.mjSTATE_FULLPHYSICS) & ~int(mujoco.mjtState.mjSTATE_HISTORY)
        physics.set_state(state)
        partial = physics.get_state(no_history)
        physics.step(40)
        physics.set_state(partial, no_history)
        assert not np.array_equal(_continue(physics, acts[100:])[0], first[0])


def test_dm_control_loads_the_plugin_model_from_xml():
    """dm_control's own constructors read MJCF with the mjjoint.joint plugin (import mjjoint
    registered it) and run the same physics as JointPhysics.load."""
    spec = build_arm(ArmSpec(segments=2), scene=False)
    runs = []
    for physics in (dm_mujoco.Physics.from_xml_string(spec.to_xml()),
                    JointPhysics.from_xml_path(str(ASSETS_DIR / "elastic_joint.xml")),
                    JointPhysics.load(spec)):
        assert physics.model.nplugin == 1
        physics.reset(0)
        runs.append(_continue(physics, [np.array([2.0])] * 50))
    assert np.any(runs[0][1] != 0)           # the plugin's states moved
    np.testing.assert_array_equal(runs[0][0], runs[2][0])
    np.testing.assert_array_equal(runs[0][1], runs[2][1])
    assert runs[1][0].shape[1] == 6          # the shipped 4-segment arm


def test_set_state_of_the_wrong_size_is_refused():
    physics = JointPhysics.load("scene.xml")
    with pytest.raises(ValueError, match="expected"):
        physics.set_state(np.zeros(3))


def test_sensors_quantise_add_noise_and_delay():
    env = short("hold", steps=400, sensors=JointSensors(torque_noise=0.5))
    exact = short("hold", steps=400, sensors=EXACT)
    late = short("hold", steps=400, sensors=dataclasses.replace(EXACT, delay=3))
    acts = actions(env, 400)
    obs, ref, lag = episode(env, acts), episode(exact, acts), episode(late, acts)
    q = np.array([o["motor_angle"] for o in obs])
    theta = np.array([o["link_angle"] for o in obs])
    np.testing.assert_allclose(q / lsb(15), np.round(q / lsb(15)), atol=1e-9)
    np.testing.assert_allclose(theta / lsb(20), np.round(theta / lsb(20)), atol=1e-9)
    exact_q = np.array([o["motor_angle"] for o in ref])
    assert np.max(np.abs(q - exact_q)) <= lsb(15) / 2 + 1e-12
    assert np.ptp(exact_q) > 100 * lsb(15)   # the motor moved: quantisation was exercised
    noise = np.array([o["joint_torque"] for o in obs]) - np.array([o["joint_torque"] for o in ref])
    assert 0.45 < noise.std() < 0.55 and abs(noise.mean()) < 0.1
    for k, o in enumerate(lag):
        for key in o:
            np.testing.assert_array_equal(o[key], ref[max(k - 3, 0)][key])


def _links(physics) -> list[int]:
    return [ji.link_qpos for ji in physics.joints]


def test_rewards_are_one_on_target_and_fall_off_it():
    env = short("hold", "arm2_planar.xml")
    env.reset()
    physics, task = env.physics, env.task
    physics.data.qpos[_links(physics)] = task.target
    assert task.get_reward(physics) == 1.0
    physics.data.qpos[_links(physics)] = task.target + 0.05
    assert 0.0 < task.get_reward(physics) < 0.9
    env = short("track")
    env.reset()
    physics, task = env.physics, env.task
    physics.data.time = 0.3
    physics.data.qpos[_links(physics)] = task.reference(0.3)
    assert task.get_reward(physics) == 1.0
    physics.data.qpos[_links(physics)] += 0.05
    assert 0.0 < task.get_reward(physics) < 0.9
    env = short("damp")
    env.reset()
    assert 0.0 <= env.task.get_reward(env.physics) < 0.5  # starts bent
    physics = env.physics
    for rod in physics.rod_qpos:
        physics.data.qpos[rod] = 0.0
    assert env.task.get_reward(physics) == 1.0


def test_torque_cell_feedback_damps_the_rod_better_than_a_free_motor():
    # The damp task is observable and controllable from the sensors: feeding the noisy torque
    # cell back to the motor (-4 T/N of motor torque) calms the rod sooner than no current.
    def mean_reward(gain: float) -> float:
        env = load("damp", task_kwargs={"random": 0}, environment_kwargs={"time_limit": 1.0})
        ts, total = env.reset(), []
        while not ts.last():
            ts = env.step(-gain / (160 * 0.25) * ts.observation["joint_torque"])
            total.append(ts.reward)
        return float(np.mean(total))
    assert mean_reward(4.0) > mean_reward(0.0) + 0.1


@pytest.mark.parametrize("bad", [{"resolver_bits": 0}, {"encoder_bits": 40}, {"encoder_bits": 2.5},
                                 {"torque_noise": -1.0}, {"delay": -1}, {"delay": 1.5}])
def test_bad_sensor_parameters_are_refused(bad):
    with pytest.raises(ValueError, match="allowed range"):
        JointSensors(**bad)


def test_bad_task_and_rigid_rod_are_refused():
    with pytest.raises(ValueError, match="allowed: track, hold, damp"):
        load("swing")
    env = load("damp", build_arm(ArmSpec(segments=0)), task_kwargs={"random": 0})
    with pytest.raises(ValueError, match="no flexible segments"):
        env.reset()
    with pytest.raises(ValueError, match="reach="):
        load("hold", task_kwargs={"reach": (0.8, 0.3)})
    with pytest.raises(ValueError, match="sensors="):
        load("track", task_kwargs={"sensors": {"delay": 1}})


def test_a_stiff_frictionless_joint_moves_as_the_rigid_arm():
    # 1 s of 0.1 s current steps (+-3 A) swinging the arm over ~4.7 rad against gravity. A stiff
    # joint needs a short step (the stability check asks <= 89 us at k1 = 1e6).
    arm = ArmSpec(timestep=5e-5)
    rng = np.random.default_rng(0)
    acts = np.repeat(rng.uniform(-3, 3, 10), 100)[:, None]
    rigid = dm_mujoco.Physics.from_model(wrapper.MjModel(build_rigid_arm(arm, 160.0).compile()))
    rigid.reset(0)
    theta_rigid, rod_rigid = [], []
    for u in acts:
        rigid.set_control(u)
        rigid.step(20)
        theta_rigid.append(rigid.data.qpos[0])
        rod_rigid.append(rigid.data.qpos[1:].copy())
    theta_rigid = np.array(theta_rigid)
    errors = {}
    for k1 in (1e4, 1e6):
        joint = JointParams(friction=None, load_friction=None,
                            transmission=Transmission(k1=k1, k3=0.0, hysteresis=None))
        env = load("track", build_arm(arm, joint), task_kwargs={"random": 0, "sensors": EXACT},
                   environment_kwargs={"time_limit": 1.0})
        obs = episode(env, acts)[1:]
        theta = np.array([o["link_angle"][0] for o in obs])
        errors[k1] = np.max(np.abs(theta - theta_rigid))
        if k1 == 1e6:
            rod = env.physics.data.qpos[2:]
            np.testing.assert_allclose(rod, rod_rigid[-1], atol=1e-3)
    assert np.ptp(theta_rigid) > 3.0
    assert errors[1e6] < 1e-3                 # 0.02 % of the swing
    assert errors[1e6] < errors[1e4] / 5      # and the gap closes as the joint stiffens
