"""scripts/bench_fit.py runs end to end at smoke sizes and reports finite, sane numbers.

Not a timing test (speed is judged by the script's own ratios, on a quiet machine): the default
run checks that every section runs and that its fit results can be physical; the bounds on its
wall-clock ratios, which a loaded machine can break, run only with ``-m slow``.
"""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "bench_fit.py"


@pytest.fixture(scope="module")
def report(tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("bench") / "bench.json"
    proc = subprocess.run([sys.executable, str(SCRIPT), "--quick", "--json", str(out)],
                          check=False, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    return json.loads(out.read_text())


@pytest.mark.slow
def test_quick_run_timings_are_plausible(report):
    for timer in ("rollout", "mj_step loop"):
        step = report["per_step"][timer]
        assert step["plugin_us"] > 0 and step["bare_us"] > 0
        # The plugin adds work to the same MJCF: it cannot be much cheaper than the bare arm.
        assert 0.8 < step["ratio"] < 20
    par = report["parallel"]
    for what in ("rollout", "predict"):
        assert 0 < par[what]["efficiency"] <= 1.5


def test_quick_run_reports_sane_numbers(report):
    r = report
    sysid = r["sysid"]
    if sysid["available"]:
        row = sysid["exact"]
        assert row["ours_seconds"] > 0 and row["sysid_seconds"] > 0 and row["time_ratio"] > 0
        for who in ("ours", "sysid", "truth"):
            assert math.isfinite(row[who]["heldout_cost"]) and row[who]["heldout_cost"] >= 0
            assert math.isfinite(row[who]["sysid_objective"]) and row[who]["sysid_objective"] >= 0
            assert len(row[who]["validation_costs"]) == 3 and all(c > 0 for c in row[who]["validation_costs"])
        # The recording is of the fitted model itself: from a start 1.5-2x off, our fit must
        # come back near the held-out cost of the true values.
        assert row["ours"]["heldout_cost"] < 10 * row["truth"]["heldout_cost"]
        # sysid's replay must be aligned with the recording's samples: at the true values only
        # the quantisation noise is left (misaligned by one MuJoCo step, q was 1100x off).
        for k in ("q", "theta"):
            assert row["truth_replay_rms"][k] < 1.2 * row["quantisation_rms"][k]
    else:
        assert sysid["reason"]

    diag = r["diagnosis"]
    assert diag["rollouts"] > 0 and diag["wall_s"] > 0 and diag["cpu_s"] > 0
    assert math.isfinite(diag["nrmse_before"]) and math.isfinite(diag["nrmse_after"])
