"""A sensor effect is named only where no physics passes beside it: a skew of the link encoder
takes up any physics that lags (the shipped arm's hysteretic route named an 83 us skew, none
recorded, while the gear's damper, 2SEP and the bearing each passed). Named after the physics,
it is screened again against the model that holds it. Likewise a candidate whose rivals gain
alike gives way to one that, every parameter free, passes and predicts better than all of them."""
from __future__ import annotations

from types import SimpleNamespace

from mjjoint.diagnosis import loop


def _chosen(monkeypatch, costs: dict, fails: dict):
    """``loop._physics_first`` after ``loop._assess`` (faked: ``fails`` the tests each key fails)
    chose the lowest of ``costs`` against a model at held-out cost 1."""
    def assess(predictor, ref, screened, key, alternatives, options, floor_cost, max_p):
        failed = fails.get(key, [])
        return loop._Choice(key, screened[key][1], 1.0 - screened[key][0], alternatives,
                            {"p": 0.001, "windows": "10 held-out windows"}, failed, False)
    monkeypatch.setattr(loop, "_assess", assess)
    screened = {k: (c, SimpleNamespace(structure=k)) for k, c in costs.items()}
    best = min(costs, key=costs.get)
    return loop._physics_first(None, SimpleNamespace(cost_test=1.0), screened,
                               assess(None, None, screened, best, [], None, 0, 0.05), loop.DiagnoseOptions(), 0.0, 0.05)


def test_a_passing_physics_candidate_is_named_before_a_sensor_effect(monkeypatch):
    chosen = _chosen(monkeypatch, {"sensor_skew": 0.77, "transmission_damping": 0.88, "dynamic_friction": 0.89}, {})
    assert chosen.best == "transmission_damping" and not chosen.failed
    assert "named before sensor_skew" in chosen.consistency["windows"]


def test_a_sensor_effect_no_physics_rivals_is_named(monkeypatch):
    fails = {"transmission_damping": ["gain 4.0 % < 10 %"]}
    assert _chosen(monkeypatch, {"sensor_skew": 0.1, "transmission_damping": 0.96}, fails).best == "sensor_skew"
    # a physics candidate that raises the held-out cost is no rival, whatever its tests say
    assert _chosen(monkeypatch, {"sensor_skew": 0.1, "transmission_damping": 1.2}, {}).best == "sensor_skew"
    # the rule leaves a physics choice as it is
    assert _chosen(monkeypatch, {"backlash": 0.5, "sensor_skew": 0.6}, {}).best == "backlash"


def test_a_sensor_effect_the_recordings_sign_opened_keeps_its_place(monkeypatch):
    """The torque sensor's lag is screened only where the gear's recorded law gives energy back,
    which no physics does (the out-of-regime torque_filter recordings: a rod passed beside it)."""
    chosen = _chosen(monkeypatch, {"torque_skew": 0.6, "link_flexibility": 0.77}, {})
    assert chosen.best == "torque_skew"


def _freed(monkeypatch, costs: dict, fails: dict, rest: dict | None = None,
           held: tuple[str, list[str]] = ("sensor_skew", [])):
    """``loop._freed_physics`` for a sensor_skew that passed with stand-ins held (or, where
    ``held`` names rivals, ``loop._freed_rival`` for its first member tied with them), given the
    screens with every parameter free (held-out ``costs`` against a refitted model at 1, and
    ``rest`` of those left on the subset; ``fails``: the tests each key fails there)."""
    def assess(predictor, ref, screened, key, alternatives, options, floor_cost, max_p):
        return loop._Choice(key, SimpleNamespace(cost_test=screened[key][0]), 1.0 - screened[key][0], alternatives,
                            {"p": 0.001, "windows": "10 held-out windows"}, fails.get(key, []), False)
    monkeypatch.setattr(loop, "_assess", assess)
    monkeypatch.setattr(loop, "_by_gear_law", lambda *args: args[3])
    screened = {k: (c, SimpleNamespace(structure=k)) for k, c in costs.items()}
    named = loop._Choice(held[0], None, 0.2, held[1], {"p": 0.001, "windows": ""}, [], False)
    rest = {k: (c, SimpleNamespace(structure=k)) for k, c in (rest or {}).items()}
    look = loop._freed_rival if held[1] else loop._freed_physics
    return look(None, SimpleNamespace(cost_test=1.0), screened, rest, named, loop.DiagnoseOptions(), 0.0)


