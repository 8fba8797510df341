"""``mjjoint diagnose`` on a fleet of recordings: rows, failure isolation, reruns, engines.

Tiny recordings (3 s of an elastic gear with a 3 ms input delay, simulated here) diagnosed
with one round and two candidates take seconds each. At 3 s the recording holds 7 held-out
windows: at 2 s, 5, and the delay's one-round screen, stuck at a sixth of the cost it can
remove, passed or failed its rank test (p 0.031 or 0.062) as a change in the last bits of the
windows' controls moved one window. Beside the good one, a fleet holds a
recording too short to name an effect (it fails inside the diagnosis) and a file that is no
recording (it fails when read); both must give failed rows while the good one is reported.
The serial run is the reference: the process pool and a Dask cluster started here must give
the same diagnosis.json bytes.
"""
from __future__ import annotations

import argparse
import contextlib
import csv
import io
import json
import shutil
from pathlib import Path

import pytest

import mjjoint.fleet.engines as engines
from mjjoint.assets import ArmSpec
from mjjoint.cli import main
from mjjoint.cli.options import NAMES, inputs_from_args
from mjjoint.excitation import Multisine
from mjjoint.fleet import resolve
from mjjoint.fleet.task import Task, failed_row, finished, input_hash
from mjjoint.identify.structure import Structure
from mjjoint.modelfile import dump_model_file
from mjjoint.problem import load_problem
from mjjoint.sim import Simulator

GEAR = 160.0
NOMINAL = ArmSpec(segments=0, gravity=0.0)
GEAR_EFFECTS = ("linear_stiffness", "transmission_damping")
GEAR_VALUES = {"linear_stiffness.k1": 1e4, "transmission_damping.d": 2.0}
FAST = ["--window-length", "0.1", "--max-rounds", "1", "--candidates", "backlash,input_delay",
        "--fit-iter", "6", "--screen-iter", "4"]


def simulate_csv(path: Path, seconds: float) -> Path:
    arm, joint = Structure.create(GEAR_EFFECTS + ("input_delay",), NOMINAL, GEAR,
                                  {**GEAR_VALUES, "input_delay.delay": 3e-3}).model_params()
    u = Multisine(amplitude=0.05, f_min=1.0, f_max=30.0, seed=1).sample(1000.0, seconds)
    return Simulator(arm=arm, joint=joint).run(u).to_csv(path)


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    d = tmp_path_factory.mktemp("fleet")
    recs = d / "recs"
    recs.mkdir()
    simulate_csv(recs / "delayed.csv", 3.0)
    simulate_csv(recs / "short.csv", 1.0)  # 2 held-out windows: too few to name an effect
    (recs / "notes.csv").write_text("t,u,q,theta\n")  # a header without data
    (recs / "README.txt").write_text("not a recording: ignored")
    arm, joint = Structure.create(GEAR_EFFECTS, NOMINAL, GEAR, GEAR_VALUES).model_params()
    model = dump_model_file(d / "gear.toml", arm, joint)
    return {"dir": d, "recs": recs, "model": model}


def diagnose(fleet, out: Path, *extra: str) -> tuple[int, str, str]:
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        code = main(["diagnose", str(fleet["recs"]), "--model", str(fleet["model"]), *FAST,
                     "--out", str(out), *extra])
    return code, stdout.getvalue(), stderr.getvalue()


def read_rows(out: Path) -> dict[str, dict]:
    with open(out / "fleet.csv", newline="") as f:
        return {r["recording"]: r for r in csv.DictReader(f)}


@pytest.fixture(scope="module")
def serial_run(fleet):
    out = fleet["dir"] / "serial"
    return out, *diagnose(fleet, out, "--workers", "1")


