"""The installed package carries its MJCF: a shipped model is found by its name from any folder."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import mujoco
import pytest

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


# Packages of seconds' import that simulating does not need, each with what first loads it.
ON_FIRST_USE = {"dm_control": "mjjoint.control.load", "scipy.signal": "mjjoint.fit",
                "scipy.stats": "mjjoint.diagnose"}


def test_import_mjjoint_leaves_what_simulating_does_not_need_unloaded():
    code = ["import sys, mjjoint",
            *[f"assert {name!r} not in sys.modules, {name!r}" for name in ON_FIRST_USE],
            *[f"assert {use} is not None and {name!r} in sys.modules, {name!r}" for name, use in ON_FIRST_USE.items()]]
    subprocess.run([sys.executable, "-c", "; ".join(code)], check=True)


@pytest.mark.slow
def test_wheel_installed_elsewhere_simulates(tmp_path):
    """The built wheel, installed alone into a folder, runs ``mjjoint simulate`` from another one.

    The wheel's own files (not this checkout) must be what runs: its console script, its
    package data and its metadata (``--version``).
    """
    # A copy of the source: building in place would leave build/ in the checkout.
    root = tmp_path / "src"
    shutil.copytree(Path(__file__).resolve().parents[1], root, ignore=shutil.ignore_patterns(
        ".git", ".venv", "build", "dist", "out", "*.egg-info", "__pycache__", ".hypothesis", ".pytest_cache"))
    wheels, site, work = tmp_path / "wheels", tmp_path / "site", tmp_path / "work"
    work.mkdir()
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
    subprocess.run([*pip, "wheel", "--no-deps", "-w", str(wheels), str(root)], check=True)
    (wheel,) = wheels.glob("mjjoint-*.whl")
    with zipfile.ZipFile(wheel) as z:
        names = z.namelist()
    assert "mjjoint/assets/mjcf/arm3.xml" in names
    assert any(".dist-info/" in n and n.endswith("/LICENSE") for n in names)
    subprocess.run([*pip, "install", "--no-deps", "--target", str(site), str(wheel)], check=True)
    env = {**os.environ, "PYTHONPATH": str(site)}
    script = site / "bin" / "mjjoint"
    where = subprocess.run([sys.executable, "-c", "import mjjoint; print(mjjoint.__file__)"],
                           cwd=work, env=env, capture_output=True, text=True, check=True)
    assert Path(where.stdout.strip()).is_relative_to(site)
    done = subprocess.run([sys.executable, str(script), "simulate", "--model", "arm3.xml", "--duration", "0.2", "--csv", "x.csv"],
                          cwd=work, env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert (work / "x.csv").read_text().splitlines()[0].startswith("t,u1,q1,theta1,tau1")
    version = subprocess.run([sys.executable, str(script), "--version"], cwd=work, env=env,
                             capture_output=True, text=True, check=True)
    assert version.stdout.strip() == f"mjjoint {mjjoint.__version__}"
