"""Report pieces on synthetic windows: evidence figures, cross-correlation, output folders, JSON, text."""
from __future__ import annotations

import json

import numpy as np
import pytest
from rerun.chunk import RrdReader

from mjjoint.identify.effects import EFFECTS
from mjjoint.report.compare import Comparison, worst_signal
from mjjoint.report.evidence import cross_correlation, evidence_signal, peak_shift, plot_evidence
from mjjoint.report.html import diagnosis_page
from mjjoint.report.output import MARKER, OutputDir, jsonable, write_json
from mjjoint.report.plots import plot_residual_time, plot_windows, worst_windows
from mjjoint.report.rrd import write_rrd
from mjjoint.report.summary import diagnosis_summary, nrmse_lines, parameter_table

PNG = b"\x89PNG\r\n\x1a\n"
RATE = 1000.0


def sines(t: np.ndarray) -> np.ndarray:
    return np.sin(2 * np.pi * 7 * t) + 0.6 * np.sin(2 * np.pi * 13 * t + 1) + 0.3 * np.sin(2 * np.pi * 29 * t + 2)


def comparison(windows: int = 8, n: int = 200, tau: bool = True, delay: float = 0.0) -> Comparison:
    """A joint whose 'before' model misses a delay and a tau offset; 'after' is exact."""
    t = (np.arange(windows)[:, None] * n + np.arange(n)[None, :]) / RATE
    q = 50 * sines(t - delay)
    measured = {"q": q, "theta": q / 160, "delta": 1e-3 * sines(t - delay), "tau": 10 * sines(t - delay)}
    after = {k: v.copy() for k, v in measured.items()}
    before = {"q": 50 * sines(t), "theta": 50 * sines(t) / 160, "delta": 1e-3 * sines(t),
              "tau": 10 * sines(t) + 0.5}
    if not tau:
        measured.pop("tau")
    cost = np.arange(n) >= 20
    held = np.zeros(windows, bool)
    held[[w for w in (1, 4, 6) if w < windows]] = True
    return Comparison(t=t, measured=measured, predicted={"before": before, "after": after},
                      conditions={"q": q, "theta": q / 160, "qd": np.gradient(q, axis=1) * RATE,
                                  "thetad": np.gradient(q / 160, axis=1) * RATE},
                      heldout=held, cost=cost, owned=np.ones(t.shape, bool))


@pytest.mark.parametrize("true_shift", [0.0, 2.4, -3.7])
def test_cross_correlation_peak_recovers_a_subsample_shift(true_shift):
    cmp = comparison(delay=true_shift / RATE)
    shifts, corr = cross_correlation(cmp.measured["tau"], cmp.predicted["before"]["tau"], 50)
    assert shifts[0] == -50 and shifts[-1] == 50
    assert peak_shift(shifts, corr) == pytest.approx(true_shift, abs=0.15)
    assert np.nanmax(corr) <= 1.0 + 1e-12


def test_every_effect_has_an_evidence_figure(tmp_path):
    cmp = comparison()
    where = {"signal": "tau", "signals": {}}
    for effect in EFFECTS:
        path = plot_evidence(effect, cmp, "before", "after", where, {"input_delay.delay": 2e-3},
                             tmp_path / f"{effect}.png", "tau")
        assert path.read_bytes()[:8] == PNG, effect


def test_loops_without_a_torque_recording_show_the_models(tmp_path):
    cmp = comparison(tau=False)
    assert "tau" not in cmp.signals
    path = plot_evidence("backlash", cmp, "before", "after", {}, {}, tmp_path / "b.png", "delta")
    assert path.read_bytes()[:8] == PNG


def test_evidence_signal_is_the_one_whose_conditions_point_at_the_effect():
    cond = lambda name, score, sig=True: {"name": name, "score": score, "significant": sig}  # noqa: E731
    where = {"signals": {"q": {"conditions": [cond("lag", 0.2), cond("resonance", 0.9)]},
                         "tau": {"conditions": [cond("lag", 0.6)]},
                         "delta": {"conditions": [cond("lag", 0.9, sig=False)]}}}
    assert evidence_signal("input_delay", where, ("q", "delta", "tau"), "q") == "tau"
    assert evidence_signal("input_delay", where, ("q", "delta"), "delta") == "q"  # tau not recorded
    assert evidence_signal("gravity", where, ("q", "delta", "tau"), "delta") == "delta"  # nothing points at it


def test_worst_windows_are_held_out_and_worst_first(tmp_path):
    cmp = comparison()
    cmp.predicted["before"]["tau"][4, 50:] += 3.0  # window 4 (held out) goes far off
    cmp.predicted["before"]["tau"][2, 50:] += 9.0  # window 2 is worse, but used in training
    wins = worst_windows(cmp, "tau", "before", 2)
    assert 4 in wins and set(wins) <= {1, 4, 6}
    assert plot_windows(cmp, "tau", ["before", "after"], tmp_path / "w.png").read_bytes()[:8] == PNG
    located = [[0.2, 0.5, 0.4]]
    assert plot_residual_time(cmp, "tau", ["before", "after"], tmp_path / "r.png", located).read_bytes()[:8] == PNG


