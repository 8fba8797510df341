"""The README's route, as a new user takes it: the shipped arm (4 flexible segments, the seed's
full joint) with a 0.3 mrad backlash, a 10 s multisine, ``mjjoint diagnose --base minimal``.

The verdict must be a calibrated claim: never "nothing missing" and never "explained" while the
final model misses far above the recording's noise floor; every signal predicted to NRMSE 0.3 with
no parameter on a bound; the backlash named. About 19 minutes on 2 cores, so not in CI. The same
route with the gear's hysteresis or its hardening spring as the gear effect (10 minutes each).
"""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from mjjoint.cli import main

pytestmark = pytest.mark.slow
EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "default.toml"


def _route(folder: Path, edits: dict[str, str]) -> dict:
    """The README's route on ``examples/default.toml`` with ``edits`` (text replaced, once each)."""
    text = EXAMPLE.read_text()
    for old, new in edits.items():
        assert old in text, old
        text = text.replace(old, new, 1)
    model = folder / "model.toml"
    model.write_text(text)
    rec = folder / "rec.csv"
    assert main(["simulate", "--model", str(model), "--excitation", "multisine", "--duration", "10",
                 "--csv", str(rec), "--out", str(folder / "sim")]) == 0
    out = folder / "diag"
    assert main(["diagnose", str(rec), "--gear-ratio", "160", "--base", "minimal", "--out", str(out)]) == 0
    return json.loads((out / "diagnosis.json").read_text())


def _calibrated(diagnosis: dict) -> None:
    floor = diagnosis["noise_floor"]["nrmse"]
    final = diagnosis["final_fit"]["nrmse_heldout"]
    above = [s for s in floor if final[s] > diagnosis["noise_floor"]["explained_ratio"] * floor[s]]
    assert diagnosis["explained"] is (not above)
    if above:
        assert "a mismatch remains" in diagnosis["verdict"] or diagnosis["verdict"].startswith("unexplained")
        assert all(s in diagnosis["verdict"] for s in above)
    assert "nothing significant is missing" not in diagnosis["verdict"]


@pytest.fixture(scope="module")
def diagnosis(tmp_path_factory) -> dict:
    return _route(tmp_path_factory.mktemp("readme_route"), {"backlash = 0.0 ": "backlash = 0.0003"})


def test_the_verdict_does_not_claim_more_than_the_model_explains(diagnosis):
    _calibrated(diagnosis)


def test_every_signal_is_predicted_with_no_parameter_on_a_bound(diagnosis):
    assert not diagnosis["stand_ins"]
    assert all(v < 0.3 for v in diagnosis["final_fit"]["nrmse_heldout"].values()), diagnosis["final_fit"]["nrmse_heldout"]


def test_the_backlash_is_named(diagnosis):
    assert "backlash" in diagnosis["missing"]


# The same route for the gear's other effects, each alone beside the rest of the seed's joint.
HYSTERESIS_OFF = """kind = "boucwen"
mu = 0.7
a = 1.0
beta = 250.0
gamma = 250.0
n = 1.0
"""
GEAR_ROUTES = {
    "transmission_hysteresis": {"k3 = 1e8 ": "k3 = 0.0 "},
    "nonlinear_stiffness": {HYSTERESIS_OFF: 'kind = "none"\n'},
}
NOT_YET = ("measured at ccbd016 (docs/diagnosis.md, \"The README's route, measured\"): the route names the "
           "Coulomb level, the rod and the gear's spring, and the gear's {} is not reached")


@pytest.fixture(scope="module", params=list(GEAR_ROUTES))
def gear_route(request, tmp_path_factory) -> tuple[str, dict]:
    return request.param, _route(tmp_path_factory.mktemp(request.param), GEAR_ROUTES[request.param])


def test_each_gear_route_verdict_is_calibrated(gear_route):
    _calibrated(gear_route[1])


def test_each_gear_effect_is_named_on_the_flexible_arm(gear_route, request):
    effect, found = gear_route
    request.applymarker(pytest.mark.xfail(strict=True, reason=NOT_YET.format(effect)))
    assert effect in found["missing"], found["verdict"]
