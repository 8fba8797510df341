"""Multi-joint arms: composition through MuJoCo's multibody dynamics, per-joint parameters, I/O."""
from __future__ import annotations

import dataclasses
import re
import tomllib
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml
from mujoco import rollout
from scipy import signal

from mjjoint.assets import ArmSpec, build_arm, load_model
from mjjoint.assets.builder import ASSETS_DIR
from mjjoint.assets.serial import (JointSpec, World, add_elastic_joint, add_home_key, build_serial_arm,
                                   check_arm_stability, new_spec, stable_timesteps)
from mjjoint.assets.serial_file import load_serial_arm_file, read_model_file
from mjjoint.assets.shipped_arms import SHIPPED, planar_arm2, shipped_xml
from mjjoint.trace_recording import recording
from mjjoint.tracking import track
from mjjoint.cli import main
from mjjoint.coupling import layout
from mjjoint.coupling.layout import pack
from mjjoint.joint import JointParams, group_config, split_config
from mjjoint.physics.load import LoadFriction
from mjjoint.physics.stribeck import StaticFriction
from mjjoint.physics.transmission import Transmission
from mjjoint.recordings import MultiRecording, read_recording
from mjjoint.sim import FULL, Simulator, check_diverged

DOCS = Path(__file__).resolve().parents[1] / "docs" / "multijoint.md"
# MuJoCo's stiffest equality: time constant 2 h (the least it accepts), impedance 0.9999.
STIFF_SOLIMP = [0.9999, 0.9999, 0.001, 0.5, 2]


def smooth_noise(n: int, ncol: int, cutoff: float, rms: float, seed: int) -> np.ndarray:
    """(n, ncol) noise low-passed at ``cutoff`` Hz (1 kHz samples), each column scaled to ``rms``."""
    sos = signal.butter(2, cutoff, fs=1000.0, output="sos")
    x = signal.sosfiltfilt(sos, np.random.default_rng(seed).standard_normal((n, ncol)), axis=0)
    return rms * x / x.std(axis=0)


def lock(spec: mujoco.MjSpec, *joints: str) -> None:
    h = spec.option.timestep
    for name in joints:
        spec.add_equality(type=mujoco.mjtEq.mjEQ_JOINT, name1=name, solref=[2 * h, 1.0], solimp=STIFF_SOLIMP)