def test_physics_freed_of_its_stand_ins_is_named_before_a_sensor_effect(monkeypatch):
    """The hardening route's bearing: held stand-ins, its screen ended above the model; all free
    it explains more than the skew does."""
    chosen = _freed(monkeypatch, {"sensor_skew": 0.82, "load_friction": 0.43, "transmission_damping": 0.77}, {})
    assert chosen is not None and chosen.best == "load_friction"
    assert "named before sensor_skew" in chosen.consistency["windows"]


def test_a_sensor_effect_physics_does_not_match_all_free_keeps_its_place(monkeypatch):
    # a real skew explains more than any physics fitted freely
    assert _freed(monkeypatch, {"sensor_skew": 0.1, "link_flexibility": 0.6}, {}) is None
    # physics that fails its tests all free
    assert _freed(monkeypatch, {"sensor_skew": 0.8, "load_friction": 0.5}, {"load_friction": ["p > 0.025"]}) is None
    # the skew, all free, still the best that passes
    assert _freed(monkeypatch, {"sensor_skew": 0.4, "load_friction": 0.9}, {}) is None
    # the skew's screen left on the subset: its scaled estimate is the rival
    assert _freed(monkeypatch, {"load_friction": 0.43}, {}, rest={"sensor_skew": 0.3}) is None
    assert _freed(monkeypatch, {"load_friction": 0.43}, {}, rest={"sensor_skew": 0.6}).best == "load_friction"


TIED = ("input_offset", ["friction_asymmetry", "viscous_asymmetry"])


def test_a_candidate_freed_of_its_stand_ins_is_named_before_tied_rivals(monkeypatch):
    """A small servo's hysteretic gear without a torque sensor (the out-of-regime set): an input
    offset and two friction asymmetries gained alike with stand-ins held, the gear's hysteresis
    nothing; every parameter free it predicts better than each of them."""
    costs = {"input_offset": 0.87, "friction_asymmetry": 0.86, "viscous_asymmetry": 0.85,
             "transmission_hysteresis": 0.58}
    chosen = _freed(monkeypatch, costs, {}, held=TIED)
    assert chosen is not None and chosen.best == "transmission_hysteresis"
    assert "named before input_offset and its rivals" in chosen.consistency["windows"]


def test_tied_rivals_that_still_win_all_free_keep_the_choice(monkeypatch):
    # one of the tied is still the best all free: the choice stands
    assert _freed(monkeypatch, {"input_offset": 0.5, "transmission_hysteresis": 0.6}, {}, held=TIED) is None
    # another candidate is better than the named one but not than its rival left on the subset
    costs = {"input_offset": 0.8, "transmission_hysteresis": 0.6}
    assert _freed(monkeypatch, costs, {}, rest={"viscous_asymmetry": 0.55}, held=TIED) is None
    # the better one fails its tests at half the level
    fails = {"transmission_hysteresis": ["p > 0.025"]}
    assert _freed(monkeypatch, {"input_offset": 0.8, "transmission_hysteresis": 0.6}, fails, held=TIED) is None


def test_the_round_is_screened_again_all_free_on_each_trigger():
    """One escalation, three triggers: a failing best screen (inconsistent, or far from the floor)
    asks the same question again; a passing default sensor effect, or a passing candidate with
    rivals that gain alike, while the model misses its floor asks whether a term freed of its
    stand-ins does better."""
    def choice(best, failed=(), inconsistent=False, rivals=()):
        return loop._Choice(best, None, 0.1, list(rivals), {"p": 0.01, "windows": ""}, list(failed), inconsistent)
    options = loop.DiagnoseOptions()
    far = 2 * loop.FAR_FROM_FLOOR
    assert loop._escalation(choice("backlash", ["p > 0.05"]), options, far, False)[1] is loop._second_look
    assert loop._escalation(choice("backlash", ["p > 0.05"], True), options, 1.5, False)[1] is loop._second_look
    assert loop._escalation(choice("backlash", ["p > 0.05"]), options, 1.5, False) is None
    assert loop._escalation(choice("sensor_skew"), options, 1.5, False)[1] is loop._freed_physics
    assert loop._escalation(choice("sensor_skew"), options, 1.5, True) is None
    assert loop._escalation(choice("torque_skew"), options, 1.5, False) is None  # on request
    assert loop._escalation(choice("backlash"), options, far, False) is None  # passing physics
    assert loop._escalation(choice(*TIED[:1], rivals=TIED[1]), options, 1.5, False)[1] is loop._freed_rival
    assert loop._escalation(choice(*TIED[:1], rivals=TIED[1]), options, 1.5, True) is None  # explained
    assert loop._escalation(choice("backlash", ["p > 0.05"]), loop.DiagnoseOptions(free_all=False), far, False) is None