def test_worst_signal_treats_nan_as_worst():
    assert worst_signal({"q": 0.1, "delta": 0.5, "tau": 0.3}, ("q", "delta", "tau")) == "delta"
    assert worst_signal({"q": float("nan"), "delta": 0.5}, ("q", "delta")) == "q"
    assert worst_signal({"theta": 9.0, "tau": 0.3}, ("q", "tau")) == "tau"


def _scalars(path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """entity -> (time [ns], values) of every scalar series in an .rrd."""
    got = {}
    for chunk in RrdReader(path).stream():
        b = chunk.to_record_batch()
        if "Scalars:scalars" in b.schema.names:
            got[chunk.entity_path] = (b.column("sim_time").cast("int64").to_numpy(),
                                      np.array([v[0] for v in b.column("Scalars:scalars").to_pylist()]))
    return got


def test_rrd_series_equal_the_windows_in_time_order(tmp_path):
    cmp = comparison(windows=6, n=50)
    path = write_rrd(tmp_path / "t.rrd", cmp, ["before", "after"], "test")
    got = _scalars(path)
    t_ns, tau = got["/before/tau"]
    assert np.array_equal(t_ns, np.round(cmp.t.ravel() * 1e9).astype(np.int64))
    assert np.allclose(tau, cmp.predicted["before"]["tau"].ravel())
    assert np.array_equal(got["/windows/heldout"][1], np.repeat(cmp.heldout.astype(float), 50))
    assert RrdReader(path).blueprints()


def test_rrd_residuals_and_located_windows(tmp_path):
    cmp = comparison(windows=6, n=50)
    t = cmp.t.ravel()
    window = [t[60], t[140], 0.7]
    got = _scalars(write_rrd(tmp_path / "t.rrd", cmp, ["before", "after"], "test", {"tau": [window]}))
    for label in ("before", "after"):
        assert np.allclose(got[f"/residual/{label}/tau"][1], cmp.residual(label, "tau").ravel())
    mark, sample = got["/located/tau"][1], np.arange(len(t))
    inside = (sample >= 60) & (sample <= 140)
    assert np.all(mark[inside] == np.abs(cmp.residual("before", "tau")).max()) and np.all(mark[~inside] == 0)
    assert not np.any(got["/located/q"][1])  # nothing located in q


def test_staged_output_appears_only_when_complete(tmp_path):
    out = OutputDir(tmp_path / "res")
    with out.staged() as d:
        assert d.name.startswith("res.partial-") and not out.path.exists()
        (d / "a.txt").write_text("1")
        (d / MARKER).write_text("{}")
    assert (out.path / "a.txt").read_text() == "1" and not out.partial.exists()
    # A failing second run keeps the first result untouched and leaves no partial folder.
    with pytest.raises(KeyboardInterrupt), out.staged() as d:
        (d / "a.txt").write_text("2")
        raise KeyboardInterrupt
    assert (out.path / "a.txt").read_text() == "1" and sorted(p.name for p in tmp_path.iterdir()) == ["res"]
    # A complete second run replaces it.
    with out.staged() as d:
        (d / "b.txt").write_text("3")
        (d / MARKER).write_text("{}")
    assert sorted(p.name for p in out.path.iterdir()) == sorted([MARKER, "b.txt"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res"]


def test_output_without_its_marker_is_a_bug_not_a_result(tmp_path):
    out = OutputDir(tmp_path / "res")
    with pytest.raises(RuntimeError, match=MARKER), out.staged() as d:
        (d / "a.txt").write_text("1")
    assert not any(tmp_path.iterdir())


def test_foreign_or_file_targets_are_refused(tmp_path):
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep")
    with pytest.raises(ValueError, match="not an mjjoint output"):
        OutputDir(tmp_path / "mine").check()
    (tmp_path / "file").write_text("x")
    with pytest.raises(ValueError, match="not a folder"):
        OutputDir(tmp_path / "file").check()
    (tmp_path / "empty").mkdir()
    OutputDir(tmp_path / "empty").check()  # an empty folder may be used
    with pytest.raises(ValueError, match="give a folder name"):
        OutputDir(".")  # the working directory cannot be renamed into place


def test_json_is_strict_plain_and_reproducible(tmp_path):
    data = {"a": np.float64(0.1), "b": np.arange(3), "c": (np.int32(2), float("nan")), "d": {1: np.bool_(True)},
            "e": float("inf")}
    assert jsonable(data) == {"a": 0.1, "b": [0, 1, 2], "c": [2, None], "d": {"1": True}, "e": None}
    p1, p2 = write_json(tmp_path / "1.json", data), write_json(tmp_path / "2.json", dict(data))
    assert p1.read_bytes() == p2.read_bytes()
    assert json.loads(p1.read_text(), parse_constant=lambda c: pytest.fail(f"non-strict {c}"))["c"] == [2, None]


def test_parameter_table_flags_warned_parameters_and_nrmse_shows_the_change():
    text = parameter_table({"inertia.motor": 5e-5, "backlash.width": 3e-4},
                           {"inertia.motor": (4.9e-5, 5.1e-5), "backlash.width": (1e-6, 5e-2)},
                           ["backlash.width = 0.0003 is poorly identifiable from this recording"])
    lines = text.splitlines()
    assert lines[1].startswith("  inertia.motor") and "kg m^2" in lines[1]
    assert lines[2].startswith("! backlash.width") and "[1e-06, 0.05]" in lines[2]
    assert "poorly identifiable" in lines[-1]
    assert nrmse_lines({"q": 0.2, "tau": 0.4}, {"q": 0.1, "tau": 0.5}) == [
        "  q      0.2000 -> 0.1000  (-50 %)", "  tau    0.4000 -> 0.5000  (+25 %)"]


def test_html_escapes_text_and_puts_the_verdict_first():
    diag = {"verdict": "nothing <significant> is missing", "steps": [],
            "initial_fit": {"nrmse_heldout": {"q": 0.1}}, "final_fit": {"nrmse_heldout": {"q": 0.1}},
            "final_model": {"effects": [], "parameters": {"inertia.motor": 5e-5}, "intervals_95": {}, "warnings": []}}
    html = diagnosis_page(diag, {"windows": "w.png", "residual": "r.png", "steps": []}, "rec<1>.csv",
                          {"files": ["w.png"], "rollouts_full_length": 3.0, "seconds": 1.0})
    assert "nothing &lt;significant&gt; is missing" in html.split("<h2>")[0]
    assert "rec&lt;1&gt;.csv" in html and "<significant>" not in html
    assert '<img src="w.png"' in html and '<img src="r.png"' in html


def test_a_diagnosis_without_a_torque_recording_draws_its_loop_evidence(tmp_path):
    """compare() keeps each model's predicted tau when the recording has none: the tau-delta
    evidence of a gear effect named on such a recording (KUKA KR300 axis 1: transmission
    hysteresis) is drawn from the models, not a KeyError."""
    from mjjoint import Chirp, Simulator
    from mjjoint.benchmark.cases import BASE, GEAR_RATIO, NOMINAL
    from mjjoint.identify.structure import Structure
    from mjjoint.identify.windows import Measured, Predictor, WindowDesign
    from mjjoint.recordings import Recording
    from mjjoint.report.compare import compare
    u = Chirp().sample(1000.0, 3.0)
    tr = Simulator().run(u)
    rec = Recording(t=tr.t, u=u, q=tr.q, theta=tr.theta, tau=None, gear_ratio=GEAR_RATIO)
    base = Structure.create(BASE, NOMINAL, GEAR_RATIO)
    cmp = compare(Predictor(Measured.from_recording(rec, GEAR_RATIO), WindowDesign(length=0.25)),
                  {"before": base, "after": base.with_effect("transmission_hysteresis", {}, {})})
    assert "tau" not in cmp.signals and all("tau" in p for p in cmp.predicted.values())
    path = plot_evidence("transmission_hysteresis", cmp, "before", "after", {"signals": {}}, {},
                         tmp_path / "loops.png", "delta")
    assert path.read_bytes()[:8] == PNG


@pytest.mark.parametrize("joint_type, position, speed, force", [("slide", "m", "m/s", "N"),
                                                                ("hinge", "rad", "rad/s", "N m")])
def test_figures_name_the_plants_own_units(joint_type, position, speed, force):
    """A linear direct drive's report shows m, m/s and N where a joint's shows rad, rad/s, N m."""
    import dataclasses

    from mjjoint.assets.drive import DriveSpec
    from mjjoint.identify.structure import Structure
    from mjjoint.report.compare import plant_units
    from mjjoint.report.evidence import condition_axis
    from mjjoint.report.plots import axis_label

    plant = dataclasses.replace(DriveSpec(), joint_type=joint_type)
    units = plant_units(Structure.create(("coulomb_friction",), plant, 1.0).nominal)
    cmp = comparison()
    cmp.plant_units = units
    assert axis_label(cmp, "q").endswith(f"[{position}]") and axis_label(cmp, "tau").endswith(f"[{force}]")
    assert condition_axis("coulomb_friction", cmp)[1] == f"motor velocity q' [{speed}]"
    assert comparison().display("q") == ("rad", 1.0)  # a geared joint keeps the catalogue's


@pytest.mark.parametrize("left", [[], [12.5, 17.75]])
def test_the_summary_names_the_held_out_windows_left_out_of_every_score(left):
    fit = {"nrmse_heldout": {"q": 0.1, "tau": 0.2}}
    diag = {"verdict": "v", "steps": [], "initial_fit": fit, "final_fit": fit, "explained": False,
            "final_model": {"warnings": []}, "budget": {"rollouts_full_length": 3.0}, "heldout_left_out_s": left}
    lines = [line for line in diagnosis_summary(diag, 1.0).splitlines() if "left out of every score" in line]
    assert lines == ([] if not left else ["held-out windows at 12.5, 17.75 s left out of every score: the recording "
                                          "leaves their start at rest open"])