def subtree_inertia(model: mujoco.MjModel, root: str) -> tuple[float, np.ndarray, np.ndarray]:
    """Mass, world COM and inertia about the COM of everything mounted below body ``root`` at home."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    top = model.body(root).id

    def below(b: int) -> bool:
        while b:
            b = model.body_parentid[b]
            if b == top:
                return True
        return False

    bodies = [b for b in range(model.nbody) if below(b)]
    m = model.body_mass[bodies]
    com = (m[:, None] * data.xipos[bodies]).sum(axis=0) / m.sum()
    inertia = np.zeros((3, 3))
    for b in bodies:
        rot = data.ximat[b].reshape(3, 3)
        r = data.xipos[b] - com
        inertia += rot @ np.diag(model.body_inertia[b]) @ rot.T + model.body_mass[b] * (r @ r * np.eye(3) - np.outer(r, r))
    return m.sum(), com, inertia


def test_locked_elbow_reproduces_the_single_arm_carrying_it_as_a_rigid_load():
    """A 2-DOF arm with its elbow locked = the shipped single arm with the elbow bolted on.

    The comparison is the single-joint builder (build_arm) plus one rigid body with the mass,
    COM and inertia of everything the elbow mounts on tip1 (computed here from the bodies). The
    lock is MuJoCo's stiffest joint equality, which still lets the elbow move by eps (~3e-8
    rad at h = 0.1 ms); a load displaced by eps changes the shoulder's motion by the same order,
    so the traces must agree within 10 eps in angle and 10 eps times the transmission's largest
    tangent stiffness in torque. The shoulder uses the Stribeck friction map: 2SEP's reversal
    memory turns any perturbation, even rounding, into a different stick-slip history.
    """
    h = 1e-4
    shoulder = JointParams(friction=StaticFriction())
    spec = build_serial_arm([JointSpec(tip_mass=1.0, joint=shoulder),
                             JointSpec(segments=0, rod_length=0.3, rod_mass=0.255, tip_mass=0.5)], World(timestep=h))
    lock(spec, "motor2", "link2")
    arm2 = load_model(spec)
    mass, com, inertia = subtree_inertia(arm2, "tip1")

    single = build_arm(ArmSpec(timestep=h), shoulder)
    data = mujoco.MjData(arm2)
    mujoco.mj_forward(arm2, data)
    load = single.body("tip").add_body(name="load", pos=com - data.xpos[arm2.body("tip1").id])
    load.mass, load.ipos, load.explicitinertial = mass, [0.0, 0.0, 0.0], True
    load.fullinertia = [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]]
    arm1 = load_model(single)

    u = smooth_noise(1000, 1, 5.0, 0.25, seed=0)[:, 0]  # swings the loaded link ~25 deg
    locked = Simulator(arm2).run(np.column_stack([u, np.zeros_like(u)]))
    ref = Simulator(arm1).run(u)
    eps = max(np.abs(locked[1].theta).max(), np.abs(locked[1].q / locked[1].gear_ratio).max())
    assert 0 < eps < 1e-6
    assert np.ptp(ref.theta) > 0.3 and np.abs(ref.tau).max() > 50  # the joint really worked
    tr = shoulder.transmission
    d_max = np.abs(ref.delta).max()
    k_tangent = tr.k1 + 2 * tr.k2 * d_max + 3 * tr.k3 * d_max ** 2
    a = locked[0]
    assert np.abs(a.theta - ref.theta).max() < 10 * eps
    assert np.abs(a.q - ref.q).max() / tr.gear_ratio < 10 * eps
    assert np.abs(a.tau - ref.tau).max() < 10 * eps * k_tangent


def _stiff_arm(k1: float) -> list[JointSpec]:
    """Rigid rods, and transmissions that are a linear spring only (no friction, damping, hysteresis)."""
    joint = JointParams(friction=None, load_friction=None,
                        transmission=Transmission(k1=k1, k3=0.0, damping=0.0, hysteresis=None))
    return [JointSpec(segments=0, joint=joint),
            JointSpec(segments=0, rod_length=0.3, rod_mass=0.255, tip_mass=1.0, joint=joint)]


def _stable_world(joints: list[JointSpec]) -> World:
    """The largest timestep dividing 1 ms that every joint's stable_timestep allows."""
    h_max = min(h for h, _ in stable_timesteps(build_serial_arm(joints, World(timestep=1e-6))).values())
    return World(timestep=1e-3 / np.ceil(1e-3 / h_max))


def _link_angles(model: mujoco.MjModel, states: np.ndarray, n: int) -> np.ndarray:
    return states[:, 1 + np.array([model.joint(f"link{i}").qposadr[0] for i in range(1, n + 1)])]


