"""The README's route, as a new user takes it: the shipped arm (4 flexible segments, the seed's
full joint) with a 0.3 mrad backlash, a 10 s multisine, ``mjjoint diagnose --base minimal``.

The verdict must be a calibrated claim: never "nothing missing" and never "explained" while the
final model misses far above the recording's noise floor; every signal predicted to NRMSE 0.3 with
no parameter on a bound; the backlash named. About 17 minutes on one core, in CI: it is the first
thing a new user runs. The same route with the gear's hysteresis or its hardening spring as the
gear effect, the multisine driving the gear to its rated deflection, is slow (5 to 10 minutes each);
so is the route's recording diagnosed from the default base (every term of the seed's joint on a
rigid link), about 15 minutes.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mjjoint.cli import main
from mjjoint.diagnosis.gear_law import gear_torque
from mjjoint.identify.effects import EFFECTS
from mjjoint.modelfile import load_model_file

pytestmark = pytest.mark.long(17)
EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "default.toml"
# An effect is visible on a route where at least this share of the gear's torque along the
# recorded deflection is what no linear spring explains (``unexplained_share``).
VISIBLE = 0.05


def _route(folder: Path, edits: dict[str, str], amplitude: float | None = None,
           base: tuple[str, ...] = ("--base", "minimal"), seed: int | None = None) -> tuple[dict, float]:
    """The README's route on ``examples/default.toml`` with ``edits`` (text replaced, once each),
    the multisine's peak ``amplitude`` [N m] and phases' ``seed`` (their defaults if None) and the
    diagnosis's ``base`` options: (the diagnosis, the share of the true gear torque no linear
    spring explains on the recording)."""
    text = EXAMPLE.read_text()
    for old, new in edits.items():
        assert old in text, old
        text = text.replace(old, new, 1)
    model = folder / "model.toml"
    model.write_text(text)
    rec = folder / "rec.csv"
    excitation = ["--excitation", "multisine", "--duration", "10"]
    excitation += [] if amplitude is None else ["--amplitude", str(amplitude)]
    excitation += [] if seed is None else ["--seed", str(seed)]
    assert main(["simulate", "--model", str(model), *excitation, "--csv", str(rec), "--out", str(folder / "sim")]) == 0
    out = folder / "diag"
    assert main(["diagnose", str(rec), "--gear-ratio", "160", *base, "--out", str(out)]) == 0
    return json.loads((out / "diagnosis.json").read_text()), unexplained_share(model, rec)


def unexplained_share(model: Path, rec: Path) -> float:
    """rms of the true gear torque's part that the best linear spring K delta leaves, over the rms
    of that torque, along the deflection recorded in ``rec`` (no damping: what a gear effect adds
    to a linear gear)."""
    joint = load_model_file(model).joint
    data = np.genfromtxt(rec, delimiter=",", names=True)
    delta = data["q"] / joint.transmission.gear_ratio - data["theta"]
    # the plugin's own Bouc-Wen state along the path, driven past the play as in the plant
    n = len(delta)
    torque = gear_torque(joint, delta, np.zeros(n), np.arange(n), [(0, n)])
    k = delta @ torque / (delta @ delta)
    return float(np.sqrt(np.mean((torque - k * delta) ** 2) / np.mean(torque ** 2)))


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
def route(tmp_path_factory) -> tuple[dict, float]:
    return _route(tmp_path_factory.mktemp("readme_route"), {"backlash = 0.0 ": "backlash = 0.0003"})


@pytest.fixture(scope="module")
def diagnosis(route) -> dict:
    return route[0]


def test_the_play_is_visible_on_the_route(route):
    assert route[1] > VISIBLE, route[1]


def test_the_verdict_does_not_claim_more_than_the_model_explains(diagnosis):
    _calibrated(diagnosis)


def test_every_signal_is_predicted_with_no_parameter_on_a_bound(diagnosis):
    assert not diagnosis["stand_ins"]
    assert all(v < 0.3 for v in diagnosis["final_fit"]["nrmse_heldout"].values()), diagnosis["final_fit"]["nrmse_heldout"]


def test_the_backlash_is_named(diagnosis):
    assert "backlash" in diagnosis["missing"]


def _sensor_effects(diagnosis: dict) -> list[str]:
    """The sensor effects ``diagnosis`` names. The simulated recorder reads every signal at its
    instant: each one is a false addition, standing in for physics not yet named."""
    return [e for e in diagnosis["missing"] if EFFECTS[e].site == "sensor"]


def test_the_route_names_no_sensor_effect(diagnosis):
    """A link encoder skew passed the acceptance rule last on this route (-14 %, p 0.0488) with
    its checked 95 % interval holding zero: refused as a stand-in (``revise.resolved``)."""
    assert not _sensor_effects(diagnosis), diagnosis["verdict"]


@pytest.mark.slow
def test_a_base_bent_by_the_rod_it_lacks_is_screened_again_free(tmp_path):
    """The route's recording from the default base: every term of the seed's joint on a rigid
    link. Fitted rigid, a base can bend its terms toward the rod it lacks (gravity and the tip
    mass far below the truth), and held there the rod's screen gains nothing; a model far above
    its floor is screened again with every parameter free, and a bent refit is fitted again
    from the recording's start (docs/diagnosis.md, "The README's route, measured"). The rod is
    named, with nothing false beside it, and every signal is predicted within 0.3 with nothing
    on a bound."""
    diagnosis, _ = _route(tmp_path, {"backlash = 0.0 ": "backlash = 0.0003"}, base=())
    assert "link_flexibility" in diagnosis["missing"], diagnosis["verdict"]
    assert set(diagnosis["missing"]) <= {"link_flexibility", "backlash"}, diagnosis["verdict"]
    assert not diagnosis["stand_ins"], diagnosis["stand_ins"]
    final = diagnosis["final_fit"]["nrmse_heldout"]
    assert all(v < 0.3 for v in final.values()), final
    _calibrated(diagnosis)


# The route is not one recording: its multisine's phases drawn from another seed (about 9 minutes
# on one core), and a wider play (about 10), where 2SEP is named because its term holds the fit
# it found: switched off there it loses little, but the model refitted without it loses the gain
# (``diagnosis.revise.stand_in``). Each: (the play [rad], the multisine's seed, names beside it).
VARIANTS = {"other phases": (0.0003, 1, set()), "wider play": (0.0005, None, {"dynamic_friction"})}


@pytest.mark.slow
@pytest.mark.parametrize("variant", list(VARIANTS))
def test_a_variant_of_the_route_names_the_play_within_its_interval_and_predicts_every_signal(variant, tmp_path):
    width, seed, beside = VARIANTS[variant]
    diagnosis, share = _route(tmp_path, {"backlash = 0.0 ": f"backlash = {width}"}, seed=seed)
    assert share > VISIBLE, share
    assert {"backlash", *beside} <= set(diagnosis["missing"]), diagnosis["verdict"]
    lo, hi = diagnosis["final_model"]["intervals_95"]["backlash.width"]
    assert lo <= width <= hi, (lo, hi)
    assert not [e for e in diagnosis["missing"] if EFFECTS[e].site == "sensor"], diagnosis["verdict"]
    assert not diagnosis["stand_ins"], diagnosis["stand_ins"]
    final = diagnosis["final_fit"]["nrmse_heldout"]
    assert all(v < 0.3 for v in final.values()), final
    _calibrated(diagnosis)


# The same route for the gear's other effects, each alone beside the rest of the seed's joint at
# its shipped values. The README's multisine (0.25 N m peak) bends the gear by 1.5 mrad at most,
# where the hardening spring adds 0.4 % to a linear gear's torque and the hysteresis 4 %, against
# the play's 9 %: neither is there to be named. At 0.75 N m the gear reaches its rated 5 mrad, and
# they add 5 % and 11 % (``test_each_gear_effect_is_visible_on_its_route``).
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
RATED = 0.75  # [N m] the multisine's peak that drives the gear to its rated deflection


@pytest.fixture(scope="module", params=list(GEAR_ROUTES))
def gear_route(request, tmp_path_factory) -> tuple[str, dict, float]:
    return request.param, *_route(tmp_path_factory.mktemp(request.param), GEAR_ROUTES[request.param], RATED)


@pytest.mark.slow
def test_each_gear_effect_is_visible_on_its_route(gear_route):
    assert gear_route[2] > VISIBLE, (gear_route[0], gear_route[2])


@pytest.mark.slow
def test_each_gear_route_verdict_is_calibrated(gear_route):
    _calibrated(gear_route[1])


@pytest.mark.slow
def test_each_gear_effect_is_named_on_the_flexible_arm(gear_route):
    effect, found, _ = gear_route
    assert effect in found["missing"], found["verdict"]


@pytest.mark.slow
def test_each_gear_route_names_no_sensor_effect(gear_route):
    assert not _sensor_effects(gear_route[1]), gear_route[1]["verdict"]
