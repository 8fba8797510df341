"""The shipped MJCF runs in plain MuJoCo after ``import mjjoint``: no loader, no register call.

Each check runs in a fresh interpreter, so nothing this test session registered or compiled
can make it pass.
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from mjjoint.assets import ASSETS_DIR

SHIPPED = sorted(p.name for p in Path(ASSETS_DIR).glob("*.xml"))

_PLAIN = r"""
import copy, json, sys
import mjjoint, mujoco
import numpy as np
from mujoco import rollout
from mjjoint.coupling import registry

path, steps = sys.argv[1], int(sys.argv[2])
FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS


def drive(model, data):
    rng = np.random.default_rng(0)
    ctrl = np.repeat(rng.normal(0.0, 0.5, (steps // 20 + 1, model.nu)), 20, axis=0)[:steps]
    out = np.empty((steps, mujoco.mj_stateSize(model, FULL)))
    passive = np.empty((steps, model.nv))
    for i in range(steps):
        data.ctrl[:] = ctrl[i]
        mujoco.mj_step(model, data)
        mujoco.mj_getState(model, data, out[i], FULL)
        passive[i] = data.qfrc_passive
    return out, passive, ctrl


# Plain MuJoCo, three ways in.
plain = mujoco.MjModel.from_xml_path(path)
spec_model = mujoco.MjSpec.from_file(path).compile()
# MuJoCo's compiler makes an mjData of the model, so plugin init has registered it already.
rows = int((registry.keys[:, registry.K_MODEL] == plain._address).sum())
a, passive, ctrl = drive(plain, mujoco.MjData(plain))
b, _, _ = drive(spec_model, mujoco.MjData(spec_model))
# A model that never had an mjData (a copy: MuJoCo's compiler makes one, copy.copy does not),
# rolled out with another model's data.
fresh = copy.copy(plain)
fresh_unregistered = not (registry.keys[:, registry.K_MODEL] == fresh._address).any()
x0 = np.empty(mujoco.mj_stateSize(plain, FULL))
d0 = mujoco.MjData(plain)
mujoco.mj_getState(plain, d0, x0, FULL)
rolled, _ = rollout.rollout(fresh, d0, x0[None], ctrl[None])

# The same MJCF with its plugin instances deleted: what MuJoCo does without the joint physics.
bare_spec = mujoco.MjSpec.from_file(path)
for p in list(bare_spec.plugins):
    bare_spec.delete(p)
bare = bare_spec.compile()
c, bare_passive, _ = drive(bare, mujoco.MjData(bare))

# The project's loader.
loaded = mjjoint.load_model(path)
ref, _, _ = drive(loaded, mujoco.MjData(loaded))

nq = plain.nq
print(json.dumps({
    "nplugin": plain.nplugin,
    "rows_registered": rows,
    "finite": bool(np.isfinite(a).all()),
    "max_vs_load_model": float(np.abs(a - ref).max()),
    "max_spec_vs_load_model": float(np.abs(b - ref).max()),
    "fresh_unregistered": fresh_unregistered,
    "max_rollout_fresh_model": float(np.abs(rolled[0] - a).max()),
    "max_qpos_vs_bare": float(np.abs(a[:, 1:1 + nq] - c[:, 1:1 + nq]).max()),
    "max_passive_vs_bare": float(np.abs(passive - bare_passive).max()),
}))
"""


@pytest.fixture(autouse=True)
def _in_tmp_cwd(tmp_path, monkeypatch):
    """The scripts run in a temporary folder: MuJoCo writes its warnings (the invalid config's
    NaN rollout) to MUJOCO_LOG.TXT in the working directory, which must not be the tree."""
    monkeypatch.chdir(tmp_path)


def _run(code: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_mjcf_runs_in_plain_mujoco_after_import(name):
    done = _run(_PLAIN, str(Path(ASSETS_DIR) / name), "400")
    assert done.returncode == 0, done.stderr
    r = json.loads(done.stdout.strip().splitlines()[-1])
    assert r["nplugin"] >= 1
    assert r["rows_registered"] == r["nplugin"]  # by plugin init: no register_model call
    assert r["finite"]
    # Bit-identical to the project's loader, whichever plain API compiled the model, and in a
    # rollout of a model that never had an mjData (compute registers it on its first step).
    assert r["max_vs_load_model"] == 0.0
    assert r["max_spec_vs_load_model"] == 0.0
    assert r["fresh_unregistered"] and r["max_rollout_fresh_model"] == 0.0
    # The plugin acts: joint torques in qfrc_passive, and a trajectory unlike the bare MJCF's.
    assert r["max_passive_vs_bare"] > 1e-3
    assert r["max_qpos_vs_bare"] > 1e-3


_BAD_CONFIG = r"""
import copy, sys
import mjjoint, mujoco
import numpy as np
from mujoco import rollout

FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS
spec = mujoco.MjSpec.from_file(sys.argv[1])
spec.plugins[0].config = {**dict(spec.plugins[0].config), "friction.fc": "-1"}
try:
    spec.compile()  # compiling makes an mjData, so the plugin's init reads the config
except ValueError as exc:
    print("compile:", str(exc).splitlines()[0])

# A model that never had an mjData, whose config is invalid, rolled out with another's data.
good = mujoco.MjModel.from_xml_path(sys.argv[1])
bad = copy.copy(good)
raw = bad.plugin_attr.view(np.uint8)
at = bytes(raw).index(b"\x00160\x00") + 1
raw[at:at + 3] = np.frombuffer(b"-60", np.uint8)  # transmission.gear_ratio = -60
data = mujoco.MjData(good)
x0 = np.empty(mujoco.mj_stateSize(good, FULL))
mujoco.mj_getState(good, data, x0, FULL)
state, _ = rollout.rollout(bad, data, x0[None], np.zeros((1, 5, good.nu)))
print("rollout finite:", bool(np.isfinite(state).all()))
"""


def test_invalid_config_in_plain_mujoco_fails_with_the_parameter_named():
    done = _run(_BAD_CONFIG, str(Path(ASSETS_DIR) / "elastic_joint.xml"))
    assert done.returncode == 0, done.stderr
    assert "compile: Error: engine error: plugin->init failed" in done.stdout, done.stdout
    assert "rollout finite: False" in done.stdout  # NaN (MuJoCo warns), never guessed parameters
    # The reasons, each once although compute retries the bad model on every step.
    lines = [ln for ln in done.stderr.splitlines() if ln.startswith("mjjoint:")]
    assert len(lines) == 2, done.stderr
    assert "friction.fc=-1" in lines[0] and "gear_ratio" in lines[1], done.stderr
