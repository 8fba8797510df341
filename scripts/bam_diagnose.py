"""Rhoban BAM servo pendulum (Dynamixel XL330): reproduce the logs, then diagnose the missing physics.

(i) reproduce: each log gets its own Coulomb-viscous-gravity fit (windowed prediction, held-out
    NRMSE of the position), and is replayed in closed loop with the servo's P controller on the
    simulated state, BAM's own score (mean |position error|); next to BAM's published m1 and m6
    parameters run through BAM's equations, and BAM's m1, m3, m6 refitted to these logs.
(ii) diagnose: from coulomb_friction + viscous_friction + gravity on all selected logs stacked
    (windows never cross a join), with the candidates a one-encoder servo can show.
(iii) at rest: how much torque imbalance the gear holds, against the load it holds.

    python scripts/bam_diagnose.py                          # all 16 logs (~30 min on 2 cores)
    python scripts/bam_diagnose.py --kp 400 --max-rounds 2  # one gain, 4 logs
    python scripts/bam_diagnose.py --skip-diagnose          # (i) and (iii) only
    python scripts/bam_diagnose.py --by-trajectory --skip-reproduce --bam-evals 0

Writes OUT/reproduce.json, OUT/summary.md and the diagnosis report OUT/diagnose/ (index.html,
diagnosis.json, traces.rrd, PNGs; ``mjjoint diagnose``'s layout), with --by-trajectory one
OUT/diagnose_<trajectory>/ per trajectory type instead.
"""
from __future__ import annotations

import argparse
import itertools
import sys
import time
from pathlib import Path

import numpy as np
from scipy.ndimage import minimum_filter1d
from scipy.optimize import minimize

from mjjoint.datasets import bam
from mjjoint.diagnosis.loop import DiagnoseOptions, diagnose
from mjjoint.identify.fit import fit
from mjjoint.report.build import write_diagnosis
from mjjoint.report.output import OutputDir, write_json

BASE = ("coulomb_friction", "viscous_friction", "gravity")
# What a servo with one encoder at the output can show: friction shapes (load-dependent ones
# too: the rigid gear's spring carries the transmitted torque), an input bias or delay,
# cogging. Nothing that needs the gear's deflection (stiffness, hysteresis, backlash) and no
# link flexibility (a 0.1 m arm with a compact mass).
CANDIDATES = ("stribeck_friction", "dynamic_friction", "friction_asymmetry", "load_friction",
              "load_dependent_friction", "input_delay", "input_offset", "torque_ripple")
# BAM's Parameter bounds (bam/model.py Model.set_actuator, bam/dynamixel/actuator.py
# XL330Actuator.initialize), for refitting its m1 and m6 to these logs.
BAM_BOUNDS = {"kt": (0.1, 3.0), "R": (2.0, 5.0), "armature": (1e-4, 0.05), "q_offset": (-0.1, 0.1),
              "friction_base": (0.0, 0.2), "friction_stribeck": (0.0, 0.2), "friction_viscous": (0.0, 1.0),
              "load_friction_motor": (0.0, 0.5), "load_friction_external": (0.0, 0.5),
              "load_friction_base": (0.0, 0.5), "load_friction_motor_stribeck": (0.0, 1.0),
              "load_friction_external_stribeck": (0.0, 1.0), "load_friction_motor_quad": (0.0, 0.01),
              "load_friction_external_quad": (0.0, 0.01), "dtheta_stribeck": (0.1, 1.0), "alpha": (1.0, 10.0)}
REST_SPEED = 0.02  # [rad/s] output speed below which a sample counts as at rest (~ 1 count / 75 ms)
REST_SAMPLES = 11  # ... for 55 ms around it: turning points, where J theta'' is large, are not rest


def mean_mae(logs, params) -> float:
    return float(np.mean([bam.replay_errors(bam.bam_rollout(log, params), log)["mae"] for log in logs]))


