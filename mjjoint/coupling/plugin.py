"""The ``mjjoint.joint`` MuJoCo engine plugin: joint physics injected with no per-step Python.

Per step, MuJoCo calls one numba ``cfunc`` of this module: ``compute`` (passive stage) first
brings the internal friction and hysteresis states, held in ``plugin_state``, over the step
just taken (``kernels.joint_catch_up``), then adds the joint's torques to ``qfrc_passive``.
The states live in MuJoCo's state, so ``mj_getState``, ``mj_setState``, ``mj_resetData``,
keyframes, ``copy.copy`` and multithreaded ``mujoco.rollout`` all carry them.

Once per mjData, a Python ``init`` parses the instance's MJCF ``<config>`` with
``JointParams.from_config`` (the validation users get everywhere else), resolves the joint
names, and stores the parameter block in the model-keyed ``registry``; ``plugin_data`` only
caches the row. A model that reaches compute without a row (one of a ``mujoco.rollout`` batch
that never had an mjData) is parsed the same way, from compute, on its first step. Doing this
part in Python keeps the parsing and its error messages in one place; it never runs per step.

``import mjjoint`` registers the plugin, so plain MuJoCo loads, steps and rolls out the
shipped MJCF with no other mjjoint call.

The callbacks read mjModel/mjData through offsets discovered at run time (``abi.offsets``),
baked in as constants when they are compiled, once per process, at registration. The physics
they call (``kernels``) is compiled with ``cache=True``.
"""
from __future__ import annotations

import ctypes
import functools
import sys
import threading

import mujoco
import numpy as np
from numba import cfunc, njit, types

from ..joint import GROUND, JointParams, config_keys, split_config
from . import abi, registry
from .kernels import joint_catch_up, joint_forces
from .layout import AT, BLOCK_LEN, LD, LQ, MAX_JOINTS, MD, MQ, NJ, NSTATE, pack
from .pointers import _addr, f64_at, f64_ptr, f64_ptr_array, field, i32_array, u64_array
from .registry import find_row, row_matches

PLUGIN_NAME = "mjjoint.joint"
_MJOBJ_JOINT = int(mujoco.mjtObj.mjOBJ_JOINT)
_SINGLE_DOF = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))

_lock = threading.Lock()
_registered: dict[str, object] = {}  # keeps every callback object alive for the process
_next_row = 0


def _read_config(m_addr: int, instance: int) -> dict[str, str]:
    get = abi.libmujoco().mj_getPluginConfig
    get.restype = ctypes.c_char_p
    get.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_char_p]
    cfg = {}
    for key in config_keys():
        raw = get(m_addr, instance, key.encode())
        if raw:
            cfg[key] = raw.decode()
    return cfg


def _joint_addresses(m_addr: int, name: str) -> tuple[int, int]:
    if name == GROUND:
        return -1, -1
    lib = abi.libmujoco()
    lib.mj_name2id.restype = ctypes.c_int
    lib.mj_name2id.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_char_p]
    jid = lib.mj_name2id(m_addr, _MJOBJ_JOINT, name.encode())
    if jid < 0:
        raise ValueError(f"joint {name!r} named in the mjjoint.joint config does not exist in the model")
    off = abi.offsets()
    jtype = ctypes.c_int.from_address(abi.read_u64(m_addr + off.m_jnt_type) + 4 * jid).value
    if jtype not in _SINGLE_DOF:
        raise ValueError(f"joint {name!r} must be a hinge or slide joint for mjjoint.joint")
    qpos = ctypes.c_int.from_address(abi.read_u64(m_addr + off.m_jnt_qposadr) + 4 * jid).value
    dof = ctypes.c_int.from_address(abi.read_u64(m_addr + off.m_jnt_dofadr) + 4 * jid).value
    return qpos, dof


def instance_joints(m_addr: int, instance: int) -> list[JointParams]:
    """The JointParams of the joints one instance drives (one, or a group's)."""
    return list(_parsed(tuple(_read_config(m_addr, instance).items())))


