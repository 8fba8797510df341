"""Where mjjoint reaches into MuJoCo's C structs, found at run time for the installed release.

Struct offsets change between MuJoCo releases, so none is hard-coded. The pointer sections
of ``mjData`` and ``mjModel`` (everything after ``void* buffer``) are runs of 8-byte pointers
in header order; the order is read from the headers the wheel ships, one field is located by
scanning a live struct for the address the Python bindings report, the others follow from the
order, and several are checked against the bindings before anything is trusted.
"""
from __future__ import annotations

import ctypes
import functools
import re
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

MUJOCO_DIR = Path(mujoco.__file__).parent
_PTR = 8
_PROBE = 0.000123456789012345  # a value no default field of mjOption or mjData holds


@functools.lru_cache(maxsize=None)
def libmujoco() -> ctypes.CDLL:
    """The shared library the Python bindings themselves load."""
    path = MUJOCO_DIR / f"libmujoco.so.{mujoco.__version__}"
    if not path.exists():
        raise RuntimeError(f"mjjoint needs {path.name} from mujoco {mujoco.__version__}; not found in {MUJOCO_DIR}")
    return ctypes.CDLL(str(path))


def _pointer_fields(header: str, struct: str) -> list[str]:
    text = (MUJOCO_DIR / "include" / "mujoco" / header).read_text()
    body = text[text.index(f"struct {struct}_ {{"):]
    body = body[: body.index("\n}")]
    lines = body[re.search(r"void\*\s+buffer;", body).start():].splitlines()
    names: list[str] = []
    tail = False  # scalar fields may close the struct (mjData.signature), never interrupt the run
    for line in lines:
        code = line.split("//")[0].strip()
        if not code:
            continue
        m = re.fullmatch(r"[\w ]+\*\s*(\w+);", code)
        if m is None:
            tail = True
        elif tail:
            raise RuntimeError(f"pointer field {m.group(1)!r} after scalars in {struct}: unsupported layout")
        else:
            names.append(m.group(1))
    return names


def read_u64(address: int) -> int:
    return ctypes.c_uint64.from_address(address).value


def _locate(struct_addr: int, fields: list[str], known: dict[str, int]) -> dict[str, int]:
    """Offsets of ``fields``, anchored where every pointer in ``known`` matches at once.

    Several anchors are needed because d->buffer equals d->qpos; the solver statistics make
    mjData ~200 kB before its pointer run, hence the long scan.
    """
    first, first_ptr = next(iter(known.items()))
    for off in range(0, 1 << 21, _PTR):
        if read_u64(struct_addr + off) != first_ptr:
            continue
        base = off - _PTR * fields.index(first)
        if base >= 0 and all(read_u64(struct_addr + base + _PTR * fields.index(n)) == p
                             for n, p in known.items()):
            return {name: base + _PTR * i for i, name in enumerate(fields)}
    raise RuntimeError(f"could not locate {list(known)} in a live MuJoCo {mujoco.__version__} struct")


@dataclass(frozen=True)
class Offsets:
    """Byte offsets of the fields the plugin callbacks read."""

    d_qpos: int
    d_qvel: int
    d_qfrc_passive: int
    d_plugin_state: int
    d_plugin_data: int
    m_jnt_type: int
    m_jnt_qposadr: int
    m_jnt_dofadr: int
    m_dof_invweight0: int
    m_plugin_stateadr: int
    m_plugin_statenum: int
    m_plugin_attr: int
    m_plugin_attradr: int
    m_timestep: int
    d_time: int


_PROBE_XML = """<mujoco><worldbody><body><joint name="a"/><geom size=".1"/>
<body pos="0 0 -1"><joint name="b"/><geom size=".1"/></body></body></worldbody>
<actuator><motor joint="a"/></actuator></mujoco>"""


