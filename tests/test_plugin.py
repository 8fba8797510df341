"""The engine plugin keeps its states in MuJoCo's state and its parameters in the MJCF."""
from __future__ import annotations

import copy
import ctypes

import mujoco
import numpy as np
import pytest
from mujoco import rollout

from mjjoint.assets import ArmSpec, build_arm, load_model
from mjjoint.coupling import abi
from mjjoint.coupling.layout import AT, NSTATE, X
from mjjoint.joint import JointParams
from mjjoint.physics.transmission import Transmission
from mjjoint.physics.twosep import TwoSEP

FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS


def _drive(model, data, nstep, seed=0):
    """Band-limited random current, stepped with mj_step; returns the full state trajectory."""
    rng = np.random.default_rng(seed)
    current = np.repeat(rng.normal(0.0, 0.3, nstep // 20 + 1), 20)[:nstep]
    out = np.empty((nstep, mujoco.mj_stateSize(model, FULL)))
    for i in range(nstep):
        data.ctrl[0] = current[i]
        mujoco.mj_step(model, data)
        mujoco.mj_getState(model, data, out[i], FULL)
    return out, current


@pytest.fixture(scope="module")
def model():
    return load_model()


def test_discovered_offsets_match_the_bindings(model):
    data = mujoco.MjData(model)
    off = abi.offsets()
    assert abi.read_u64(data._address + off.d_plugin_state) == data.plugin_state.ctypes.data
    assert abi.read_u64(data._address + off.d_plugin_data) == data.plugin_data.ctypes.data
    assert abi.read_u64(model._address + off.m_plugin_stateadr) == model.plugin_stateadr.ctypes.data
    assert ctypes.c_double.from_address(model._address + off.m_timestep).value == model.opt.timestep
    data.time = 12.375
    assert ctypes.c_double.from_address(data._address + off.d_time).value == data.time


def test_states_live_in_plugin_state(model):
    data = mujoco.MjData(model)
    assert model.npluginstate == NSTATE
    _drive(model, data, 400)
    assert np.any(data.plugin_state != 0.0), "2SEP and Bouc-Wen states must evolve"
    full = np.empty(mujoco.mj_stateSize(model, FULL))
    mujoco.mj_getState(model, data, full, FULL)
    np.testing.assert_array_equal(full[-NSTATE:], data.plugin_state)


def test_save_restore_is_bit_identical(model):
    data = mujoco.MjData(model)
    _drive(model, data, 300, seed=1)
    saved = np.empty(mujoco.mj_stateSize(model, FULL))
    mujoco.mj_getState(model, data, saved, FULL)
    first, _ = _drive(model, data, 500, seed=2)
    mujoco.mj_setState(model, data, saved, FULL)
    again, _ = _drive(model, data, 500, seed=2)
    np.testing.assert_array_equal(first, again)


def test_state_restore_matters(model):
    """The check above is not vacuous: restoring only qpos/qvel (not the plugin state) differs."""
    data = mujoco.MjData(model)
    _drive(model, data, 300, seed=1)
    spec = mujoco.mjtState.mjSTATE_PHYSICS
    saved = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, saved, spec)
    first, _ = _drive(model, data, 500, seed=2)
    mujoco.mj_setState(model, data, saved, spec)
    again, _ = _drive(model, data, 500, seed=2)
    assert not np.array_equal(first, again)


def test_copy_carries_states_and_parameters(model):
    data = mujoco.MjData(model)
    _drive(model, data, 300, seed=3)
    twin = copy.copy(data)
    np.testing.assert_array_equal(twin.plugin_state, data.plugin_state)
    a, _ = _drive(model, data, 300, seed=4)
    del data  # the copy must not depend on the original's memory
    b, _ = _drive(model, twin, 300, seed=4)
    np.testing.assert_array_equal(a, b)


def _assert_fresh(data):
    """Zero states that hold at whatever time they are next evaluated (AT is NaN)."""
    np.testing.assert_array_equal(data.plugin_state[:AT], 0.0)
    assert np.isnan(data.plugin_state[AT])


def test_reset_and_keyframe_reset_clear_states(model):
    data = mujoco.MjData(model)
    _drive(model, data, 300, seed=5)
    assert np.any(data.plugin_state[:AT] != 0.0)
    mujoco.mj_resetData(model, data)
    _assert_fresh(data)
    _drive(model, data, 300, seed=5)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    _assert_fresh(data)
    # A reset run reproduces a fresh run exactly.
    fresh = mujoco.MjData(model)
    a, _ = _drive(model, data, 300, seed=6)
    b, _ = _drive(model, fresh, 300, seed=6)
    np.testing.assert_array_equal(a, b)


def test_unregistered_model_is_registered_on_its_first_step(model):
    """A model copy never registered (no mjData of its own) is parsed by compute on its first
    step and runs its own parameters: the same trajectory as the registered model."""
    from mjjoint.coupling import registry
    twin = copy.copy(model)
    saved = registry.keys.copy()
    data = mujoco.MjData(model)
    x0 = np.empty(mujoco.mj_stateSize(model, FULL))
    mujoco.mj_getState(model, data, x0, FULL)
    ctrl = np.full((1, 50, 1), 0.3)
    good, _ = rollout.rollout(model, data, x0[None], ctrl)
    try:
        registry.keys[:] = 0  # forget every model, as if neither had ever been seen
        state, _ = rollout.rollout(twin, data, x0[None], ctrl)
        assert (registry.keys[:, registry.K_MODEL] == twin._address).sum() == 1
    finally:
        registry.keys[:] = saved
    np.testing.assert_array_equal(state, good)


def test_model_at_a_recycled_address_with_another_config_is_parsed_afresh(model):
    """Rows keyed by this model's address whose config bytes differ (a freed model's rows, the
    address reused by a model never registered) are never used: compute parses the live config
    into a new row, so the old parameters never run."""
    from mjjoint.coupling import registry
    data = mujoco.MjData(model)
    x0 = np.empty(mujoco.mj_stateSize(model, FULL))
    mujoco.mj_getState(model, data, x0, FULL)
    ctrl = np.full((1, 5, 1), 0.3)
    good, _ = rollout.rollout(model, data, x0[None], ctrl)
    assert np.isfinite(good).all()
    rows = np.flatnonzero(registry.keys[:, registry.K_MODEL] == model._address)
    assert rows.size > 0
    saved_keys, saved_configs, saved_params = registry.keys.copy(), registry.configs.copy(), registry.params.copy()
    try:
        registry.configs[rows, 0] ^= np.uint64(1)  # as if parsed from another config at this address
        registry.params[rows] = np.nan  # ... with parameters that would show if they ran
        state, _ = rollout.rollout(model, data, x0[None], ctrl)
        fresh = np.flatnonzero(registry.keys[:, registry.K_MODEL] == model._address)
        assert set(fresh) > set(rows)  # a new row, from the live config
    finally:
        registry.keys[:], registry.configs[:], registry.params[:] = saved_keys, saved_configs, saved_params
    np.testing.assert_array_equal(state, good)


def test_extra_evaluations_between_steps_change_nothing(model):
    """compute advances the states once per new time: mj_forward (sensors, rendering), repeated
    or not, between steps leaves the trajectory bit-identical, and brings plugin_state to the
    states at d.time that the stepping reference holds."""
    plain, probed = mujoco.MjData(model), mujoco.MjData(model)
    a, current = _drive(model, plain, 200, seed=11)
    b = np.empty_like(a)
    settled = []
    for i, c in enumerate(current):
        probed.ctrl[0] = c
        mujoco.mj_step(model, probed)
        mujoco.mj_getState(model, probed, b[i], FULL)
        mujoco.mj_forward(model, probed)
        mujoco.mj_forward(model, probed)
        settled.append(probed.plugin_state[:AT].copy())
    np.testing.assert_array_equal(a, b)
    # What mj_forward left is the pending step applied: the next step's start states.
    np.testing.assert_array_equal(np.array(settled[:-1]), a[1:, -NSTATE:-NSTATE + AT])
    assert np.ptp(np.array(settled)[:, X]) > 0.0


def test_rk4_is_refused_with_a_one_line_error():
    spec = build_arm()
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_RK4
    with pytest.raises(ValueError, match="RK4") as err:
        load_model(spec)
    assert "\n" not in str(err.value)


def test_threaded_rollout_of_two_parameter_sets_equals_sequential_runs():
    soft = load_model(build_arm(joint=JointParams(transmission=Transmission(k1=3e3))))
    sticky = load_model(build_arm(joint=JointParams(friction=TwoSEP(fc=0.15, fs=0.2))))
    models = [soft, sticky]
    rng = np.random.default_rng(7)
    nstep = 2000
    ctrl = np.repeat(rng.normal(0, 0.4, (2, nstep // 25, 1)), 25, axis=1)
    x0 = []
    for m in models:
        d = mujoco.MjData(m)
        s = np.empty(mujoco.mj_stateSize(m, FULL))
        mujoco.mj_getState(m, d, s, FULL)
        x0.append(s)
    x0 = np.array(x0)
    threaded, _ = rollout.rollout(models, [mujoco.MjData(soft), mujoco.MjData(soft)], x0, ctrl)
    for i, m in enumerate(models):
        single, _ = rollout.rollout(m, mujoco.MjData(m), x0[i:i + 1], ctrl[i:i + 1])
        np.testing.assert_array_equal(threaded[i], single[0])
    # Different MJCF parameters really give different physics side by side in one process.
    assert np.abs(threaded[0, -1, 1:3] - threaded[1, -1, 1:3]).max() > 1e-3


def test_rollout_matches_mj_step(model):
    data = mujoco.MjData(model)
    x0 = np.empty(mujoco.mj_stateSize(model, FULL))
    mujoco.mj_getState(model, data, x0, FULL)
    stepped, current = _drive(model, data, 600, seed=8)
    rolled, _ = rollout.rollout(model, mujoco.MjData(model), x0[None], current[None, :, None])
    np.testing.assert_array_equal(rolled[0], stepped)


@pytest.mark.parametrize("config, needle", [
    ({"friction.fc": "-1"}, "friction.fc"),
    ({"transmission.k1": "abc"}, "transmission.k1"),
    ({"friction": "lugre"}, "friction='lugre'"),
    ({"hysteresis.mu": "1.5"}, "mu=1.5"),
    ({"link_joint": "nosuchjoint"}, "nosuchjoint"),
    ({"friction.fc": ""}, "'friction.fc' has an empty value"),
])
def test_bad_plugin_config_is_a_one_line_error(config, needle):
    spec = build_arm()
    plugin = spec.plugins[0]
    plugin.config = {**dict(plugin.config), **config}
    with pytest.raises((ValueError, Exception)) as err:
        load_model(spec)
    message = str(err.value)
    assert needle in message and "\n" not in message.strip()


def test_a_fixed_input_loads_but_has_no_motor_to_drive():
    """motor_joint "world" holds the gear's input still: a valid joint, which an input torque
    cannot drive; the simulator says why in one line."""
    from mjjoint.sim import Simulator
    sim = Simulator(load_model(build_arm(ArmSpec(), JointParams(motor_joint="world"))))
    with pytest.raises(ValueError, match=r"motor_joint is 'world' \(a fixed input\)") as err:
        sim.controls(np.zeros(10))
    assert "\n" not in str(err.value)


def test_locked_output_keeps_link_still():
    sim_model = load_model(build_arm(ArmSpec(), JointParams(link_joint="world")))
    data = mujoco.MjData(sim_model)
    _drive(sim_model, data, 500, seed=9)
    assert data.qpos[sim_model.joint("link").qposadr[0]] == 0.0
    assert abs(data.qpos[sim_model.joint("motor").qposadr[0]]) > 0.0


def test_a_model_objects_config_span_is_the_byte_wise_reads():
    from mjjoint.assets.serial import build_serial_arm
    from mjjoint.assets.shipped_arms import arm3
    from mjjoint.coupling.plugin import _attr_span, _model_attr_span
    models = [build_arm(scene=False).compile(), build_serial_arm(arm3()).compile(),
              build_serial_arm(arm3(), one_instance=True).compile()]
    spans = [(_model_attr_span(m, i), _attr_span(m._address, i)) for m in models for i in range(m.nplugin)]
    assert len(spans) == 5
    for fast, bytewise in spans:
        assert fast == bytewise