@functools.lru_cache(maxsize=1024)
def _parsed(config: tuple[tuple[str, str], ...]) -> tuple[JointParams, ...]:
    """An instance's config parsed (memoised: identification compiles thousands of models of a
    few configs, and each model's registration and joint lookup parses it)."""
    cfgs = split_config(dict(config))
    if len(cfgs) > MAX_JOINTS:
        raise ValueError(f"one instance drives at most {MAX_JOINTS} joints, not {len(cfgs)}")
    return tuple(JointParams.from_config(c) for c in cfgs)


def instance_params(model: mujoco.MjModel) -> list[tuple[str, JointParams]]:
    """(label, JointParams) of every joint the model's mjjoint.joint instances drive, in instance
    order: the instance's name, with its motor joint's for an instance that drives several."""
    out = []
    for i in range(model.nplugin):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_PLUGIN, i) or f"{PLUGIN_NAME}[{i}]"
        joints = instance_joints(model._address, i)
        out += [(name if len(joints) == 1 else f"{name}:{p.motor_joint}", p) for p in joints]
    return out


def block_for(m_addr: int, instance: int) -> list[tuple[JointParams, np.ndarray]]:
    """Parse, validate and pack one instance's config: the parameters and parameter block of
    each joint it drives (raises ``ValueError`` on bad input)."""
    joints = instance_joints(m_addr, instance)
    out = []
    for params in joints:
        mq, md = _joint_addresses(m_addr, params.motor_joint)
        lq, ld = _joint_addresses(m_addr, params.link_joint)
        out.append((params, pack(params, mq, md, lq, ld, len(joints))))
    return out


def _attr_span(m_addr: int, instance: int) -> tuple[int, int]:
    """Address and length of one instance's config values (NUL-separated, key order)."""
    off = abi.offsets()
    attr = abi.read_u64(m_addr + off.m_plugin_attr)
    adr = ctypes.c_int.from_address(abi.read_u64(m_addr + off.m_plugin_attradr) + 4 * instance).value
    start = attr + adr
    length, seen = 0, 0
    while seen < len(config_keys()):
        if ctypes.c_char.from_address(start + length).value == b"\0":
            seen += 1
        length += 1
    return start, length


def _model_attr_span(model: mujoco.MjModel, instance: int) -> tuple[int, int]:
    """``_attr_span`` of a model object, read through its array view (no byte-wise ctypes reads:
    this runs for every model of every prediction batch)."""
    attr = model.plugin_attr
    start = int(model.plugin_attradr[instance])
    ends = np.flatnonzero(attr[start:] == 0)
    return attr.ctypes.data + start, int(ends[len(config_keys()) - 1]) + 1


def register_model(model_or_address, instance: int | None = None) -> list[int]:
    """Parse and store the parameters of a model's plugin instances; returns their rows.

    Called automatically for every new mjData (plugin init), by ``load_model``, and by compute
    on the first step of a model that never had an mjData of its own (e.g. ``copy.copy(model)``
    handed straight to ``mujoco.rollout``). Calling it up front moves that parse out of the
    rollout and raises a config error as a ``ValueError`` here.
    """
    global _next_row
    if isinstance(model_or_address, int):
        m_addr = model_or_address
        instances = [instance] if instance is not None else []
    else:
        m_addr = model_or_address._address
        instances = [instance] if instance is not None else range(model_or_address.nplugin)
    rows = []
    for i in instances:
        attr, length = (_attr_span(m_addr, i) if isinstance(model_or_address, int)
                        else _model_attr_span(model_or_address, i))
        with _lock:
            r = find_row(registry.KEYS_ADDRESS, registry.CONFIGS_ADDRESS, m_addr, attr, i)
            if r < 0:
                blocks = block_for(m_addr, i)
                words = registry.config_words(attr, length)
                r = _next_row
                _next_row = (_next_row + 1) % registry.CAPACITY
                registry.keys[r] = 0  # invalidate before the parameters change
                registry.params[r] = 0.0
                for j, (_, blk) in enumerate(blocks):
                    registry.params[r, j * BLOCK_LEN:(j + 1) * BLOCK_LEN] = blk
                registry.configs[r] = words
                registry.keys[r] = (m_addr, attr, length, i)
        rows.append(int(r))
    return rows


