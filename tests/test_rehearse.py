"""Closed-loop recordings (``mjjoint.rehearse``, ``mjjoint simulate --controller``): the loop
tracks, the command respects its limit, the sensors' counts, noise and delay show in the
written signals, a seed gives the same bytes, and ``mjjoint diagnose`` reads the result."""
from __future__ import annotations

import json

import numpy as np
import pytest

from mjjoint.cli import main
from mjjoint.excitation import Chirp, Step
from mjjoint.joint import JointParams
from mjjoint.modelfile import ModelFile
from mjjoint.physics.load import LoadFriction
from mjjoint.rehearse import Controller, Sensors, lsb, run_loop
from mjjoint.sim import Simulator

RATE = 1000.0
SLOW = Chirp(amplitude=0.1, f_start=0.5, f_end=0.2)  # [rad at the link]: far below either loop's bandwidth


@pytest.fixture(scope="module")
def model():
    return ModelFile().compile()


def read(path):
    header = path.read_text().splitlines()[0].split(",")
    return dict(zip(header, np.loadtxt(path, delimiter=",", skiprows=1).T))


@pytest.mark.parametrize("kind, on, share", [("pd", "motor", 0.05), ("pid", "motor", 0.05),
                                             ("pd", "link", 0.1), ("pid", "link", 0.1)])
def test_a_slow_reference_is_tracked(model, kind, on, share):
    """rms error under 5 % of the amplitude on the motor loop (~15 Hz), 10 % on the link (half that)."""
    ref = SLOW.sample(RATE, 3.0)
    cols = run_loop(model, ref, Controller.default(kind, on), Sensors(), RATE).columns
    sensed = cols["theta"] if on == "link" else cols["q"] / 160.0
    assert np.sqrt(np.mean((ref - sensed) ** 2)) < share * SLOW.amplitude
    assert np.sqrt(np.mean((ref - cols["theta"]) ** 2)) < share * SLOW.amplitude  # the link follows


def test_the_integral_removes_what_gravity_leaves_of_a_link_step():
    """The bearing's dry friction left out (it holds the link anywhere within its band, whatever
    the loop): what the PD leaves is gravity's, and the integral removes it."""
    gravity_only = ModelFile(joint=JointParams(load_friction=LoadFriction(fc=0.0))).compile()
    ref = Step(amplitude=0.15, t0=0.2).sample(RATE, 5.0)  # the integral's time constant is seconds
    offset = {kind: abs(np.mean(ref[-300:] - run_loop(gravity_only, ref, Controller.default(kind, "link"), Sensors(),
                                                      RATE).columns["theta"][-300:])) for kind in ("pd", "pid")}
    assert offset["pid"] < 0.75 * offset["pd"]


def test_the_true_motion_behind_the_log_is_the_simulators(model):
    """The states the loop keeps give, through Simulator.traces, the angles the sensors counted."""
    sensors = Sensors(resolver_bits=14, encoder_bits=18, torque_noise=0.0)
    run = run_loop(model, Step(amplitude=0.15, t0=0.1).sample(RATE, 1.0), Controller(), sensors, RATE,
                   keep_states=True)
    trace = Simulator(model, sample_rate=RATE).traces(run.states, run.columns["u"])[0]
    assert np.array_equal(np.round(trace.q / lsb(14)) * lsb(14), run.columns["q"])
    assert np.array_equal(np.round(trace.theta / lsb(18)) * lsb(18), run.columns["theta"])
    assert np.array_equal(trace.tau, run.columns["tau"])


def test_the_reader_delays_every_channel_by_whole_samples():
    read_now, read_late = Sensors(resolver_bits=0, encoder_bits=0, torque_noise=0).reader(), \
        Sensors(resolver_bits=0, encoder_bits=0, torque_noise=0, delay=3).reader()
    x = np.arange(10.0)
    now = [read_now(v, 2 * v, 3 * v) for v in x]
    late = [read_late(v, 2 * v, 3 * v) for v in x]
    assert late[3:] == now[:-3] and late[:3] == [now[0]] * 3


@pytest.mark.parametrize("sensors", [dict(resolver_bits=-1), dict(encoder_bits=33), dict(torque_noise=-0.1),
                                     dict(delay=1.5), dict(q_noise=1e300), dict(torque_noise=1e5)])
def test_bad_sensor_values_name_the_range(sensors):
    with pytest.raises(ValueError, match="range|integer"):
        Sensors(**sensors)


