"""``mjjoint simulate``: outputs, excitation options, model files, one-line errors, chunking."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from mjjoint.assets import ASSETS_DIR, ArmSpec
import mjjoint.cli.memory as memory
import mjjoint.viz.rerun_log as rerun_log
from mjjoint.cli import COMMANDS, main
from mjjoint.cli.chunked import rollout_chunked
from mjjoint.excitation import Chirp, Step
from mjjoint.sim import Simulator, simulate

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
HEADER = "t,u,q,theta,tau"


def read_csv(path: Path) -> dict[str, np.ndarray]:
    header = path.read_text().splitlines()[0]
    assert header == HEADER
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    return dict(zip(header.split(","), data.T))


def test_simulate_writes_the_csv_of_the_requested_chirp(tmp_path, capsys):
    csv = tmp_path / "trace.csv"
    assert main(["simulate", "--duration", "0.5", "--csv", str(csv)]) == 0
    cols = read_csv(csv)
    assert len(cols["t"]) == 500 and all(np.all(np.isfinite(c)) for c in cols.values())
    assert np.allclose(cols["t"], np.arange(500) / 1000, rtol=0, atol=1e-12)
    assert np.array_equal(cols["u"], Chirp().sample(1000, 0.5))  # %.17g round-trips exactly
    assert np.ptp(cols["q"]) > 0 and np.ptp(cols["tau"]) > 0  # the joint actually moved
    assert "wrote" in capsys.readouterr().out


def test_simulate_without_arguments_writes_csv_png_and_rrd(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["simulate"]) == 0
    out = tmp_path / "out" / "simulate"
    cols = read_csv(out / "trace.csv")
    assert len(cols["t"]) == 5000  # the default: 5 s at 1 kHz
    assert (out / "trace.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (out / "trace.rrd").stat().st_size > 0


def test_step_options_reach_the_excitation_and_friction_limits_the_swing(tmp_path):
    csv = tmp_path / "step.csv"
    rc = main(["simulate", "--excitation", "step", "--amplitude", "0.095", "--param", "t0=0.2",
               "--duration", "3", "--csv", str(csv)])
    assert rc == 0
    c = read_csv(csv)
    assert np.all(c["u"][c["t"] < 0.2 - 1e-9] == 0) and np.all(c["u"][c["t"] >= 0.2 - 1e-9] == 0.095)
    # Sliding, the motor friction takes at least its Coulomb level 0.08 N m, so at most
    # (0.095 - 0.08) x 160 = 2.4 N m reach the link against gravity G sin(theta), with
    # G = g (m_tip L + m_rod L / 2) = 4.59 N m: the arm swings up but stays below asin(2.4 / G).
    gravity = 9.81 * (1.0 * 0.4 + 0.34 * 0.2)
    bound = np.arcsin((0.095 - 0.08) * 160 / gravity)
    assert 0.3 < c["theta"].max() < bound


def test_a_stiffer_model_file_deflects_less(tmp_path):
    default, stiff = tmp_path / "default.csv", tmp_path / "stiff.csv"
    common = ["simulate", "--excitation", "step", "--amplitude", "0.1", "--duration", "1"]
    assert main([*common, "--model", str(EXAMPLES / "default.toml"), "--csv", str(default)]) == 0
    assert main([*common, "--model", str(EXAMPLES / "stiff_linear.yaml"), "--csv", str(stiff)]) == 0

    def deflection(c):
        return np.abs(c["q"] / 160.0 - c["theta"]).max()
    # ten times the linear stiffness and no hardening to help the default at small deflection
    assert deflection(read_csv(stiff)) < 0.3 * deflection(read_csv(default))


def test_mjcf_model_and_file_excitation_replay_the_recorded_input(tmp_path):
    first, replay = tmp_path / "first.csv", tmp_path / "replay.csv"
    xml = ASSETS_DIR / "scene.xml"
    assert main(["simulate", "--model", str(xml), "--excitation", "multisine", "--param", "n=8",
                 "--duration", "0.4",
                 "--csv", str(first)]) == 0
    # The trace CSV is itself a valid excitation file (columns t and u); replaying it on the
    # same deterministic model must give the same response.
    assert main(["simulate", "--model", str(xml), "--file", str(first), "--csv", str(replay)]) == 0
    a, b = read_csv(first), read_csv(replay)
    assert np.array_equal(a["u"], b["u"]) and np.array_equal(a["q"], b["q"])


def _bad_model(tmp_path: Path) -> str:
    path = tmp_path / "bad.toml"
    path.write_text("[transmission]\nk1 = -3\n")
    return str(path)


def _written(path, text: str):
    path.write_text(text)
    return path


BAD_ARGS = [
    (lambda p: ["simulate", "--model", _bad_model(p)], "transmission.k1=-3"),
    (lambda p: ["simulate", "--model", str(p / "missing.yaml")], "no such file"),
    (lambda p: ["simulate", "--excitation", "sawtooth"], "invalid choice"),
    (lambda p: ["simulate", "--param", "width"], "KEY=VALUE"),
    (lambda p: ["simulate", "--excitation", "chirp", "--param", "width=2"], "unknown key chirp.width"),
    (lambda p: ["simulate", "--excitation", "impulse", "--param", "width=-1"], "impulse.width=-1"),
    (lambda p: ["simulate", "--excitation", "multisine", "--param", "n=many"], "n='many' must be an integer"),
    (lambda p: ["simulate", "--excitation", "file"], "--file"),
    (lambda p: ["simulate", "--file", str(p / "none.csv")], "no such file"),
    (lambda p: ["simulate", "--seed", "3"], "--seed does not apply"),
    (lambda p: ["simulate", "--rate", "fast"], "invalid float value"),
    (lambda p: ["simulate", "--rate", "-5"], "--rate=-5"),
    (lambda p: ["simulate", "--duration", "0"], "duration=0"),
    (lambda p: ["simulate", "--duration", "nan"], "--duration=nan s must be positive and finite"),
    (lambda p: ["simulate", "--csv", str(p)], "is a directory"),
    (lambda p: ["simulate", "--csv", str(p / "file.txt" / "x.csv")], "file.txt"),
    # outside the working directory an output's folder must exist (nothing made at the root)
    (lambda p: ["simulate", "--csv", str(p / "missing" / "x.csv")], "missing does not exist"),
    (lambda p: ["simulate", "--plot", str(p / "missing" / "x.png")], "--plot"),
    (lambda p: ["simulate", "--rrd", str(p / "missing" / "x.rrd")], "--rrd"),
    (lambda p: ["simulate", "--out", str(p / "missing" / "sim")], "--out"),
    (lambda p: ["simulate", "--rate", "3000", "--csv", str(p / "x.csv")], "sample_rate=3000"),
    # outputs checked before any simulation: one file each, each in a format its writer writes
    (lambda p: ["simulate", "--csv", str(p / "x.csv"), "--rrd", str(p / "x.csv")], "must name different files"),
    (lambda p: ["simulate", "--csv", str(p / "x.txt")], "--csv writes .csv, not '.txt'"),
    (lambda p: ["simulate", "--plot", str(p / "x.txt")], "--plot writes"),
    (lambda p: ["simulate", "--rrd", str(p / "x")], "--rrd writes .rrd, not 'a name without a suffix'"),
    # a flexible rod far too stiff for the step: MuJoCo's own joint springs diverge
    (lambda p: ["simulate", "--model", str(_written(p / "stiff.toml", "[arm]\nrod_ei = 1e7\n")), "--duration", "0.5",
                "--csv", str(p / "x.csv")], "diverged"),
    (lambda p: [], "required: COMMAND"),
    (lambda p: ["fit-everything"], "invalid choice"),
]


@pytest.mark.parametrize("make_args, message", BAD_ARGS, ids=[m for _, m in BAD_ARGS])
def test_user_errors_exit_2_with_one_line(tmp_path, capsys, monkeypatch, make_args, message):
    (tmp_path / "file.txt").write_text("not a directory")
    (tmp_path / "cwd").mkdir()
    monkeypatch.chdir(tmp_path / "cwd")  # tmp_path is outside the working directory
    rc = main(make_args(tmp_path))
    err = capsys.readouterr().err
    assert rc == 2
    assert_one_error_line(err, message)
    assert not (tmp_path / "missing").exists()


def assert_one_error_line(err: str, message: str) -> None:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("mjjoint: error: ") and message in lines[0]


def test_missing_folders_are_created_inside_the_working_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "--duration", "0.1", "--csv", "a/b/x.csv", "--rrd", str(tmp_path / "c" / "x.rrd")]) == 0
    assert (tmp_path / "a" / "b" / "x.csv").is_file() and (tmp_path / "c" / "x.rrd").is_file()


def final_outputs(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir()) if folder.exists() else []


def test_an_interrupt_while_writing_leaves_only_the_previous_complete_outputs(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out" / "simulate"

    def interrupted(*args, **kwargs):  # Ctrl-C after the CSV and the plot are written
        assert any(".partial-" in name for name in final_outputs(out))
        raise KeyboardInterrupt
    real = rerun_log.log_traces
    monkeypatch.setattr(rerun_log, "log_traces", interrupted)
    assert main(["simulate", "--duration", "0.2"]) == 130
    assert final_outputs(out) == []  # no trace.csv of full size, no partial names

    monkeypatch.setattr(rerun_log, "log_traces", real)
    assert main(["simulate", "--duration", "0.2"]) == 0
    first = {name: (out / name).read_bytes() for name in final_outputs(out)}
    assert sorted(first) == ["trace.csv", "trace.png", "trace.rrd"]
    monkeypatch.setattr(rerun_log, "log_traces", interrupted)
    assert main(["simulate", "--duration", "0.3"]) == 130
    assert {name: (out / name).read_bytes() for name in final_outputs(out)} == first
    assert "mjjoint: interrupted" in capsys.readouterr().err


def test_sigint_to_a_running_simulate_leaves_no_output(tmp_path):
    """The real Ctrl-C: SIGINT once the first partial file exists."""
    out = tmp_path / "out" / "simulate"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    proc = subprocess.Popen([sys.executable, "-m", "mjjoint", "simulate"], cwd=tmp_path,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while proc.poll() is None and time.monotonic() < deadline:
        if any(".partial-" in name for name in final_outputs(out)):
            break
        time.sleep(0.005)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and err.strip().splitlines()[-1] == "mjjoint: interrupted"
    assert final_outputs(out) == []


def test_a_run_that_would_not_fit_in_memory_is_refused_before_it_starts(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(memory, "available_bytes", lambda: 24e9)  # the 24 GB machine of the report
    csv = tmp_path / "x.csv"
    start = time.perf_counter()
    assert main(["simulate", "--duration", "1e6", "--csv", str(csv)]) == 2
    assert time.perf_counter() - start < 5  # refused up front, not after allocating 8 GB of input
    err = capsys.readouterr().err
    assert_one_error_line(err, "--duration 1e+06 s at --rate 1000 Hz")
    assert "GB of memory but 24 GB is available" in err and not csv.exists()
    # The estimate scales with the run: 10 s at 1 kHz needs about 16 MB.
    monkeypatch.setattr(memory, "available_bytes", lambda: 10e6)
    assert main(["simulate", "--duration", "10", "--csv", str(csv)]) == 2
    monkeypatch.setattr(memory, "available_bytes", lambda: 30e6)
    assert main(["simulate", "--duration", "10", "--csv", str(csv)]) == 0


def test_available_memory_is_known_on_linux():
    have = memory.available_bytes()
    assert have is not None and have > 0


def test_help_exits_0(capsys):
    assert main(["--help"]) == 0
    assert main(["simulate", "--help"]) == 0
    out = capsys.readouterr().out
    assert "--excitation" in out and "KEY=VALUE" in out and "f_start=30.0" in out


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_prints_its_help(command, capsys):
    """argparse formats each help text with %: a literal percent sign in one broke the command's
    --help with a format error."""
    assert main([command, "--help"]) == 0
    out, err = capsys.readouterr()
    assert out.startswith(f"usage: mjjoint {command}") and not err


def test_module_entry_point_prints_no_traceback(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "mjjoint.cli", "simulate", "--model", _bad_model(tmp_path)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert proc.stderr.strip().splitlines() == [f"mjjoint: error: {tmp_path}/bad.toml: transmission.k1=-3 is "
                                                "outside the allowed range (0, inf)"]


@pytest.mark.parametrize("arm", [ArmSpec(), ArmSpec(input_delay=2e-3)], ids=["default", "input-delay"])
def test_chunked_rollout_equals_one_rollout_exactly(arm):
    sim = Simulator(arm=arm)
    u = Chirp(amplitude=0.15).sample(sim.sample_rate, 0.6)
    whole = sim.rollout_states(u)
    for chunk in (1, 7, 250, 600, 1000):
        assert np.array_equal(rollout_chunked(sim, u, chunk), whole), chunk


def test_python_api_in_three_lines(tmp_path):
    trace = simulate(Step().sample(1000, 1.0))
    path = trace.to_csv(tmp_path / "x.csv")
    assert len(read_csv(path)["t"]) == 1000