def test_one_row_per_recording_and_failures_stay_their_own(serial_run):
    out, code, stdout, stderr = serial_run
    assert code == 1  # some recordings failed
    rows = read_rows(out)
    assert list(rows) == ["delayed", "notes", "short"]  # README.txt is no recording
    ok = rows["delayed"]
    assert (ok["status"], ok["joint"], ok["missing"], ok["error"]) == ("ok", "1", "input_delay", "")
    for s in ("q", "tau"):
        assert float(ok[f"nrmse_after_{s}"]) < 0.5 * float(ok[f"nrmse_before_{s}"])
    assert float(ok["seconds"]) > 0
    assert rows["short"]["status"] == rows["notes"]["status"] == "failed"
    assert "held-out windows" in rows["short"]["error"] and "no data rows" in rows["notes"]["error"]
    # Each report is the single command's folder, complete; failed recordings leave none.
    assert json.loads((out / "delayed" / "diagnosis.json").read_text())["missing"] == ["input_delay"]
    assert json.loads((out / "delayed" / "run.json").read_text())["arguments"]["input_hash"]
    assert sorted(p.name for p in out.iterdir()) == sorted([".mjjoint-fleet", "delayed", "fleet.csv",
                                                            "index.html", "run.json"])
    html = (out / "index.html").read_text()
    assert 'href="delayed/index.html"' in html and "failed: " in html
    assert "3 recordings: 1 ok, 2 failed (notes, short)" in stdout
    progress = [line for line in stderr.splitlines() if line.startswith("recording ")]
    assert [p.split(":")[0] for p in progress] == [f"recording {k} of 3" for k in (1, 2, 3)]
    assert "left" in progress[0] and "left" not in progress[-1]


def test_rerun_keeps_finished_reports_and_retries_failed(fleet, serial_run, monkeypatch):
    out = serial_run[0]
    before = (out / "delayed" / "run.json").stat().st_mtime_ns
    code, stdout, stderr = diagnose(fleet, out, "--workers", "1")
    assert code == 1
    assert "diagnosing 2 of 3 recordings" in stderr and "1 up to date" in stderr
    assert (out / "delayed" / "run.json").stat().st_mtime_ns == before
    rows = read_rows(out)
    assert (rows["delayed"]["status"], rows["delayed"]["reused"]) == ("ok", "1")
    assert rows["short"]["status"] == "failed"
    assert "(1 from an earlier run)" in stdout
    # A moved fleet folder is still up to date; --force hands every recording to the engine again.
    moved = fleet["dir"] / "moved"
    shutil.copytree(out, moved)
    for extra, expected in (((), ["notes", "short"]), (("--force",), ["delayed", "notes", "short"])):
        ran = []
        monkeypatch.setattr(engines, "run_task", lambda t: ran.append(t.name) or [failed_row(t, "stopped", 0.0)])
        diagnose(fleet, moved, "--workers", "1", *extra)
        assert ran == expected


def test_finished_needs_the_same_inputs_and_options(fleet, serial_run, tmp_path):
    out = serial_run[0]
    run = json.loads((out / "delayed" / "run.json").read_text())
    arguments = {k: v for k, v in run["arguments"].items() if k not in ("out", "input_hash")}
    task = Task("delayed", arguments, out / "delayed", input_hash(arguments))
    assert finished(task)
    assert not finished(Task("delayed", arguments, out / "delayed", input_hash({**arguments, "seed": 1})))
    changed = tmp_path / "delayed.csv"
    (recorded,) = arguments["recording"]  # run.json lists the command line's recordings
    changed.write_bytes(Path(recorded).read_bytes().replace(b"\n", b"\r\n", 1))
    assert input_hash({**arguments, "recording": [str(changed)]}) != task.input_hash
    # where the data lies and how the work is spread do not count
    assert input_hash({**arguments, "workers": 4, "recording": [str(Path(recorded))]}) == task.input_hash


def same_results(out: Path, reference: Path) -> None:
    """The same diagnosis.json bytes, and the same rows but for wall times (and reuse: the reference was rerun)."""
    assert (out / "delayed" / "diagnosis.json").read_bytes() == (reference / "delayed" / "diagnosis.json").read_bytes()
    rows = [{n: {k: v for k, v in r.items() if k not in ("seconds", "reused")} for n, r in read_rows(o).items()}
            for o in (out, reference)]
    assert rows[0] == rows[1]


def test_process_pool_gives_the_serial_bytes(fleet, serial_run):
    out = fleet["dir"] / "pool"
    code, _, stderr = diagnose(fleet, out, "--workers", "2")
    assert code == 1 and "on 2 local processes" in stderr
    same_results(out, serial_run[0])