def test_a_delay_as_long_as_the_run_is_refused(tmp_path, capsys):
    """A 10 000-sample delay on a 2 s run at 1 kHz logged q = 0 throughout, exit 0."""
    assert main(["simulate", "--controller", "pd", "--duration", "2", "--delay", "2000",
                 "--csv", str(tmp_path / "rec.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--delay 2000 samples is not shorter than the run (2000 samples)" in err[0]
    assert not (tmp_path / "rec.csv").exists()


def test_the_written_command_never_exceeds_the_limit(tmp_path, capsys):
    csv = tmp_path / "rec.csv"
    assert main(["simulate", "--controller", "pd", "--reference", "step", "--limit", "0.2", "--duration", "1",
                 "--csv", str(csv)]) == 0
    u = read(csv)["u"]
    assert np.abs(u).max() <= 0.2 and np.isclose(np.abs(u).max(), 0.2)  # reached: the limit acted
    assert json.loads(csv.with_suffix(".json").read_text())["controller"]["u_max"] == 0.2
    assert "limit 0.2" in capsys.readouterr().out


def test_the_counts_of_coarse_encoders_show_in_the_written_angles(tmp_path):
    csv = tmp_path / "rec.csv"
    assert main(["simulate", "--controller", "pid", "--reference", "step", "--duration", "1", "--bits",
                 "q=10,theta=12", "--noise", "tau=0.2", "--csv", str(csv)]) == 0
    cols = read(csv)
    for name, bits in (("q", 10), ("theta", 12)):
        counts = cols[name] / lsb(bits)
        assert np.allclose(counts, np.round(counts), rtol=0, atol=1e-6)  # whole counts only
        steps = np.diff(np.unique(np.round(counts)))
        assert steps.min() == 1 and len(steps) > 3  # adjacent counts visited: the step is one count
    sidecar = json.loads(csv.with_suffix(".json").read_text())
    assert sidecar["sensors"]["resolver_bits"] == 10 and sidecar["sensors"]["torque_noise"] == 0.2
    assert np.std(np.diff(cols["tau"])) > 0.2  # white noise of 0.2 rms: differences ~0.28 rms


def _recorded(tmp_path, name, *extra):
    csv = tmp_path / f"{name}.csv"
    assert main(["simulate", "--controller", "pd", "--duration", "2", "--noise", "q=1e-4,tau=0.05",
                 "--csv", str(csv), *extra]) == 0
    return csv.read_bytes(), csv.with_suffix(".json").read_bytes()


def test_the_same_seed_gives_the_same_bytes(tmp_path):
    first = _recorded(tmp_path, "a", "--sensor-seed", "4")
    assert _recorded(tmp_path, "b", "--sensor-seed", "4")[0] == first[0]
    assert _recorded(tmp_path, "c", "--sensor-seed", "5")[0] != first[0]
    assert first[1].replace(b'"a.csv"', b'"b.csv"') == (tmp_path / "b.json").read_bytes()


@pytest.mark.parametrize("argv, message", [
    (["--bits", "q=12"], "--bits needs --controller"),
    (["--controller", "pd", "--limit", "9"], "outside the motor's range"),
    (["--controller", "pd", "--reference", "nosuch"], "neither one of step, chirp, multisine, lab nor a file"),
    (["--controller", "pd", "--gains", "kq=1"], "unknown name 'kq'"),
    (["--controller", "pd", "--gains", "ki=1"], "needs the pid controller"),
    (["--controller", "pd", "--bits", "q=40"], "resolver_bits=40 is outside the allowed range"),
    (["--controller", "pd", "--bits", "theta=inf"], "must be a whole number of bits"),
    (["--controller", "pd", "--excitation", "step"], "with --controller give --reference"),
    (["--controller", "pd", "--model", "arm3.xml"], "drives one joint; the model has 3"),
])
def test_closed_loop_mistakes_are_one_line(tmp_path, capsys, argv, message):
    assert main(["simulate", *argv, "--csv", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("mjjoint: error:") and message in err
    assert not list(tmp_path.iterdir())


def test_a_reference_file_of_motor_angles_is_followed(tmp_path, model):
    t = np.arange(1500) / RATE
    q_ref = 160 * 0.1 * np.sin(2 * np.pi * 0.5 * t)
    ref = tmp_path / "ref.csv"
    ref.write_text("t,q_ref\n" + "".join(f"{a!r},{b!r}\n" for a, b in zip(t.tolist(), q_ref.tolist())))
    csv = tmp_path / "rec.csv"
    assert main(["simulate", "--controller", "pd", "--reference", str(ref), "--csv", str(csv)]) == 0
    cols = read(csv)
    assert len(cols["t"]) == len(t)  # the file's length
    assert np.sqrt(np.mean((q_ref - cols["q"]) ** 2)) < 0.05 * np.abs(q_ref).max()


def test_diagnose_reads_the_recording_unchanged(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "--controller", "pd", "--duration", "5", "--csv", "rec.csv"]) == 0
    assert main(["diagnose", "rec.csv", "--gear-ratio", "160", "--base", "coulomb_friction,linear_stiffness",
                 "--max-rounds", "1", "--candidates", "viscous_friction", "--fit-iter", "2", "--screen-iter", "1",
                 "--out", "diag"]) == 0
    assert json.loads((tmp_path / "diag" / "diagnosis.json").read_text())["verdict"]
