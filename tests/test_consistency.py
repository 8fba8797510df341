"""A recording read against the model's conventions (q after the gear, q and theta swapped, a
flipped encoder, u or tau of the other sign) is refused in one line with what it looks like and
the remedy, instead of being fitted to a model that cannot be right."""
from __future__ import annotations

import numpy as np
import pytest

from mjjoint.excitation import Multisine
from mjjoint.recordings import Recording, write_recording
from mjjoint.recordings.consistency import gear_sides_problem, torque_sign_problem
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