def dask_run(fleet, serial_run, processes: bool) -> None:
    distributed = pytest.importorskip("distributed", reason="dask.distributed absent: pip install 'mjjoint[fleet]'")
    out = fleet["dir"] / f"dask-{processes}"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=processes,
                                  dashboard_address=None) as cluster:
        code, _, stderr = diagnose(fleet, out, "--scheduler", cluster.scheduler_address)
    assert code == 1 and f"on the Dask cluster at {cluster.scheduler_address}" in stderr
    same_results(out, serial_run[0])


def test_dask_cluster_in_process_gives_the_serial_bytes(fleet, serial_run):
    dask_run(fleet, serial_run, processes=False)


@pytest.mark.slow  # two worker processes importing mjjoint: a minute on a loaded 2-core machine
def test_dask_cluster_of_processes_gives_the_serial_bytes(fleet, serial_run):
    dask_run(fleet, serial_run, processes=True)


# ---- inputs: folders, globs, manifests ----------------------------------------------------------

def test_manifests_give_paths_relative_to_them_and_per_recording_options(fleet, tmp_path):
    recs = fleet["recs"]
    toml = recs / "fleet.toml"
    toml.write_text('[[recording]]\npath = "delayed.csv"\nname = "robot-a"\ngear_ratio = 100\n\n'
                    '[[recording]]\npath = "short.csv"\nscales = "u=2"\n')
    table = recs / "fleet-manifest.csv"
    table.write_text("recording,name,gear_ratio,scales\ndelayed.csv,robot-a,100,\nshort.csv,,,u=2\n")
    for manifest in (toml, table):
        entries = resolve(manifest)
        assert [(e.name, e.path, e.options) for e in entries] == [
            ("robot-a", recs / "delayed.csv", {"gear_ratio": "100"}),
            ("short", recs / "short.csv", {"scales": "u=2"})]
    toml.unlink()
    table.unlink()


def test_a_manifest_row_replaces_the_command_line_options(fleet, tmp_path, monkeypatch):
    """The row's gear ratio and columns reach the recording's problem (read as the worker reads it)."""
    seen = []
    monkeypatch.setattr(engines, "run_task", lambda t: seen.append(t) or [failed_row(t, "stopped", 0.0)])
    renamed = tmp_path / "renamed.csv"
    text = (fleet["recs"] / "delayed.csv").read_text()
    renamed.write_text(text.replace("t,u,q,theta", "time,u,q,theta", 1))
    manifest = tmp_path / "robots.csv"
    manifest.write_text("recording,gear_ratio,columns\nrenamed.csv,,t=time\n" f"{fleet['recs'] / 'delayed.csv'},100,\n")
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main(["diagnose", str(manifest), "--base", "linear_stiffness", "--gear-ratio", str(GEAR), *FAST,
                     "--out", str(tmp_path / "out"), "--workers", "1"]) == 1
    problems = {t.name: load_problem(t.arguments["recording"], inputs_from_args(argparse.Namespace(**t.arguments)), NAMES)
                for t in seen}
    assert problems["renamed"].base.gear_ratio == GEAR and problems["delayed"].base.gear_ratio == 100.0
    assert problems["renamed"].predictor.m.t[-1] == pytest.approx(3.0, abs=2e-3)