def test_stiff_transmissions_converge_to_the_rigid_arm_of_eq_1():
    """k1 -> inf: the elastic arm's links follow the rigid arm (motors geared by equalities).

    The rigid arm is the same MJCF with the plugin instances removed and each motor held at
    N theta by a joint equality, so MuJoCo's M, C, G (rotor reactions included) are Eq. 1 of
    the rigid robot. The elastic arm differs by the transmission deflection delta = T / k1
    and the ringing it excites, so the link angles must agree within the largest deflection
    (x 2 for the ringing), and the gap must shrink like 1 / k1.
    """
    u = smooth_noise(1000, 2, 3.0, 0.05, seed=1)  # ~0.3 and 0.6 rad swings
    gaps = []
    for k1 in (1e6, 1e7):
        joints = _stiff_arm(k1)
        world = _stable_world(joints)
        sim = Simulator(load_model(build_serial_arm(joints, world)))
        elastic = sim.run(u)
        rigid_spec = build_serial_arm(joints, world)
        for plugin in list(rigid_spec.plugins):
            rigid_spec.delete(plugin)
        for i, js in enumerate(joints, start=1):
            rigid_spec.add_equality(type=mujoco.mjtEq.mjEQ_JOINT, name1=f"motor{i}", name2=f"link{i}",
                                    data=[0.0, js.joint.gear_ratio] + [0.0] * 10,
                                    solref=[2 * world.timestep, 1.0], solimp=STIFF_SOLIMP)
        rigid = rigid_spec.compile()
        x0 = np.zeros(mujoco.mj_stateSize(rigid, FULL))
        mujoco.mj_getState(rigid, mujoco.MjData(rigid), x0, FULL)
        states, _ = rollout.rollout(rigid, mujoco.MjData(rigid), x0[None], sim.controls(u)[None])
        check_diverged(states[0], x0[0])
        theta_rigid = np.vstack([x0[None], states[0, sim.substeps - 1::sim.substeps][:-1]])
        theta_rigid = _link_angles(rigid, theta_rigid, 2)
        theta = np.column_stack([t.theta for t in elastic])
        delta = np.column_stack([np.abs(t.delta).max() for t in elastic])[0]
        gap = np.abs(theta - theta_rigid).max(axis=0)
        assert np.all(np.ptp(theta_rigid, axis=0) > 0.2)
        assert np.all(gap < 2 * delta), (k1, gap, delta)
        gaps.append(gap)
    ratio = gaps[0] / gaps[1]
    assert np.all((5 < ratio) & (ratio < 20)), ratio


def _bench(first: JointParams, second: JointParams) -> mujoco.MjModel:
    """Two identical single-joint arms side by side on one base, each with its own parameters."""
    spec = new_spec()
    add_elastic_joint(spec, spec.worldbody, 1, JointSpec(tip_mass=1.0, joint=first))
    add_elastic_joint(spec, spec.worldbody, 2, JointSpec(tip_mass=1.0, joint=second), pos=(0.0, 0.4, 0.0))
    add_home_key(spec)
    check_arm_stability(spec)
    return load_model(spec)


def test_swapping_two_joints_parameters_and_inputs_swaps_their_traces():
    p = JointParams()
    q = JointParams(friction=StaticFriction(fc=0.05, fs=0.08), load_friction=LoadFriction(fc=0.2),
                    transmission=Transmission(gear_ratio=100.0, k1=2e4, k3=5e7))
    u = smooth_noise(800, 2, 10.0, 0.15, seed=2)
    a = Simulator(_bench(p, q)).run(u)
    b = Simulator(_bench(q, p)).run(u[:, ::-1])
    for name in ("q", "theta", "tau"):
        # The two joints' own traces differ widely, and swap to rounding (the arms sit 0.4 m apart).
        assert np.abs(getattr(a[0], name) - getattr(a[1], name)).max() > 0.1
        for x, y in ((a[0], b[1]), (a[1], b[0])):
            assert np.allclose(getattr(x, name), getattr(y, name), rtol=0, atol=1e-9), name
    assert (a[0].gear_ratio, a[1].gear_ratio) == (160.0, 100.0)


def _warnings(data: mujoco.MjData) -> list[str]:
    return [f"{name} x{data.warning[int(w)].number}" for name, w in mujoco.mjtWarning.__members__.items()
            if w != mujoco.mjtWarning.mjNWARNING and data.warning[int(w)].number]