def refit_bam(logs, model: str, max_evals: int) -> dict:
    """BAM's model ``model`` refitted to ``logs`` on BAM's score (Powell from the published values)."""
    start = dict(bam.BAM_PARAMS[model])
    names = list(start)
    bounds = [BAM_BOUNDS[n] for n in names]
    x0 = np.clip([start[n] for n in names], [b[0] for b in bounds], [b[1] for b in bounds])
    best = [mean_mae(logs, dict(zip(names, x0))), x0]

    def score(x):
        # Keep the best point seen: bounded Powell's final point can be worse than its start.
        f = mean_mae(logs, dict(zip(names, x)))
        f = f if np.isfinite(f) else np.inf
        if f < best[0]:
            best[:] = [f, np.array(x)]
        return f

    minimize(score, x0, method="Powell", bounds=bounds, options={"maxfev": max_evals, "xtol": 1e-3, "ftol": 1e-4})
    return dict(zip(names, (float(v) for v in best[1])))


def reproduce(logs, recs, window: float, fit_iter: int, say) -> list[dict]:
    """Per log: its own Coulomb-viscous fit, windowed and closed-loop errors; BAM's published models."""
    rows = []
    for log, rec in zip(logs, recs):
        p = bam.problem([rec], BASE, log, window)
        res = fit(p.predictor, p.base, max_iter=fit_iter)
        closed = bam.replay_errors(bam.replay(res.structure, log), log)
        row = {"log": log.name, "file": log.path.name, "kp": log.kp, "trajectory": log.trajectory,
               "windowed_nrmse_heldout": res.nrmse_test["theta"], "windowed_nrmse_train": res.nrmse_train["theta"],
               "closed_loop": closed, "parameters_output_side": output_side(res.structure.values),
               "warnings": res.warnings, "seconds": res.seconds}
        for m in ("m1", "m6"):
            row[f"bam_{m}_published"] = bam.replay_errors(bam.bam_rollout(log, bam.BAM_PARAMS[m]), log)
        rows.append(row)
        say(f"{log.name:24s} windowed NRMSE {row['windowed_nrmse_heldout']:.3f}  closed-loop MAE "
            f"{closed['mae']:.4f} rad (BAM m1 {row['bam_m1_published']['mae']:.4f}, "
            f"m6 {row['bam_m6_published']['mae']:.4f})  {res.seconds:.0f} s")
    return rows


def output_side(values: dict[str, float]) -> dict[str, float]:
    """Fitted motor-side values as BAM states them, at the output (x N or N^2)."""
    n = bam.GEAR_RATIO
    scale = {"inertia.motor": n * n, "coulomb_friction.fc": n, "viscous_friction.sigma": n * n,
             "stribeck_friction.vs": 1 / n, "input_offset.offset": n, "torque_ripple.a": n, "torque_ripple.b": n}
    return {k: v * scale.get(k, 1.0) for k, v in values.items()}


def rest_holding(logs) -> list[dict]:
    """At rest with torque on: the imbalance |u - G| the gear holds, binned by the load |G| [N m, output]."""
    imbalance, load = [], []
    for log in logs:
        w = log.speed()
        tau = bam.XL330_M6.kt * log.current()
        gravity = (log.mass + bam.ROD_MASS / 2) * 9.81 * log.length * np.sin(log.position)
        still = (np.abs(w) < REST_SPEED) & (log.enable > 0)
        rest = minimum_filter1d(still.astype(int), REST_SAMPLES) > 0
        imbalance.append(np.abs(tau - gravity)[rest])
        load.append(np.abs(gravity)[rest])
    imbalance, load = np.concatenate(imbalance), np.concatenate(load)
    edges = np.linspace(0.0, 0.5, 6)
    rows = []
    for lo, hi in itertools.pairwise(edges):
        m = (load >= lo) & (load < hi)
        if m.sum() >= 20:
            rows.append({"load_lo": lo, "load_hi": hi, "samples": int(m.sum()),
                         "imbalance_p50": float(np.median(imbalance[m])),
                         "imbalance_p95": float(np.percentile(imbalance[m], 95))})
    return rows


