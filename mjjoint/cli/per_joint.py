"""``fit`` and ``diagnose`` on a multi-joint recording: each joint on its own, one report per joint.

Joint j's columns (u_j, q_j, theta_j, tau_j) make a single-joint recording, and the ordinary
single-joint fit or diagnosis runs on it from that joint's starting model (``problem``:
``--base`` with the joint's ``--gear-ratio``, one value for all joints or one per joint; a
single-joint model file used for every joint; or a ``[[joint]]`` model file whose joint j is
seen as the single arm with the rest of the arm frozen as a rigid load, ``assets.joint_view``).
The other joints' motion is then a load the model lacks (docs/multijoint.md says when that
matters), unless ``--arm`` gives the arm: then MuJoCo computes that load from their measured
motion and each joint's predictor applies it (``manipulator``).

Output: DIR/joint{j}/ holds the usual files of that joint; DIR/diagnosis.json (or fit.json)
gathers them under "joints", and DIR/index.html links them.
"""
from __future__ import annotations

import argparse
import time

from ..problem import JointProblems
from .options import run_info

COUPLING = ("each joint was diagnosed alone, so the other joints' motion (their inertia, Coriolis and gravity "
            "forces) is a load its model lacks: it can hide a missing effect or pass for one; --arm FILE takes "
            "it into account (docs/multijoint.md)")
LOADED = ("the other joints' inertia, Coriolis and gravity forces on each joint were computed by MuJoCo from their "
          "measured motion through {arm} (docs/multijoint.md)")


def fit_joints(args: argparse.Namespace, out, jp: JointProblems) -> int:
    """``mjjoint fit`` on each selected joint; DIR/joint{j}/ plus a top-level fit.json and index."""
    from ..report.build import write_fit
    from ..report.joints import write_joints_index
    from ..report.output import write_json
    from ..report.progress import FitProgress
    from ..report.summary import judged_lines, parameter_table
    from .fit import fitted

    results, floors = {}, {}
    for j, problem in jp.problems.items():
        start = time.perf_counter()
        with FitProgress(args.max_iter, desc=f"fit joint {j}") as progress:
            result, floors[j] = fitted(problem, args, progress)
        results[j] = (result, time.perf_counter() - start)
    with out.staged() as folder:
        data = _write_each(folder, "fit", args, jp, results,
                           lambda path, p, res, run: write_fit(path, p.predictor, res, p.base, p.source, run,
                                                               floors[run["joint"]]))
        write_json(folder / "fit.json", {"joints": data})
        write_joints_index(folder, "fit", jp.source, data, None, _top_run("fit", args, jp, results))
    for j, (result, seconds) in results.items():
        st = result.structure
        print(f"== joint {j}: fitted {', '.join(st.effects) or 'the minimal model'} "
              f"({result.iterations} iterations, {result.rollouts:.0f} full-length rollouts, {seconds:.1f} s)")
        print(parameter_table(st.values, result.intervals, result.warnings))
        print("held-out NRMSE per signal (noise floor: the fitted model's simulated twin):")
        print("\n".join(judged_lines(data[str(j)], result.nrmse_test)))
    print(f"wrote {out.path}/ (fit.json, index.html; joint1/ ... with each joint's fit)")
    return 0


def _write_each(folder, command: str, args, jp: JointProblems, results: dict, write) -> dict:
    """Each joint's usual output in ``folder/joint{j}``; returns their JSON data by joint."""
    data = {}
    for j, (res, seconds) in results.items():
        problem = jp.problems[j]
        run = {**run_info(command, args, problem), "joint": j, "seconds": round(seconds, 3),
               "rollouts_full_length": round(res.rollouts, 1)}
        (folder / f"joint{j}").mkdir()
        data[str(j)] = write(folder / f"joint{j}", problem, res, run)
    return data


def diagnose_joints(args: argparse.Namespace, out, jp: JointProblems, options) -> int:
    """``mjjoint diagnose`` on each selected joint; names the joints where something is missing."""
    from ..report.progress import StepLog
    from ..report.summary import diagnosis_summary

    log = StepLog()
    summary, seconds = diagnose_each_joint(args, out, jp, options, log)
    for j, data in summary["joints"].items():
        print(f"== joint {j}")
        print(diagnosis_summary(data, seconds[int(j)]))
    print(f"verdict: {summary['verdict']}")
    print(f"report: {out.path / 'index.html'}  (data: diagnosis.json; joint1/ ... with each joint's report)")
    return 0


def diagnose_each_joint(args: argparse.Namespace, out, jp: JointProblems, options, log) -> tuple[dict, dict[int, float]]:
    """Each selected joint diagnosed into ``out``; the top-level diagnosis.json data and each joint's wall time."""
    from ..diagnosis.loop import diagnose
    from ..report.build import write_diagnosis
    from ..report.joints import write_joints_index
    from ..report.output import write_json

    results = {}
    for j, problem in jp.problems.items():
        start = time.perf_counter()
        diag = diagnose(problem.predictor, problem.base, options, progress=lambda m, j=j: log(f"joint {j}: {m}"))
        results[j] = (diag, time.perf_counter() - start)
    with out.staged() as folder:
        data = _write_each(folder, "diagnose", args, jp, results,
                           lambda path, p, res, run: write_diagnosis(path, p.predictor, res, p.source, run))
        summary = joints_verdict(data, COUPLING if jp.arm is None else LOADED.format(arm=jp.arm))
        write_json(folder / "diagnosis.json", summary)
        write_joints_index(folder, "diagnose", jp.source, data, summary, _top_run("diagnose", args, jp, results))
    return summary, {j: s for j, (_, s) in results.items()}


def joints_verdict(data: dict[str, dict], coupling: str = COUPLING) -> dict:
    """The top-level diagnosis.json: every joint's diagnosis, where something is missing, the verdict
    (``coupling``: what the verdict notes about the other joints' motion)."""
    mismatch = [int(j) for j, d in data.items() if d["missing"]]
    clean = [j for j in data if int(j) not in mismatch]
    named = [", ".join(data[str(j)]["missing"]) for j in mismatch]
    parts = []
    if len(mismatch) == 1:
        parts.append(f"the mismatch is in joint {mismatch[0]}: {named[0]}")
    elif mismatch:
        each = "; ".join(f"joint {j}: {e}" for j, e in zip(mismatch, named))
        parts.append(f"the mismatch is in joints {', '.join(map(str, mismatch))} ({each})")
    explained = [j for j in clean if data[j].get("explained")]
    unexplained = [j for j in clean if j not in explained]
    for js, what in ((explained, "explained to the noise, nothing missing"),
                     (unexplained, "nothing catalogued found, but a mismatch remains")):
        if js:
            parts.append(f"joint{'s' if len(js) > 1 else ''} {', '.join(js)}: {what}")
    return {"joints": data, "mismatch_in": mismatch, "explained": all(d.get("explained") for d in data.values()),
            "verdict": f"{'; '.join(parts)}. Note: {coupling}"}


def _top_run(command: str, args: argparse.Namespace, jp: JointProblems, results: dict) -> dict:
    """The top-level run.json: the invocation (windows are alike: one recording, one design) and totals."""
    info = run_info(command, args, next(iter(jp.problems.values())))
    return {**info, "recording": jp.source, "joints": list(results),
            "seconds": round(sum(s for _, s in results.values()), 3),
            "rollouts_full_length": round(sum(r.rollouts for r, _ in results.values()), 1)}
