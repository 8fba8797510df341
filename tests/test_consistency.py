"""A recording read against the model's conventions (q after the gear, q and theta swapped, a
flipped encoder, u or tau of the other sign) is refused in one line with what it looks like and
the remedy, instead of being fitted to a model that cannot be right."""
from __future__ import annotations

import numpy as np
import pytest

from mjjoint.excitation import Multisine
from mjjoint.recordings import Recording, write_recording
from mjjoint.recordings.consistency import (dead_sensor_problem, gear_sides_problem, motion_problem, scale_problem,
                                           torque_sign_problem)
from mjjoint.sim import simulate

N = 160.0  # the shipped arm's gear


@pytest.fixture(scope="module")
def trace():
    return simulate(Multisine().sample(1000, 4))


def test_a_recording_read_as_the_model_takes_it_passes(trace):
    assert gear_sides_problem(trace.q, trace.theta, N) is None
    assert torque_sign_problem(trace.u, trace.q, trace.theta, trace.tau, N, 1000.0) is None


@pytest.mark.parametrize("q, theta, remedy", [
    (lambda tr: tr.q / N, lambda tr: tr.theta, "--scales q=160"),
    (lambda tr: tr.theta, lambda tr: tr.q, "swapped"),
    (lambda tr: tr.q, lambda tr: -tr.theta, "--scales theta=-1"),
    (lambda tr: tr.q, lambda tr: tr.theta * N / 50.0, "check --gear-ratio"),
], ids=["q after the gear", "swapped", "flipped encoder", "another ratio"])
def test_angles_off_the_convention_are_named(trace, q, theta, remedy):
    assert remedy in gear_sides_problem(q(trace), theta(trace), N)


def test_a_held_link_is_not_compared(trace):
    """An output held still moves only by the deflection: nothing to compare q with."""
    rng = np.random.default_rng(0)
    assert gear_sides_problem(trace.q, 1e-5 * rng.normal(size=trace.q.size), N) is None


@pytest.mark.parametrize("flip, remedy", [("u", "--scales u=-1"), ("tau", "--scales tau=-1")])
def test_a_flipped_torque_sign_is_named(trace, flip, remedy):
    u = -trace.u if flip == "u" else trace.u
    tau = -trace.tau if flip == "tau" else trace.tau
    assert remedy in torque_sign_problem(u, trace.q, trace.theta, tau, N, 1000.0)


def test_the_cli_refuses_a_flipped_input_in_one_line_and_takes_the_remedy(trace, tmp_path, capsys):
    from mjjoint.cli import main
    rec = tmp_path / "rec.csv"
    write_recording(rec, Recording(t=trace.t, u=-trace.u, q=trace.q, theta=trace.theta, tau=trace.tau))
    args = ["fit", str(rec), "--gear-ratio", "160", "--base", "coulomb_friction", "--max-iter", "1", "--restarts", "0"]
    assert main([*args, "--out", str(tmp_path / "a")]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "u's sign looks opposite" in err[0] and "--scales u=-1" in err[0]
    assert main([*args, "--scales", "u=-1", "--out", str(tmp_path / "b")]) == 0


def test_a_joint_at_rest_or_a_sensor_that_recorded_nothing_is_refused(trace):
    """A motor that only jitters by a few encoder counts holds nothing to fit; a torque sensor or
    link encoder that reads one value while the motor moves recorded nothing. Each was fitted
    (intervals 0 .. 1e304, NRMSE 5e300 against a zero spread)."""
    count = 2 * np.pi / 2 ** 15
    jitter = count * np.round(np.random.default_rng(0).normal(0.0, 1.0, trace.q.size))
    assert "a joint at rest" in motion_problem(jitter)
    assert "a joint at rest" in motion_problem(np.zeros(trace.q.size))
    assert motion_problem(trace.q) is None
    assert "recorded nothing" in dead_sensor_problem("tau", np.zeros(trace.q.size))
    assert "--plant rotary" in dead_sensor_problem("theta", np.full(trace.q.size, 0.3))
    assert dead_sensor_problem("theta", trace.theta) is None


def test_a_signal_in_another_unit_than_read_is_refused(trace, tmp_path, capsys):
    """Every signal scaled by 1e-200 (a unit mistaken by 200 decades) divided by zero in the
    estimator's bounds (a traceback); at 1e-160 it fitted, printing a noise floor of 130 digits."""
    assert "check its unit (--scales q=FACTOR)" in scale_problem("q", 1e-200 * trace.q)
    assert "--scales u=FACTOR" in scale_problem("u", 1e-12 * trace.u)
    assert scale_problem("q", trace.q) is None and scale_problem("u", np.zeros(trace.u.size)) is None
    from mjjoint.cli import main
    path = tmp_path / "rec.csv"
    trace.to_csv(path)
    assert main(["fit", str(path), "--gear-ratio", str(N), "--scales", "q=1e-200,theta=1e-200,tau=1e-200,u=1e-200",
                 "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "q never exceeds" in err[0] and not (tmp_path / "out").exists()


@pytest.mark.parametrize("signal", ["q", "theta", "tau"])
def test_the_cli_refuses_a_flat_signal_in_one_line(trace, tmp_path, capsys, signal):
    from mjjoint.cli import main
    rec = tmp_path / "rec.csv"
    cols = dict(t=trace.t, u=trace.u, q=trace.q, theta=trace.theta, tau=trace.tau)
    cols[signal] = np.zeros_like(cols[signal])
    write_recording(rec, Recording(**cols))
    assert main(["fit", str(rec), "--gear-ratio", "160", "--max-iter", "1", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and (f"{signal} is 0 throughout" in err[0] or "a joint at rest" in err[0])


def test_a_direct_drive_with_its_input_flipped_is_named(trace, tmp_path, capsys):
    """A drive has no tau: u alone works on the rotor, and its model has no gravity to give work
    back either. Flipped, u was fitted (inertia on its bound, held-out q NRMSE 2.5)."""
    assert torque_sign_problem(trace.u, trace.q, None, None, 1.0, 1000.0) is None
    assert "--scales u=-1" in torque_sign_problem(-trace.u, trace.q, None, None, 1.0, 1000.0)
    from mjjoint.cli import main
    rec = tmp_path / "drive.csv"
    write_recording(rec, Recording(t=trace.t, u=-trace.u, q=trace.q, theta=trace.q))
    assert main(["fit", str(rec), "--plant", "rotary", "--max-iter", "1", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the input u gives back" in err[0] and "--scales u=-1" in err[0]


def test_a_direct_drive_with_a_torque_column_is_refused_in_one_line(trace, tmp_path, capsys):
    """A drive has no gear: a tau column was taken as one and its power balance refused the
    recording for a sign ("u - tau/N gives back 35 %")."""
    from mjjoint.cli import main
    rec = tmp_path / "drive.csv"
    write_recording(rec, Recording(t=trace.t, u=trace.u, q=trace.q, theta=trace.q, tau=trace.tau))
    assert main(["fit", str(rec), "--plant", "rotary", "--max-iter", "1", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no transmission torque: leave the tau column out" in err[0]
