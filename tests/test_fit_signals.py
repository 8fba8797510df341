"""--fit-signals: the cost scores the named signals only; a bad or unrecorded name fails in one line."""
from __future__ import annotations

import pytest

import mjjoint
from mjjoint.cli import main
from mjjoint.cli.errors import CliError
from mjjoint.cli.options import fit_signals
from mjjoint.problem import Inputs, make_predictor
from mjjoint.identify.windows import Measured
from mjjoint.recordings import Recording


def measured(tau: bool = True) -> Measured:
    tr = mjjoint.simulate(mjjoint.Chirp().sample(1000, 3))
    return Measured.from_recording(Recording(t=tr.t, u=tr.u, q=tr.q, theta=tr.theta, tau=tr.tau if tau else None), 160)


def test_fit_signals_choose_what_the_cost_scores():
    m = measured()
    pick = lambda text: make_predictor(m, Inputs(fit_signals=fit_signals(text)))  # noqa: E731
    assert pick(None).signals == ("q", "delta", "tau")
    assert pick("q,theta").signals == ("q", "delta")
    p = pick("tau")
    assert p.signals == ("tau",) and set(p.scale) >= {"q", "delta", "tau"}  # NRMSE still reports all
    with pytest.raises(CliError, match="choose among q, theta, tau"):
        pick("q,omega")
    with pytest.raises(ValueError, match="has no tau"):
        make_predictor(measured(tau=False), Inputs(fit_signals=fit_signals("q,tau")))


def test_a_bad_fit_signal_is_a_one_line_error(tmp_path, capsys):
    rec = tmp_path / "rec.csv"
    mjjoint.simulate(mjjoint.Chirp().sample(1000, 3)).to_csv(rec)
    assert main(["fit", str(rec), "--gear-ratio", "160", "--fit-signals", "speed", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("mjjoint: error: --fit-signals 'speed'") and "Traceback" not in err