# (model, instance, message) of the config errors printed. The message is part of the key: a
# freed model's address is reused, and another model's error there must still be said.
_reported: set[tuple[int, int, str]] = set()


def _row_for(m_addr: int, d_addr: int, instance: int) -> int:
    """Register one instance and cache its row in d->plugin_data; -1 (message on stderr) if
    its config is invalid. Called from C: an exception cannot propagate."""
    try:
        (row,) = register_model(m_addr, instance)
    except Exception as exc:  # noqa: BLE001 - a C caller cannot take a Python exception
        key = (m_addr, instance, str(exc))
        if key not in _reported:  # compute retries every step: say it once
            _reported.add(key)
            print(f"mjjoint: plugin instance {instance}: {exc}", file=sys.stderr)
        return -1
    slots = abi.read_u64(d_addr + abi.offsets().d_plugin_data)
    ctypes.c_uint64.from_address(slots + 8 * instance).value = row
    return row


def _nstate(m_addr, instance):
    """States of one instance: NSTATE per joint it drives. Called by MuJoCo's compiler only; a
    config error is reported by init, which fails the model."""
    try:
        return NSTATE * len(split_config(_read_config(m_addr, instance)))
    except Exception:  # noqa: BLE001 - a C caller cannot take a Python exception
        return NSTATE


def _init(m_addr, d_addr, instance):
    return 0 if _row_for(m_addr, d_addr, instance) >= 0 else -1


def _miss(m_addr, d_addr, instance):
    """compute met a model instance with no parameter row (a model that never had an mjData
    of its own, e.g. one of a ``mujoco.rollout`` batch): register it now."""
    return _row_for(m_addr, d_addr, instance)


def _compile_hot_callbacks(off: abi.Offsets, miss):
    """numba cfuncs for reset and compute, with the offsets baked in; compute calls
    ``miss`` (a ctypes callback) for a model instance it finds no parameter row for."""
    d_qpos, d_qvel, d_frc, d_time = off.d_qpos, off.d_qvel, off.d_qfrc_passive, off.d_time
    d_state, d_data = off.d_plugin_state, off.d_plugin_data
    m_stateadr, m_statenum = off.m_plugin_stateadr, off.m_plugin_statenum
    m_dt, m_invw = off.m_timestep, off.m_dof_invweight0
    m_attr, m_attradr = off.m_plugin_attr, off.m_plugin_attradr
    keys_addr, configs_addr = registry.KEYS_ADDRESS, registry.CONFIGS_ADDRESS
    params_addr, cap, row_len = registry.PARAMS_ADDRESS, registry.CAPACITY, registry.ROW_LEN

    @njit(inline="always")
    def config_address(m, instance):
        return field(m, m_attr) + np.uint64(i32_array(field(m, m_attradr), instance + 1)[instance])

    @njit(inline="always")
    def lookup(m, d, instance):
        """This instance's parameter row for model m (cached in d->plugin_data), or -1."""
        slot = u64_array(field(d, d_data), instance + 1)
        attr = config_address(m, instance)
        # int64 throughout: int() of a uint64 stays uint64, and numba unifies uint64 with the
        # int64 of find_row as float64, which put float conversions on the row's address.
        r = np.int64(slot[instance])
        model = _addr(m)
        if r >= cap or not row_matches(keys_addr, configs_addr, r, model, attr, instance):
            r = find_row(keys_addr, configs_addr, model, attr, instance)
            if r >= 0:
                slot[instance] = np.uint64(r)
        return r

    @njit(inline="always")
    def joint_state(m, d, instance, r, j):
        # Raw pointers, not arrays: the kernels take either, and pointers leave numba nothing
        # to reference-count on the way in and out of each kernel call.
        blk = f64_ptr(params_addr + 8 * (row_len * r + BLOCK_LEN * j))
        adr = i32_array(field(m, m_stateadr), instance + 1)[instance] + NSTATE * j
        st = f64_ptr(field(d, d_state) + 8 * adr)
        mq, md, lq, ld = int(blk[MQ]), int(blk[MD]), int(blk[LQ]), int(blk[LD])
        qpos = f64_ptr(field(d, d_qpos))
        qvel = f64_ptr(field(d, d_qvel))
        q = qpos[mq] if mq >= 0 else 0.0
        th = qpos[lq] if lq >= 0 else 0.0
        wq = qvel[md] if md >= 0 else 0.0
        wth = qvel[ld] if ld >= 0 else 0.0
        return blk, st, q, wq, th, wth

    @cfunc(types.void(types.voidptr, types.voidptr, types.voidptr, types.int32))
    def reset(m, plugin_state, plugin_data, instance):
        n = i32_array(field(m, m_statenum), instance + 1)[instance]
        st = f64_ptr_array(plugin_state, n)
        for i in range(n):
            st[i] = 0.0
        for j in range(n // NSTATE):
            st[NSTATE * j + AT] = np.nan  # zero states at whatever time the reset leaves (a keyframe's)

    @cfunc(types.void(types.voidptr, types.voidptr, types.int32, types.int32))
    def compute(m, d, instance, capability):
        r = lookup(m, d, instance)
        if r < 0:
            r = miss(m, d, instance)  # first step of a model never registered: parse it now
        if r < 0:
            # Invalid config (the message is on stderr): fail loudly (MuJoCo reports NaN in
            # qacc) rather than guess.
            f64_ptr(field(d, d_frc))[0] = np.nan
            return
        h = f64_at(m, m_dt)
        t = f64_at(d, d_time)
        invw = f64_ptr(field(m, m_invw))
        frc = f64_ptr(field(d, d_frc))
        nj = int(f64_ptr(params_addr + 8 * row_len * r)[NJ])
        for j in range(nj):
            blk, st, q, wq, th, wth = joint_state(m, d, instance, r, j)
            md, ld = int(blk[MD]), int(blk[LD])
            hj = h * invw[md] if md >= 0 else 0.0
            hjl = h * invw[ld] if ld >= 0 else 0.0
            joint_catch_up(blk, st, q, wq, th, wth, t, h, hj, hjl)
            fm, fl = joint_forces(blk, st, q, wq, th, wth, h, hj, hjl)
            if md >= 0:
                frc[md] += fm
            if ld >= 0:
                frc[ld] += fl

    return reset, compute


_INIT = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int)
_NSTATE = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_int)
_MISS = ctypes.CFUNCTYPE(ctypes.c_int64, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int32)