def run_diagnosis(logs, recs, args, out: Path, say) -> dict:
    """Diagnose ``logs`` stacked; the report goes to ``out`` (``mjjoint diagnose``'s layout)."""
    p = bam.problem(recs, BASE, logs[0], args.window, seed=args.seed)
    pred = p.predictor
    say(f"diagnosing {len(recs)} logs: {len(pred.starts)} windows of {args.window} s, {len(pred.test)} held out")
    options = DiagnoseOptions(max_rounds=args.max_rounds, fit_iter=args.fit_iter, screen_iter=args.screen_iter,
                              candidates=tuple(args.candidates))
    start = time.perf_counter()
    diag = diagnose(pred, p.base, options, progress=say)
    seconds = time.perf_counter() - start
    source = f"BAM XL330 pendulum: {', '.join(lg.name for lg in logs)}"
    run = {"command": " ".join(sys.argv), "seconds": round(seconds, 1), "rollouts_full_length": round(diag.rollouts, 1),
           "windows": len(pred.starts), "heldout_windows": int(pred.holdout.sum()), "logs": [lg.path.name for lg in logs]}
    target = OutputDir(out)
    target.check()
    with target.staged() as folder:
        write_diagnosis(folder, pred, diag, source, run)
    replays = {}
    for label, res in (("coulomb_viscous", diag.initial), ("diagnosed", diag.final)):
        replays[label] = {lg.name: bam.replay_errors(bam.replay(res.structure, lg), lg) for lg in logs}
    return {"named": diag.missing, "verdict": diag.verdict, "seconds": seconds,
            "nrmse_heldout_before": diag.initial.nrmse_test, "nrmse_heldout_after": diag.final.nrmse_test,
            "steps": [{"effect": s.effect, "heldout_gain": s.gain, "screened": s.screened,
                       "parameters_output_side": output_side(s.parameters), "evidence": s.evidence} for s in diag.steps],
            "base_parameters_output_side": output_side(diag.initial.structure.values),
            "final_parameters_output_side": output_side(diag.final.structure.values),
            "final_warnings": diag.final.warnings, "closed_loop": replays}