def test_threaded_rollouts_of_the_3dof_arm_from_several_states_stay_finite():
    model = load_model(ASSETS_DIR / "arm3.xml")
    sim = Simulator(model)
    rng = np.random.default_rng(3)
    x0 = np.tile(sim.initial_state(), (4, 1))
    for k in range(1, 4):  # arm raised, links and motors consistent (relaxed transmissions), moving
        for ji in sim.joints:
            theta = rng.uniform(-1.0, 1.0)
            x0[k, 1 + ji.link_qpos], x0[k, 1 + ji.motor_qpos] = theta, theta * ji.gear_ratio
            x0[k, 1 + model.nq + ji.link_dof] = rng.uniform(-1.0, 1.0)
    steps = 2000
    hold = round(1e-3 / model.opt.timestep)
    ctrl = np.stack([np.repeat(smooth_noise(steps // hold, model.nu, 20.0, 1.0, seed=10 + k), hold, axis=0)
                     for k in range(4)])  # 1 A RMS: a quarter of the range, clipped by MuJoCo
    datas = [mujoco.MjData(model) for _ in range(2)]
    states, _ = rollout.rollout(model, datas, x0, ctrl)
    assert [w for d in datas for w in _warnings(d)] == []
    assert np.all(np.isfinite(states))
    for k in range(4):
        check_diverged(states[k], x0[k, 0])
    swing = np.ptp(_link_angles(model, states.reshape(-1, states.shape[-1]), 3), axis=0)
    assert np.all(swing > 0.2)  # every joint moved


@pytest.mark.parametrize("name", list(SHIPPED))
def test_shipped_arms_survive_a_full_range_current_step_on_every_joint(name):
    model = load_model(ASSETS_DIR / name)
    for sign in (1.0, -1.0):
        data = mujoco.MjData(model)
        ctrl = np.full((1, int(0.5 / model.opt.timestep), model.nu), sign * model.actuator_ctrlrange[:, 1])
        x0 = np.zeros((1, mujoco.mj_stateSize(model, FULL)))
        mujoco.mj_getState(model, data, x0[0], FULL)
        states, _ = rollout.rollout(model, data, x0, ctrl)
        assert _warnings(data) == [] and np.all(np.isfinite(states))


@pytest.mark.parametrize("name", list(SHIPPED))
def test_shipped_xml_is_what_the_builder_writes(name):
    """The assets are generated (python -m mjjoint.assets.shipped_arms): they must not drift from the code."""
    assert (ASSETS_DIR / name).read_text() == shipped_xml(name)


def test_joint_params_reach_their_own_plugin_instance_and_stability_is_checked_per_joint():
    joints = planar_arm2()
    sim = Simulator(load_model(build_serial_arm(joints)))
    for i, (ji, js) in enumerate(zip(sim.joints, joints), start=1):
        names = sim.model.joint(f"motor{i}"), sim.model.joint(f"link{i}")
        expected = pack(js.joint, names[0].qposadr[0], names[0].dofadr[0], names[1].qposadr[0], names[1].dofadr[0])
        assert np.array_equal(ji.block, expected)
        assert sim.model.actuator_gear[ji.actuator, 0] == js.k_m
    too_stiff = [joints[0], JointSpec(joint=JointParams(transmission=Transmission(k1=1e7)))]
    with pytest.raises(ValueError, match=r"joint2: transmission.k1/k3 .* timestep=0.0005 s"):
        build_serial_arm(too_stiff)
    with pytest.raises(ValueError, match="perpendicular"):
        JointSpec(axis=(0, 0, 1), direction=(0, 0, -1))


MULTI_TOML = """\
[simulation]
sample_rate = 1000.0
[world]
timestep = 5e-4

[[joint]]
[joint.arm]
rod_length = 0.4
[joint.transmission]
k1 = 1.5e4

[[joint]]
[joint.arm]
axis = [0, 1, 0]
rod_length = 0.3
segments = 3
rod_mass = 0.255
tip_mass = 1.0
[joint.friction]
kind = "static"
[joint.transmission]
gear_ratio = 100.0
k1 = 5e3
k3 = 5e7
[joint.hysteresis]
kind = "none"
"""


def test_multi_joint_model_file_gives_each_joint_its_sections(tmp_path):
    path = tmp_path / "arm.toml"
    path.write_text(MULTI_TOML)
    arm = read_model_file(path)
    assert len(arm.joints) == 2 and arm.sample_rate == 1000.0
    first, second = (js.joint for js in arm.joints)
    assert first.transmission.k1 == 1.5e4 and second.transmission.k1 == 5e3
    assert isinstance(second.friction, StaticFriction) and second.transmission.hysteresis is None
    assert second.transmission.gear_ratio == 100.0 and arm.joints[1].segments == 3
    sim = Simulator(arm.compile())
    assert [j.gear_ratio for j in sim.joints] == [160.0, 100.0]
    as_yaml = tmp_path / "arm.yaml"
    as_yaml.write_text(yaml.safe_dump(tomllib.loads(MULTI_TOML)))
    assert read_model_file(as_yaml) == arm
    bad = tmp_path / "bad.toml"
    bad.write_text(MULTI_TOML.replace("gear_ratio = 100.0", "gear_ratio = -1.0"))
    with pytest.raises(ValueError, match=r"^.*bad.toml: joint\[2\]\.transmission\.gear_ratio=-1 is outside"):
        load_serial_arm_file(bad)


@pytest.mark.parametrize("text, message", [
    ("[[joint]]\narm = 3\n", r"joint\[1\]\.arm must be a section"),
    ("[[joint]]\narm = [1, 2]\n", r"joint\[1\]\.arm must be a section"),
    ("world = 3\n[[joint]]\n", "world must be a section"),
    ("simulation = 'x'\n[[joint]]\n", "simulation must be a section"),
])
def test_a_multi_joint_section_that_is_not_one_fails_in_one_line(tmp_path, text, message):
    path = tmp_path / "arm.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=message) as info:
        load_serial_arm_file(path)
    assert "\n" not in str(info.value) and str(info.value).startswith(str(path))


def test_the_documented_model_file_is_the_shipped_planar_arm(tmp_path):
    block = re.search(r"```toml\n(.*?)```", DOCS.read_text(), re.DOTALL).group(1)
    path = tmp_path / "doc.toml"
    path.write_text(block)
    arm = read_model_file(path)
    assert arm.joints == tuple(planar_arm2()) and arm.world == World()


def test_motor_side_pd_tracks_a_joint_space_trajectory():
    """A motor-side PD holds gravity and friction through N^2 kp at the link: the tracking
    error is a few percent of the motion and halves when the gains double."""
    sim = Simulator(load_model(build_serial_arm(planar_arm2())))
    t = np.arange(2000) / 1000
    ref = np.column_stack([0.4 * np.sin(2 * np.pi * 0.5 * t), -0.3 * np.sin(2 * np.pi * 0.5 * t)])
    gear = np.array([j.gear_ratio for j in sim.joints])
    limit = 4.0 * np.array([j.k_m for j in sim.joints])  # the arm's current limit as torque
    late = t > 0.5  # after the start-up transient
    errors = []
    for scale in (1.0, 2.0):
        kp, kd = scale * np.array([0.1, 0.2]), scale * np.array([0.004, 0.004])  # ~5 Hz at the link
        traces = track(sim, ref, kp, kd)
        theta = np.column_stack([tr.theta for tr in traces])
        errors.append(np.sqrt(np.mean((theta[late] - ref[late]) ** 2, axis=0)))
        # Each sample's torque is the PD law on that sample's motor state, clipped to the actuator.
        q = np.column_stack([tr.q for tr in traces])
        qd = np.column_stack([tr.qd for tr in traces])
        law = kp * (gear * ref - q) + kd * (gear * np.gradient(ref, 1e-3, axis=0) - qd)
        u = np.column_stack([tr.u for tr in traces])
        assert np.allclose(u, np.clip(law, -limit, limit), rtol=0, atol=1e-12)
    assert np.all(errors[0] < 0.05 * np.abs(ref).max(axis=0))
    ratio = errors[0] / errors[1]
    assert np.all((1.6 < ratio) & (ratio < 2.5)), ratio
    assert np.any(np.abs(u) == limit)  # the doubled gains reached the current limit


def test_simulate_cli_writes_per_joint_columns_for_a_multi_joint_model(tmp_path, capsys):
    csv = tmp_path / "arm.csv"
    assert main(["simulate", "--model", str(ASSETS_DIR / "arm3.xml"), "--duration", "0.3",
                 "--csv", str(csv), "--plot", str(tmp_path / "arm.png")]) == 0
    assert csv.read_text().splitlines()[0] == ",".join(
        ["t"] + [f"{s}{j}" for j in (1, 2, 3) for s in ("u", "q", "theta", "tau")])
    rec = read_recording(csv)
    assert isinstance(rec, MultiRecording) and rec.n_joints == 3 and rec.n == 300
    assert all(np.ptp(rec.joint(j).tau) > 0 for j in (1, 2, 3))
    assert all(np.array_equal(rec.joint(j).u, rec.joint(1).u) for j in (2, 3))  # every motor driven
    assert [p.name for p in sorted(tmp_path.glob("arm*.png"))] == ["arm1.png", "arm2.png", "arm3.png"]
    assert capsys.readouterr().out.count("joint ") >= 3


def test_simulate_cli_takes_a_multi_joint_model_file(tmp_path):
    model, csv = tmp_path / "arm.toml", tmp_path / "out.csv"
    model.write_text(MULTI_TOML)
    assert main(["simulate", "--model", str(model), "--excitation", "step", "--amplitude", "0.15",
                 "--param", "t0=0.05", "--duration", "0.2", "--csv", str(csv)]) == 0
    rec = read_recording(csv)
    direct = recording(Simulator(read_model_file(model).compile()).run(np.column_stack([rec.joint(1).u] * 2)))
    for j in (1, 2):  # the CLI wrote exactly what the API computes
        assert np.array_equal(rec.joint(j).theta, direct.joint(j).theta)


def test_one_instance_driving_every_joint_gives_the_per_joint_instances_traces_bit_for_bit():
    """One plugin instance listing the joints (``joints="motor1:link1 ..."``, per-joint values
    space-separated) runs the same physics as one instance per joint, through plain MuJoCo too."""
    joints = planar_arm2()
    joints[1] = dataclasses.replace(joints[1], joint=joints[1].joint.replace(
        friction=StaticFriction(fc=0.02, fs=0.03), load_friction=None))  # other kinds per joint
    # both through MJCF text, read by plain MuJoCo
    each = mujoco.MjModel.from_xml_string(build_serial_arm(joints).to_xml())
    spec = build_serial_arm(joints, one_instance=True)
    one = mujoco.MjModel.from_xml_string(spec.to_xml())
    assert (each.nplugin, one.nplugin) == (2, 1) and one.npluginstate == each.npluginstate
    cfg = dict(spec.plugins[0].config)
    assert cfg["joints"] == "motor1:link1 motor2:link2" and cfg["friction"] == "2sep static"
    rng = np.random.default_rng(0)
    u = rng.uniform(-0.4, 0.4, (400, 2)).repeat(5, axis=0)
    a, b = Simulator(each).run(u), Simulator(one).run(u)
    for x, y in zip(a, b):
        for field in ("q", "theta", "qd", "tau", "friction", "load_friction", "states"):
            assert np.array_equal(getattr(x, field), getattr(y, field), equal_nan=True), field
    # reset leaves every joint's states at zero, their time unset
    data = mujoco.MjData(one)
    mujoco.mj_resetData(one, data)
    st = data.plugin_state.reshape(2, -1)
    assert np.isnan(st[:, layout.AT]).all() and not st[:, :layout.AT].any()


def test_a_group_config_with_the_wrong_number_of_values_is_one_line():
    cfg = group_config([JointParams(motor_joint="motor1", link_joint="link1"),
                        JointParams(motor_joint="motor2", link_joint="link2")])
    cfg["friction.fc"] = "0.1 0.2 0.3"
    with pytest.raises(ValueError, match="'friction.fc' has 3 values for 2 joints"):
        split_config(cfg)
    with pytest.raises(ValueError, match="must be motor_joint:link_joint"):
        split_config({"joints": "motor1 link1"})
