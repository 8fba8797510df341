"""The test suite leaves no MUJOCO_LOG.TXT in the tree (tests/conftest.py redirects it)."""
from __future__ import annotations

import mujoco

from conftest import ROOT_LOG

UNSTABLE = '<mujoco><worldbody><body><freejoint/><geom size="0.1"/></body></worldbody></mujoco>'


def test_a_mujoco_warning_goes_to_the_temporary_log_not_the_tree(mujoco_log_file, tmp_path, monkeypatch):
    monkeypatch.chdir(ROOT_LOG.parent)  # where MuJoCo would put its log by default
    before = ROOT_LOG.read_bytes() if ROOT_LOG.exists() else None
    model = mujoco.MjModel.from_xml_string(UNSTABLE)
    data = mujoco.MjData(model)
    data.qvel[:] = float("nan")
    mujoco.mj_step(model, data)  # "Nan, Inf or huge value in QVEL": the warning MuJoCo logs
    assert data.warning[mujoco.mjtWarning.mjWARN_BADQVEL].number == 1
    assert "QVEL" in mujoco_log_file.read_text()
    assert (ROOT_LOG.read_bytes() if ROOT_LOG.exists() else None) == before