def summary(result: dict) -> str:
    """The numbers of docs/datasets_bam.md as Markdown."""
    lines = ["| log | windowed NRMSE (held-out) | closed-loop MAE [rad] | BAM m1 published | BAM m6 published |",
             "|---|---|---|---|---|"]
    for r in result.get("reproduce", []):
        lines.append(f"| {r['log']} | {r['windowed_nrmse_heldout']:.3f} | {r['closed_loop']['mae']:.4f} | "
                     f"{r['bam_m1_published']['mae']:.4f} | {r['bam_m6_published']['mae']:.4f} |")
    mean = lambda key: np.mean([r[key]["mae"] for r in result.get("reproduce", [])])
    if result.get("reproduce"):
        lines.append(f"| mean | {np.mean([r['windowed_nrmse_heldout'] for r in result['reproduce']]):.3f} | "
                     f"{mean('closed_loop'):.4f} | {mean('bam_m1_published'):.4f} | {mean('bam_m6_published'):.4f} |")
    if "bam_refit" in result:
        lines += ["", "| BAM model | published params, these logs | refitted to these logs | BAM's published MAE (its logs) |",
                  "|---|---|---|---|"]
        for m, r in result["bam_refit"].items():
            lines.append(f"| {m} | {r['mae_published']:.4f} | {r['mae']:.4f} | {bam.BAM_MAE[m]:.4f} |")
    for group, d in result.get("diagnosis", {}).items():
        before, after = d["nrmse_heldout_before"]["theta"], d["nrmse_heldout_after"]["theta"]
        lines += ["", f"diagnosis ({group}): named {', '.join(d['named']) or 'nothing'}; {d['verdict']}",
                  f"held-out NRMSE (theta) {before:.3f} -> {after:.3f}; {d['seconds']:.0f} s"]
        for label, per in d["closed_loop"].items():
            lines.append(f"closed-loop MAE, one {label} fit for these logs: "
                         f"{np.mean([e['mae'] for e in per.values()]):.4f} rad")
    if "rest_holding" in result:
        lines += ["", "| load |G| [N m] | samples | median |u - G| | 95th pct |u - G| |", "|---|---|---|---|"]
        for r in result["rest_holding"]:
            lines.append(f"| {r['load_lo']:.1f}-{r['load_hi']:.1f} | {r['samples']} | {r['imbalance_p50']:.3f} | "
                         f"{r['imbalance_p95']:.3f} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, help="folder of the BAM .json logs (default: the dataset folder)")
    ap.add_argument("--kp", type=float, nargs="+", help="only logs with these gains")
    ap.add_argument("--trajectory", nargs="+", help="only these trajectories (sin_sin, lift_and_drop, ...)")
    ap.add_argument("--window", type=float, default=0.2, help="prediction window [s] (default 0.2)")
    ap.add_argument("--seed", type=int, default=0, help="which windows are held out (default 0)")
    ap.add_argument("--fit-iter", type=int, default=20)
    ap.add_argument("--screen-iter", type=int, default=8)
    ap.add_argument("--max-rounds", type=int, default=3)
    ap.add_argument("--candidates", nargs="+", default=list(CANDIDATES))
    ap.add_argument("--bam-evals", type=int, default=1500, help="BAM refit budget per model (0: skip)")
    ap.add_argument("--skip-reproduce", action="store_true")
    ap.add_argument("--skip-diagnose", action="store_true")
    ap.add_argument("--by-trajectory", action="store_true", help="diagnose each trajectory type on its own")
    ap.add_argument("--out", type=Path, default=Path("out/bam"))
    args = ap.parse_args(argv)
    say = lambda msg: print(msg, flush=True)
    try:
        logs = [bam.read_log(p) for p in bam.log_paths(args.data)]
    except (ValueError, FileNotFoundError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    logs = [lg for lg in logs if (args.kp is None or lg.kp in args.kp)
            and (args.trajectory is None or lg.trajectory in args.trajectory)]
    if not logs:
        print("error: no log matches --kp/--trajectory", file=sys.stderr)
        return 2
    recs = [bam.to_recording(lg) for lg in logs]
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    result: dict = {"logs": [lg.path.name for lg in logs], "window": args.window,
                    "bam_published_mae": bam.BAM_MAE, "rest_holding": rest_holding(logs)}
    if not args.skip_reproduce:
        say("(i) reproduce: one Coulomb-viscous fit per log")
        result["reproduce"] = reproduce(logs, recs, args.window, args.fit_iter, say)
    if args.bam_evals > 0:
        result["bam_refit"] = {}
        for m in bam.BAM_PARAMS:
            t = time.perf_counter()
            params = refit_bam(logs, m, args.bam_evals)
            row = {"mae": mean_mae(logs, params), "mae_published": mean_mae(logs, bam.BAM_PARAMS[m]), "params": params}
            result["bam_refit"][m] = row
            say(f"BAM {m} refitted to these logs: mean MAE {row['mae']:.4f} rad (published params "
                f"{row['mae_published']:.4f}; {time.perf_counter() - t:.0f} s)")
    if not args.skip_diagnose:
        groups = {"all": list(range(len(logs)))}
        if args.by_trajectory:
            groups = {tr: [i for i, lg in enumerate(logs) if lg.trajectory == tr]
                      for tr in dict.fromkeys(lg.trajectory for lg in logs)}
        result["diagnosis"] = {}
        for group, idx in groups.items():
            say(f"(ii) diagnose: {group}")
            folder = args.out / ("diagnose" if group == "all" else f"diagnose_{group}")
            result["diagnosis"][group] = run_diagnosis([logs[i] for i in idx], [recs[i] for i in idx], args, folder, say)
    result["seconds"] = time.perf_counter() - t0
    write_json(args.out / "reproduce.json", result)
    (args.out / "summary.md").write_text(summary(result), encoding="utf-8")
    print(summary(result))
    say(f"wrote {args.out}/ (reproduce.json, summary.md{', diagnose*/' if 'diagnosis' in result else ''}); "
        f"{result['seconds']:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