def register() -> None:
    """Register ``mjjoint.joint`` with MuJoCo (idempotent; ``import mjjoint`` calls it, so
    plain ``mujoco.MjModel.from_xml_path`` and ``MjSpec.compile`` read the plugin's MJCF)."""
    with _lock:
        if PLUGIN_NAME in _registered:
            return
        off = abi.offsets()
        miss_cb = _MISS(_miss)
        reset, compute = _compile_hot_callbacks(off, miss_cb)
        nstate_cb = _NSTATE(_nstate)
        keys = config_keys()
        attrs = (ctypes.c_char_p * len(keys))(*[k.encode() for k in keys])
        plugin = abi.MjpPlugin()
        lib = abi.libmujoco()
        lib.mjp_defaultPlugin(ctypes.byref(plugin))
        plugin.name = PLUGIN_NAME.encode()
        plugin.nattribute = len(keys)
        plugin.attributes = attrs
        plugin.capabilityflags = int(mujoco.mjtPluginCapabilityBit.mjPLUGIN_PASSIVE)
        init_cb = _INIT(_init)
        plugin.nstate = ctypes.cast(nstate_cb, ctypes.c_void_p).value
        plugin.reset = reset.address
        plugin.compute = compute.address
        plugin.init = ctypes.cast(init_cb, ctypes.c_void_p).value
        lib.mjp_registerPlugin.restype = ctypes.c_int
        slot = lib.mjp_registerPlugin(ctypes.byref(plugin))
        if slot < 0:
            raise RuntimeError(f"MuJoCo refused to register plugin {PLUGIN_NAME!r}")
        # MuJoCo keeps raw pointers to all of these: they must live as long as the process.
        _registered[PLUGIN_NAME] = (plugin, attrs, keys, nstate_cb, reset, compute, init_cb, miss_cb)
