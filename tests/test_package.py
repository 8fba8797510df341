"""The installed package carries its MJCF: a shipped model is found by its name from any folder."""
from __future__ import annotations

from pathlib import Path

import mujoco

import mjjoint
from mjjoint.cli import main


def test_shipped_mjcf_is_package_data():
    names = {p.name for p in mjjoint.ASSETS_DIR.glob("*.xml")}
    assert {"elastic_joint.xml", "scene.xml", "arm3.xml", "linear_drive.xml"} <= names
    assert mjjoint.ASSETS_DIR.is_relative_to(Path(mjjoint.__file__).parent)
    model = mujoco.MjModel.from_xml_path(str(mjjoint.ASSETS_DIR / "arm3.xml"))
    assert model.nplugin == 3


def test_a_shipped_model_by_name_from_another_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "--model", "arm3.xml", "--duration", "0.2", "--csv", "x.csv"]) == 0
    header = (tmp_path / "x.csv").read_text().splitlines()[0]
    assert header.startswith("t,u1,q1,theta1,tau1")


def test_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"mjjoint {mjjoint.__version__}"