@functools.lru_cache(maxsize=None)
def offsets() -> Offsets:
    """Discover and verify the offsets on a probe model of the installed MuJoCo."""
    m = mujoco.MjModel.from_xml_string(_PROBE_XML)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    dfields = _pointer_fields("mjdata.h", "mjData")
    mfields = _pointer_fields("mjmodel.h", "mjModel")
    dd = _locate(d._address, dfields, {n: getattr(d, n).ctypes.data for n in ("qpos", "qvel", "qacc")})
    mm = _locate(m._address, mfields, {n: getattr(m, n).ctypes.data for n in ("jnt_qposadr", "jnt_dofadr")})
    for name in ("qvel", "qfrc_passive", "ctrl", "xpos", "qacc"):
        if read_u64(d._address + dd[name]) != getattr(d, name).ctypes.data:
            raise RuntimeError(f"mjData.{name} offset check failed for mujoco {mujoco.__version__}")
    for name in ("jnt_type", "jnt_dofadr", "dof_invweight0", "body_mass", "dof_damping", "actuator_gear"):
        if read_u64(m._address + mm[name]) != getattr(m, name).ctypes.data:
            raise RuntimeError(f"mjModel.{name} offset check failed for mujoco {mujoco.__version__}")
    # opt.timestep (in the embedded mjOption) and d->time precede the pointer runs: found by value.
    m_timestep = _inline_double(m, "opt.timestep", mm["buffer"])
    d_time = _inline_double(d, "time", dd["buffer"])
    return Offsets(
        d_qpos=dd["qpos"], d_qvel=dd["qvel"], d_qfrc_passive=dd["qfrc_passive"],
        d_plugin_state=dd["plugin_state"], d_plugin_data=dd["plugin_data"],
        m_jnt_type=mm["jnt_type"], m_jnt_qposadr=mm["jnt_qposadr"], m_jnt_dofadr=mm["jnt_dofadr"],
        m_dof_invweight0=mm["dof_invweight0"],
        m_plugin_stateadr=mm["plugin_stateadr"], m_plugin_statenum=mm["plugin_statenum"],
        m_plugin_attr=mm["plugin_attr"],
        m_plugin_attradr=mm["plugin_attradr"], m_timestep=m_timestep, d_time=d_time,
    )


def _inline_double(struct, name: str, before: int) -> int:
    """Offset of the double ``struct.<name>`` (a dotted path) within its first ``before`` bytes,
    located by setting it to a probe value and finding the one place that holds it."""
    *path, leaf = name.split(".")
    owner = functools.reduce(getattr, path, struct)
    saved = getattr(owner, leaf)
    setattr(owner, leaf, _PROBE)
    raw = np.frombuffer(ctypes.string_at(struct._address, before - before % 8), dtype=np.float64)
    setattr(owner, leaf, saved)
    hits = np.flatnonzero(raw == _PROBE)
    if len(hits) != 1:
        raise RuntimeError(f"could not locate {type(struct).__name__}.{name} in mujoco {mujoco.__version__}")
    return int(hits[0]) * 8


class MjpPlugin(ctypes.Structure):
    """ctypes mirror of ``mjpPlugin`` (mjplugin.h of mujoco 3.17.0, 152 bytes)."""

    _fields_ = [
        ("name", ctypes.c_char_p),
        ("nattribute", ctypes.c_int),
        ("attributes", ctypes.POINTER(ctypes.c_char_p)),
        ("capabilityflags", ctypes.c_int),
        ("needstage", ctypes.c_int),
        ("nstate", ctypes.c_void_p),
        ("nsensordata", ctypes.c_void_p),
        ("init", ctypes.c_void_p),
        ("destroy", ctypes.c_void_p),
        ("copy", ctypes.c_void_p),
        ("reset", ctypes.c_void_p),
        ("compute", ctypes.c_void_p),
        ("advance", ctypes.c_void_p),
        ("visualize", ctypes.c_void_p),
        ("actuator_act_dot", ctypes.c_void_p),
        ("sdf_distance", ctypes.c_void_p),
        ("sdf_gradient", ctypes.c_void_p),
        ("sdf_staticdistance", ctypes.c_void_p),
        ("sdf_attribute", ctypes.c_void_p),
        ("sdf_aabb", ctypes.c_void_p),
    ]


assert ctypes.sizeof(MjpPlugin) == 152, "mjpPlugin mirror must match mujoco 3.17.0"
