"""How much of a fitted parameter's bias the windows' start velocities carry.

The windows start from the encoders' angles and from velocities the recording does not hold
(``Measured.step_velocity``: a Savitzky-Golay derivative). For a concealed case's truth recorded
in closed loop, the TRUE structure is fitted as ``scripts/interval_coverage.py`` fits it, once
with the start velocities as estimated and once with some of them replaced by the truth's own
state velocities at the window starts (the simulation's states, which no recording has). What
the estimate moves by between the two is the start velocities' share of its bias.

    python scripts/start_state_bias.py --effect input_delay --seeds 4 16 --truth motor

prints, per seed, how far the estimated start velocities are off the truth's, and per reading
of them the effect's parameters: truth, estimate, its difference and the 95 % interval
(docs/diagnosis.md, "Intervals: coverage measured").
"""
from __future__ import annotations

import argparse

import numpy as np

from mjjoint.assets import build_arm, load_model
from mjjoint.benchmark.cases import CONCEALED, GEAR_RATIO, make_case
from mjjoint.cli.fit import RESTARTS
from mjjoint.identify.effects import EFFECTS
from mjjoint.identify.fit import check_intervals, fit
from mjjoint.identify.structure import Structure
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.recordings import Recording
from mjjoint.rehearse.loop import run_loop
from mjjoint.rehearse.reference import LabProgram
from mjjoint.sim import joint_indices

READINGS = {"estimated": (), "motor": ("q",), "link": ("theta",), "both": ("q", "theta")}


class TrueStarts(Measured):
    """A recording whose start velocities of the signals in ``truth`` are the truth's own state
    velocities (set after reading: {"q" or "theta": one per sample})."""

    truth: dict

    def step_velocity(self, name: str, h: float, at: np.ndarray) -> np.ndarray:
        if name not in self.truth:
            return super().step_velocity(name, h, at)
        v = self.truth[name]
        return np.interp(at, np.arange(len(v)), v)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--effect", default="input_delay", choices=[e for e in CONCEALED if e not in ("none", "gravity")])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--duration", type=float, default=8.0)
    ap.add_argument("--truth", nargs="+", choices=list(READINGS)[1:], default=["motor"],
                    help="which start velocities to take from the truth, each beside the estimated ones")
    args = ap.parse_args(argv)
    own = [p.name for p in EFFECTS[args.effect].params]
    for seed in args.seeds:
        case = make_case(args.effect, seed)
        arm, joint = case.truth.model_params()
        model = load_model(build_arm(arm, joint, scene=False))
        program = LabProgram(duration=args.duration, seed=case.seed)
        run = run_loop(model, program.sample(1000.0, program.duration), keep_states=True)
        c = run.columns
        rec = Recording(t=c["t"], u=c["u"], q=c["q"], theta=c["theta"], tau=c["tau"], gear_ratio=GEAR_RATIO, meta={})
        ji = joint_indices(model)[0]
        state = {"q": run.states[:, 1 + model.nq + ji.motor_dof], "theta": run.states[:, 1 + model.nq + ji.link_dof]}
        start = Structure.create(case.truth.effects, case.truth.nominal, GEAR_RATIO, settings=case.truth.settings)
        for reading in ("estimated", *args.truth):
            measured = TrueStarts.from_recording(rec, GEAR_RATIO)
            measured.truth = {k: state[k] for k in READINGS[reading]}
            predictor = Predictor(measured, WindowDesign(seed=seed))
            if not measured.truth:  # the estimated reading: how far its start velocities are off
                for name, v in state.items():
                    err = measured.step_velocity(name, model.opt.timestep, predictor.starts) - v[predictor.starts]
                    print(f"{args.effect} seed {seed}: {name}'s start velocities {np.sqrt(np.mean(err ** 2)):.3g} "
                          f"rms off the truth's (which are {np.sqrt(np.mean(v[predictor.starts] ** 2)):.3g} rms)",
                          flush=True)
            result = fit(predictor, start, max_iter=30, restarts=RESTARTS)  # as interval_coverage.py fits
            result = check_intervals(predictor, result, own, biased=list(result.intervals))
            for name in own:
                truth, value = case.truth.values[name], result.structure.values[name]
                lo, hi = result.intervals[name]
                print(f"{args.effect} seed {seed}, start velocities {reading}: {name} truth {truth:.7g}, estimate "
                      f"{value:.7g} ({value - truth:+.3g}), 95 % {lo:.7g} .. {hi:.7g} "
                      f"{'holds' if lo <= truth <= hi else 'misses'} the truth", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