@pytest.mark.parametrize("files, error", [
    ({"robots.toml": '[[recording]]\npath = "a.csv"\ngear = 3\n'}, "unknown key 'gear' (allowed: path, name, gear_ratio"),
    ({"robots.toml": '[[recording]]\nname = "a"\n'}, "no 'path'"),
    ({"robots.csv": "recording,gear_ratio\na.csv,fast\n"}, "recording a: gear_ratio 'fast' is not a number"),
    ({"robots.csv": "recording,plant\na.csv,boat\n"}, "'boat' is not one of arm, linear, rotary"),
    ({"robots.toml": '[[recording]]\npath = "x/a.csv"\n[[recording]]\npath = "y/a.mat"\n'}, "would both report into a/"),
    ({"robots.toml": '[[recording]]\npath = "a.csv"\nname = "../up"\n'}, "cannot be a folder name"),
    ({"empty/x.txt": ""}, "holds no recording"),
    # a value the row's own run would refuse, refused before any recording is diagnosed
    ({"robots.csv": "recording,gear_ratio\na.csv,-1\n"}, "recording a: --gear-ratio -1 must be positive and finite"),
    ({"robots.csv": "recording,gear_ratio\na.csv,nan\n"}, "--gear-ratio nan must be positive"),
    ({"robots.toml": '[[recording]]\npath = "a.csv"\nbase = "bogus"\n'}, "recording a: --base: unknown effect 'bogus'"),
    ({"robots.toml": "recording = [1, 2]\n"}, "a recording's entry is a table of keys, not 1"),
    ({"robots.toml": "recording = [" + "9" * 5000 + "]\n"}, "not valid TOML (Exceeds the limit"),
    ({"robots.toml": '[[recording]]\npath = ["a.csv"]\n'}, "'path' and 'name' are text"),
    ({"robots.toml": '[[recording]]\npath = "a.csv"\nname = "a\\u0000b"\n'}, "cannot be a folder name"),
    ({"robots.csv": "recording,gear_ratio\na.csv,160,3\n"}, "line 2: more cells than the header names"),
    ({"robots.csv": "recording,gear_ratio,gear_ratio\na.csv,160,100\n"}, "names each column once"),
])
def test_bad_fleets_are_refused_in_one_line_before_any_work(tmp_path, capsys, files, error):
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(exist_ok=True)
        (tmp_path / name).write_text(text)
    spec = tmp_path / ("empty" if "empty/x.txt" in files else next(iter(files)))
    assert main(["diagnose", str(spec), "--gear-ratio", "160", "--out", str(tmp_path / "out"), "--workers", "1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("mjjoint: error: ") and err.count("\n") == 1 and error in err
    assert not (tmp_path / "out").exists()


def test_fleet_options_and_folders_are_checked(fleet, tmp_path, capsys):
    rec = str(fleet["recs"] / "delayed.csv")
    cases = [
        (["diagnose", rec, "--gear-ratio", "160", "--workers", "2"], "--workers: for a folder, glob or manifest"),
        (["diagnose", rec, "--gear-ratio", "160", "--workers", "0"], "--workers: for a folder, glob or manifest"),
        (["diagnose", str(fleet["recs"]), "--gear-ratio", "160", "--workers", "0"], "--workers 0 must be at least 1"),
        (["diagnose", str(fleet["recs"]), "--gear-ratio", "160", "--workers", "2", "--scheduler", "tcp://x:1"],
         "with --scheduler the cluster's workers do the work"),
    ]
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "thesis.tex").write_text("")
    cases.append((["diagnose", f"{fleet['recs']}/d*.csv", "--gear-ratio", "160", "--out", str(foreign)],
                  "is not an mjjoint fleet output"))
    for argv, error in cases:
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.startswith("mjjoint: error: ") and error in err, err
    assert sorted(p.name for p in foreign.iterdir()) == ["thesis.tex"]


def test_a_multi_joint_recording_gives_a_row_per_joint(fleet, serial_run, tmp_path):
    """Joint 2 of a two-joint log (both joints the delayed gear) is reported as the single recording."""
    with open(fleet["recs"] / "delayed.csv", newline="") as f:
        table = list(csv.reader(f))
    head = table[0][1:]
    with open(tmp_path / "arm.csv", "w", newline="") as f:
        csv.writer(f).writerows([["t", *(f"{c}{j}" for j in (1, 2) for c in head)]]
                                + [[r[0], *r[1:], *r[1:]] for r in table[1:]])
    (tmp_path / "robots.toml").write_text('[[recording]]\npath = "arm.csv"\njoint = [2]\n')
    out = tmp_path / "out"
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main(["diagnose", str(tmp_path / "robots.toml"), "--model", str(fleet["model"]), *FAST,
                     "--out", str(out), "--workers", "1"]) == 0
    (row,) = read_rows(out).values()
    assert (row["recording"], row["joint"], row["status"], row["missing"]) == ("arm", "2", "ok", "input_delay")
    assert row["report"] == "arm/joint2/index.html" and (out / row["report"]).is_file()
    assert (out / "arm" / "joint2" / "diagnosis.json").read_bytes() == \
        (serial_run[0] / "delayed" / "diagnosis.json").read_bytes()
