"""diagnose: fit -> locate -> name -> add -> refit, until nothing missing is left.

First, the held-out windows whose start the recording leaves open are left out of every score
(``open_starts``), so that every model is tested on the same windows. Each round:
1. the current structure is fitted to the training windows (``identify.fit``);
2. its prediction residual is located (``locate``): which signal, when, under which condition;
   and, where the gear torque is recorded, the rotor's torque balance (``balance``);
3. every effect not yet in the model (whose prerequisites are; those screened on request only
   where the options name them or the recording shows their sign: ``recorded_signs``, and
   the base fit's rotor creeping through the recording's rests, ``rests.creep``) is
   screened by fitting its own parameters and those of the effects it refines, the rest held
   at their fitted values, on
   the training windows; if the best one's gain is material but inconsistent over windows
   (only the rank test fails), or it fails while the model misses FAR_FROM_FLOOR times its
   noise floor (the terms it has bent toward what it lacks), or it is a sensor effect screened
   by default (``_freed_physics``) or passes with rivals the held-out windows cannot tell apart
   from it (``_freed_rival``) while the model misses its floor, once more with every parameter
   free, from and against the current structure refitted with every parameter free, the rank
   test at half the level (stand-ins for a missing effect need not sit at its site: a delay's
   phase lag in the load's viscous coefficient, a flexible rod's in a rigid link's gravity and
   tip mass; docs/diagnosis.md). Screens run in two stages (CONTINUE_SHARE):
   every candidate on the coarse subset of the training windows, then the few that gain most
   on the model itself fitted the same way on all of them, each to the result a whole screen gives;
4. the candidate that lowers the HELD-OUT cost most is named if it passes both tests below;
   if none does and a located condition is significant, the generic forms that condition points
   to (``identify.generic``: the open vocabulary, named by site and form) are screened, as the
   catalogue last was (all free after an escalation), and judged the same way; if none of those
   does either, the two best screens fitted together (``diagnosis.pairs``: two missing terms can
   mask each other) are judged as one addition;
   it is added, the whole structure refitted (least squares; where that leaves a parameter on
   a stand-in bound FAR_FROM_FLOOR times the floor away, again from the recording's start,
   ``restarted``; then under the robust loss over
   windows, kept if that lowers the held-out cost: ``DiagnoseOptions.robust_refit``), the
   search revised (``diagnosis.revise``: an addition that is a stand-in is refused, named
   effects are swapped for rivals or removed when the acceptance rule says so; a refusal whose
   refit without the effect beats the base by ``min_gain`` screens it once more from there), and
   the next round starts;
5. when no candidate passes, the final structure's parameters are estimated once more under the
   robust loss over windows (``identify.fit``, ``robust=True``; ``DiagnoseOptions.robust_final``),
   kept only if that lowers the held-out cost; unless they already are such an estimate (the
   last addition's or revision's robust refit, kept, and nothing refitted since): that fit
   would start at its own optimum. Where nothing was named yet and that estimate of the base
   predicts the held-out windows better by ``min_gain``, the search goes on from it, once: a
   least-squares base can be held by the few training windows it misses most, and every screen
   starts from it.
The base fit and every screen are least squares: while a structure is being searched, the
windows it predicts worst are where missing physics shows, and a robust fit would discount them
as outliers (20 s dynamic_friction case, robust fits throughout: 2SEP still lowers the held-out
cost by 81 %, but the paired test over windows gives p 0.064 instead of 0.003, and 2SEP is not
named). Once the structure is settled, the windows it still misses by orders of magnitude are
ones no candidate explains (a start state the recording cannot give, such as 2SEP's lag
memory of a resting motor), and least squares would let them bias the parameters
(torque_ripple case, before window starts were moved off input steps: ripple 8 % small).
Stopping rule (documented in docs/diagnosis.md): a candidate is accepted only if, on the
held-out windows, it lowers the cost by at least ``min_gain`` (relative) and ``floor_share`` of
the recording's noise floor (absolute: ``floor``, the current model's own twin), the per-window
reductions are consistent (one-sided Wilcoxon signed-rank p <= ``max_p`` on the log ratios of
the windows' costs: a few lucky windows do not make an effect; a rank test because the
reductions are heavy-tailed, large on transients and small elsewhere; ratios because windows'
costs span a decade or more, and a difference would rank a window by its size, not its gain),
AND it lowers the BIC n log(RSS/n) + p log(n), which charges every added parameter, over the training windows both
fits were fitted on (``FitResult.left_out``). An effect at the gear, or at the torque sensor, must
also fit the gear's own law better where the recording measures it (``gear_law``: the recorded
torque from the recorded deflection, on the held-out windows): what it gains in simulation
otherwise stands in for physics elsewhere.

A round's final choice that fails the rank test alone is tested once more on its held-out
windows and those of a second fold, at half its level (``second_fold``): a short recording's few
held-out windows put a real gain on either side of the level by one window's rank.

A base whose prediction diverges from its start (its initial values too stiff for the plant's
step) is fitted at the timestep its stability check asks for, then at the plant's step where its
fitted values allow (``_base_fit``), and again from its start for a term it ran to its physical
floor on the way (``_off_the_floor``).

Candidates: every catalogued effect the model lacks; one behind a prerequisite the model lacks
too is screened together with it (a bundle "linear_stiffness+backlash"): a play cannot show
through a rigid gear, and a gear spring alone may predict worse than none. A screen whose
prediction is unstable is reported with the reason and screened again at the timestep its
stability check asks for (MAX_REFINE); one that ends far above the model it extends
(FAR_ABOVE_NULL) and holds a term the step may not resolve (``Effect.step_resolved``) is
screened again at finer steps while that gains (``_refined``).

Verdict: the final model's held-out NRMSE is judged against the recording's noise floor
(``floor``): "explained" when every signal is within the floor's ratio. The verdict says one of:
explained to the noise, nothing missing; effects found and the rest explained; effects found but
a mismatch remains (which signal, how far above its floor, where and under which conditions,
and the last round's best candidate with the tests it failed);
nothing in the catalogue explains the located mismatch. Parameters the final fit left on a
bound are named as stand-ins. A candidate whose screen's training cost ended above the model it
extends (its fit did not converge: the candidate contains that model) is screened again from
other starts (``_restarted_screen``) and, where it still ends there, is not ruled out by it;
while the model misses its floor, the verdict names such screens (``not_converged``).

Effects that act mainly under one operating condition (``Effect.acts_under``: 2SEP's pre-sliding and
lag, Stribeck's break-away, after motor velocity reversals) are also rank-tested on the held-out
windows in which that condition occurs, as the measured motor velocity shows it: windows where
the effect cannot act carry only noise, which drowns a real, concentrated gain in a rank test
over all windows. The selection is sound: it uses a measured input-side covariate only (never
a residual, nor the candidate's or the base's predictions), and it is fixed per effect by its
physics before anything is fitted, so under the null (no systematic reduction) the selected
windows' reductions are as symmetric as all of them and that test keeps its level. Of the two
tests the smaller p counts, Bonferroni-corrected (2 x min(p_all, p_condition) <= ``max_p``), so
the pair keeps the level of one test; where too few held-out windows hold the condition for its
test, 2 x p_all decides all the same; the gain thresholds and the BIC still count all held-out
windows. Both are needed: with the motion reconstructed from the angle, 2SEP also acts on
small retraces that no velocity swing marks (20 s case: p 0.0016 over all windows, 0.034 over
the 13 with a swing).

Evidence: each effect lists the residual conditions it would explain (e.g. backlash: near
velocity reversals, small |delta|); the located conditions that are significant and belong
to the named effect are reported as its evidence, next to the held-out improvement that
actually decided.
"""
from __future__ import annotations

import dataclasses
import math
import time
import weakref
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy.stats import wilcoxon

from ..assets.stability import check_model_stability, stable_timesteps
from ..identify.effects import EFFECTS, GENERIC, ON_REQUEST, base_params, incompatible, plant_effects
from ..identify.fit import (FitResult, check_intervals, finish, fit, fits_from, fitted_on_both, lowest, restart_points,
                            training_ratio, window_costs)
from ..identify.structure import Structure
from ..identify.twin import Twin
from ..identify.windows import Predictor
from .balance import SIGNAL as BALANCE, balance_location
from .clock import Phases, ScreenClock
from .features import operating_conditions, reversal_proximity
from .floor import EXPLAINED_RATIO, WINDOWING_TRUST, Floor, judged, noise_floor
from .gear_law import ENERGY_RETURNED, law_energy, law_ratio, law_site
from .locate import REVERSAL_WINDOW_S, locate, located_conditions
from .open_starts import leave_out_open_starts
from .rests import ROTOR_HOLDS, creep, rest_mask

MIN_HELDOUT = 5  # a one-sided signed-rank test on n windows cannot go below p = 2^-n

CONDITION_TEXT = {"reversal": "a motor velocity reversal"}


@dataclass(frozen=True)
class DiagnoseOptions:
    min_gain: float = 0.10       # relative held-out cost reduction needed to name an effect
    floor_share: float = 0.1     # absolute one, as a share of the noise floor's cost: below, immaterial
    max_p: float = 0.05          # Wilcoxon signed-rank p of the per-window held-out reductions
    max_rounds: int = 8          # a minimal start needs a round per missing term: the full joint has ~10
    screen_iter: int = 8         # LM iterations when screening a candidate
    fit_iter: int = 20           # LM iterations when refitting the whole structure
    candidates: tuple[str, ...] | None = None  # default: every effect
    robust_final: bool = True    # the final structure's parameters under the robust loss (step 5)
    robust_refit: bool = True    # each added effect's refit once more under the robust loss (step 4)
    free_all: bool = True        # a material but inconsistent best screen, or a model far above its floor: screen again, all free
    generic: bool = True         # where no catalogued effect explains a located residual, fit the generic forms it points to
    revise: bool = True          # after each addition: stand-in guard, swaps for rivals, removals (diagnosis.revise)
    pairs: bool = True           # no single candidate passes: the two best screens together (diagnosis.pairs)
    folds: bool = True           # a material gain only the rank test refuses: tested on a second fold as well


@dataclass
class Step:
    effect: str
    evidence: list[str]
    where: dict
    parameters: dict[str, float]
    fit_before: dict[str, float]
    fit_after: dict[str, float]
    gain: float
    screened: dict[str, float]
    alternatives: list[str] = field(default_factory=list)
    consistency: dict = field(default_factory=dict)  # the rank test: windows tested, p
    screen: str = "stand-ins held"  # or "all free": the second screen named it (module doc)
    prerequisites: list[str] = field(default_factory=list)  # added with it: the model lacked them too
    replaced: str = ""  # the effect a swap put this one in place of (``revise._swap``)

    @property
    def effects(self) -> tuple[str, ...]:
        """The effects this step adds: its prerequisites the model lacked, then the effect."""
        return (*self.prerequisites, self.effect)

    @property
    def label(self) -> str:
        text = self.effect + (f" (with {', '.join(self.prerequisites)})" if self.prerequisites else "")
        effect = EFFECTS[self.effect]
        if effect.site == "sensor":
            return text + " [a sensor effect: how the signal is measured, not the joint's physics]"
        return text + (f" [a generic form; it arises from {effect.causes}]" if effect.causes else "")

    def as_dict(self) -> dict:
        return {"effect": self.effect, "evidence": self.evidence, "where": self.where,
                "parameters": self.parameters, "fit_before": self.fit_before, "fit_after": self.fit_after,
                "heldout_gain": self.gain, "screened": self.screened,
                "indistinguishable_from": self.alternatives, "consistency_test": self.consistency,
                "screen": self.screen, "prerequisites_added": self.prerequisites,
                "generic": EFFECTS[self.effect].generic, "causes": EFFECTS[self.effect].causes}


@dataclass
class Diagnosis:
    steps: list[Step]
    initial: FitResult
    final: FitResult
    final_where: dict
    verdict: str
    rollouts: float
    seconds: float
    history: list[FitResult] = field(default_factory=list)
    floor: Floor | None = None
    explained: bool = False
    stand_ins: dict[str, str] = field(default_factory=dict)   # parameter -> which bound it sits on
    unstable: dict[str, str] = field(default_factory=dict)    # screened candidate -> why unstable
    unresolved: dict[str, float] = field(default_factory=dict)  # candidate -> its screen's training cost / the reference's
    revisions: list = field(default_factory=list)  # diagnosis.revise.Revision: swaps, removals, stand-ins refused
    phases: dict = field(default_factory=dict)  # where the rollouts and time went (``clock.Phases.as_dict``)
    signs: dict = field(default_factory=dict)  # the recording's own signs (``recorded_signs``): name -> description
    open_starts: list = field(default_factory=list)  # [s] held-out windows left out of every score (``open_starts``)

    @property
    def stand_in_effects(self) -> dict[str, str]:
        """{effect: why}: effects that passed the acceptance rule but were refused as stand-ins."""
        return {r.effect: r.reason for r in self.revisions if r.kind == "stand-in"}

    def models(self) -> list[Structure]:
        """The model before the first step and after each (the final one last); after a swap or
        a removal, or where one round named a pair (one fit for two steps), as the final fit has
        them (``revise.step_models``)."""
        from .revise import step_models
        if any(r.kind != "stand-in" for r in self.revisions) or any(s.screen.startswith(TOGETHER) for s in self.steps):
            return step_models(self.initial.structure, self.final.structure, self.steps)
        return [r.structure for r in self.history] if self.steps else [self.initial.structure]

    @property
    def missing(self) -> list[str]:
        return [e for s in self.steps for e in s.effects]

    def as_dict(self) -> dict:
        return {"missing": self.missing, "steps": [s.as_dict() for s in self.steps],
                "final_model": {**self.final.structure.describe(),
                                "intervals_95": {k: list(v) for k, v in self.final.intervals.items()},
                                "warnings": self.final.warnings},
                "initial_fit": {"nrmse_heldout": self.initial.nrmse_test, "cost_heldout": self.initial.cost_test},
                "final_fit": {"nrmse_heldout": self.final.nrmse_test, "cost_heldout": self.final.cost_test},
                "final_where": self.final_where,
                "noise_floor": None if self.floor is None else self.floor.as_dict(),
                "explained": self.explained,
                "stand_ins": self.stand_ins,
                "unstable_screens": self.unstable,
                "unresolved_screens": self.unresolved,
                "revisions": [r.as_dict() for r in self.revisions],
                "stand_in_effects": self.stand_in_effects,
                "recorded_signs": self.signs,
                "heldout_left_out_s": self.open_starts,
                "verdict": self.verdict,
                # Rollouts only: diagnosis.json holds no wall times (run.json does), so that a rerun
                # gives the same file; the progress line has the seconds per phase.
                "budget": {"rollouts_full_length": round(self.rollouts, 1),
                           "phases": {k: {n: v for n, v in p.items() if n != "seconds"} for k, p in self.phases.items()}}}


def _bic(cost: float, n: int, p: int) -> float:
    return n * np.log(max(cost, 1e-300)) + p * np.log(n)


def residual_location(predictor: Predictor, structure: Structure, seed: int = 0) -> dict:
    """Where the structure's windowed predictions miss the recording (JSON-ready)."""
    (pred,) = predictor.predict([structure])
    m = predictor.m
    n = predictor.nwin_samples
    # One uniform time line over the windows, each sample taken from the window that first
    # covers it; samples no window predicts (before a join of stacked logs) count as matched.
    span = np.arange(predictor.starts[0], predictor.starts[-1] + n)
    at = predictor.samples[predictor.owned] - span[0]
    meas, sim = {}, {}
    for s in predictor.signals:
        # q drifts within a window by construction: locate on its deviation from the window start.
        start = predictor.meas[s][:, :1] if s == "q" else 0.0
        meas[s], sim[s] = np.zeros(len(span)), np.zeros(len(span))
        meas[s][at] = (predictor.meas[s] - start)[predictor.owned]
        sim[s][at] = np.nan_to_num(pred[s] - start)[predictor.owned]
    cond = operating_conditions(m.t, m.q, m.theta, m.u, m.gear_ratio, m.tau)
    cond = {k: np.asarray(v)[span] for k, v in cond.items()}
    t = m.t[span]
    where = locate(t, meas, sim, cond, seed=seed).as_dict()
    # A torque on the rotor as a function of its angle, however filtered. The balance is the
    # recording's alone, whatever the model: located once per recording and seed, not each round
    # (its scan of real periods is the costliest condition on a long travel). A resting rotor's
    # friction is whatever holds it: no law of the motion, so the rests are left out.
    balances = _BALANCES.setdefault(predictor, {})
    if seed not in balances:
        balances[seed] = balance_location(t, cond, moving=~rest_mask(m)[span], seed=seed)
    if balances[seed] is not None:
        where["signals"][BALANCE] = balances[seed].as_dict()
    return where


_BALANCES: "weakref.WeakKeyDictionary[Predictor, dict]" = weakref.WeakKeyDictionary()


BUNDLE = "+"  # joins an effect to the prerequisites screened with it: "linear_stiffness+backlash"
PAIR = " & "  # joins the two candidate keys named together (``diagnosis.pairs``): "backlash & input_delay"
TOGETHER = "together with"  # a pair's steps' screen: "together with backlash"


def parts(key: str) -> tuple[str, ...]:
    """The effects of a candidate: one, or a bundle (prerequisites first)."""
    return tuple(key.split(BUNDLE))


def with_candidate(structure: Structure, key: str, values=None, settings=None) -> Structure:
    """``structure`` with candidate ``key``: its prerequisites at their initial values, then its
    effect with ``values`` (any of the key's parameters) and ``settings``."""
    *needed, effect = parts(key)
    for e in needed:
        structure = structure.with_effect(e)
    return structure.with_effect(effect, values, settings)


def _evidence(key: str, where: dict, signs: dict[str, str] | None = None) -> list[str]:
    """The located conditions and the recording's ``signs`` (``recorded_signs``) that the effects
    of ``key`` declare as their evidence."""
    wanted = {c for e in parts(key) for c in EFFECTS[e].evidence}
    return [f"{sig}: {c['description']}" for sig, c in located_conditions(where)
            if c["significant"] and c["name"] in wanted] + [d for sign, d in (signs or {}).items() if sign in wanted]


def _candidate_variants(effect: str, where: dict, structure: Structure) -> list[tuple[dict, dict]]:
    """(initial values, discrete settings) to screen an effect with on ``structure``, suggested by
    the evidence (``Effect.variants``)."""
    variants = EFFECTS[effect].variants
    return [({}, {})] if variants is None else variants([c for _, c in located_conditions(where)], structure)


def screened_params(key: str, structure: Structure) -> list[str]:
    """The parameters freed when screening ``effect`` on ``structure``.

    The candidate's own; those of the effects it refines (adding hysteresis to a gear changes
    what k1 should be: the base fit's k1 is the secant stiffness of the hysteretic truth) or that
    stand in for it (``Effect.stand_ins``: a gear damper fitted to a rod's oscillation); those
    of the effects already in the model that act where it acts (a model without Coulomb
    friction fits a viscous coefficient that stands in for it: EMPS, 424 instead of ~200
    N s/m); and the inertias, which stand in for everything (EMPS without friction: 418 kg for
    a 95 kg axis). A candidate held against such stand-ins cannot show what it explains.
    """
    effects = parts(key)
    sites = {EFFECTS[e].site for e in effects}
    related = [e for e in structure.effects if EFFECTS[e].site in sites]
    related += [r for e in effects for r in EFFECTS[e].requires]
    related += [r for e in effects for r in EFFECTS[e].stand_ins if r in structure.effects]
    names = [p.name for p in base_params(structure.nominal)]
    for e in dict.fromkeys([*related, *effects]):
        names += [p.name for p in EFFECTS[e].params]
    return names


def default_candidates(structure: Structure, shown=()) -> tuple[str, ...]:
    """The effects screened unless the options name them: every one the plant can have but the
    generic forms and those screened on request (``effects.ON_REQUEST``: the sensors', the exact
    sign), unless the recording ``shown`` a sign of one (``Effect.evidence``, ``recorded_signs``)."""
    opened = opened_by(shown)
    return tuple(e for e in plant_effects(structure.nominal) if e not in GENERIC
                 and (e not in ON_REQUEST or e in opened))


def opened_by(shown) -> tuple[str, ...]:
    """The effects screened on request that the recording's signs ``shown`` make default
    candidates: those that declare one of them as evidence."""
    return tuple(e for e in ON_REQUEST if set(EFFECTS[e].evidence) & set(shown))


def recorded_signs(predictor: Predictor) -> dict[str, str]:
    """{sign: description} of the signs the recording itself shows, whatever the model: the gear
    law giving energy back (``gear_law.law_energy``)."""
    energy = law_energy(predictor.m)
    return {ENERGY_RETURNED: energy.describe()} if energy is not None and energy.shown else {}


def candidates_for(structure: Structure, allowed=None, scored=None, shown=()) -> list[str]:
    """The effects to screen on ``structure``: each one it lacks, bundled with the prerequisites
    it lacks too (module doc). By default (no ``allowed`` list), those of ``default_candidates``
    (the recording's signs ``shown``) but, where the signals the fit ``scored`` are given, any
    sensor effect that changes none of them: a skew of the link encoder on a fit of the motor
    angle would act through the windows' start states alone, a stand-in."""
    possible = plant_effects(structure.nominal)
    if allowed is not None:
        names = [e for e in allowed if e in possible]
    else:
        names = [e for e in default_candidates(structure, shown) if scored is None or EFFECTS[e].site != "sensor"
                 or set(EFFECTS[e].senses) & set(scored)]
    keys = (bundle(e, structure.effects, possible) for e in names if e not in structure.effects)
    return [k for k in keys if k is not None]


def bundle(effect: str, effects, possible) -> str | None:
    """The candidate key that adds ``effect`` to a model of ``effects``, with the prerequisites
    it lacks; None where one of those is not ``possible`` or ``effect`` cannot be in one model
    with an effect there."""
    missing = [r for r in EFFECTS[effect].requires if r not in effects]
    if not all(r in possible for r in missing) or any(incompatible(effect, x) for x in effects):
        return None
    return BUNDLE.join([*missing, effect])


def generic_candidates(structure: Structure, where: dict, excluded=()) -> tuple[str, ...]:
    """The generic forms (``identify.generic``) the model lacks whose structure a significant
    located condition shows, but the ``excluded``."""
    shown = {c["name"] for _, c in located_conditions(where) if c["significant"]}
    possible = plant_effects(structure.nominal)
    return tuple(e for e in GENERIC if e in possible and e not in structure.effects and e not in excluded
                 and shown.intersection(EFFECTS[e].evidence))


def diagnose(predictor: Predictor, base: Structure, options: DiagnoseOptions = DiagnoseOptions(),
             progress: Callable[[str], None] | None = None) -> Diagnosis:
    say = progress or (lambda msg: None)
    t_start = time.perf_counter()
    roll0 = predictor.rollouts
    phases = Phases(lambda: predictor.rollouts)
    with phases("open held-out starts"):
        open_starts = leave_out_open_starts(predictor, base, MIN_HELDOUT, say)
    if len(predictor.test) < MIN_HELDOUT:
        raise ValueError(f"only {len(predictor.test)} held-out windows: naming an effect needs at least {MIN_HELDOUT} "
                         "(the rank test cannot reach p <= 0.05 with fewer); use a longer recording or shorter windows")
    say(f"fitting the base model ({', '.join(base.effects) or 'minimal'})")
    iterations = lambda i, c: say(f"    iteration {i}: cost {c:.4g}")  # noqa: E731
    with phases("base fit"):
        current = _base_fit(predictor, base, options, say, iterations)
    signs = recorded_signs(predictor)
    held = creep(predictor, current)
    if held is not None and held.shown:
        signs[ROTOR_HOLDS] = held.describe()
    for text in signs.values():
        say(f"{text}; screened with the catalogue: {', '.join(opened_by(signs))}")
    initial = current
    final = None  # the robust final estimate (step 5), once made within the loop
    history = [current]
    steps: list[Step] = []
    unstable: dict[str, str] = {}
    stepped: set[str] = set()  # candidates a finer step did not help (``_refined``): not refined again
    rejected = ""  # why the last round's best candidate was not added, for the verdict
    unresolved: dict[str, float] = {}  # the last round's screens that ended above their reference
    clock = ScreenClock(options.max_rounds, phases)
    located: tuple = ()  # (structure, where) of the last residual located
    revisions = []  # revise.Revision
    search = options  # less the effects refused as stand-ins
    for k in range(1, options.max_rounds + 1):
        with phases("locate"):
            where = residual_location(predictor, current.structure)
        located = (current.structure, where)
        clock.round = k
        with phases("noise floor"):
            floor = noise_floor(predictor, current.structure)
        floor_cost = floor.cost()
        ref, screened, rest, above = _screen(predictor, current, where, search, say, clock, unstable, stepped, signs)
        if not screened:
            break
        with phases("acceptance tests"):
            choice, screen = _decide(predictor, ref, screened, options, floor_cost), "stand-ins held"
        far = floor.worst(current.nrmse_test)
        escalation = _escalation(choice, options, far, floor.explained(current.nrmse_test))
        if escalation is not None:
            why, second_look = escalation
            say(f"  best candidate {choice.best} {why}; screening again with every parameter free, "
                "from the model refitted")
            e_ref, e_screened, e_rest, e_above = _screen(predictor, current, where, search, say, clock, unstable,
                                                         stepped, signs, free_all=True)
            with phases("acceptance tests"):
                e_choice = second_look(predictor, e_ref, e_screened, e_rest, choice, options, floor_cost)
            if e_choice is not None:
                if e_ref.cost_test < current.cost_test:  # the same structure, fitted further
                    current = history[-1] = e_ref
                    initial = initial if steps else e_ref
                choice, ref, screened, rest, above, screen = e_choice, e_ref, e_screened, e_rest, e_above, "all free"
        generic = (generic_candidates(ref.structure, where, refused(revisions)) if choice.failed and options.generic
                   else ())
        generic_rejected = ""
        if generic:
            say(f"  no catalogued effect explains the located residual: screening the generic forms it "
                f"points to ({', '.join(generic)})")
            # as the catalogue was last screened: with every parameter free where the model missed
            # far above its floor, so the stand-ins the base fitted for the form do not hold it back
            g_ref, g_screened, g_rest, g_above = _screen(predictor, current, where,
                                                         dataclasses.replace(options, candidates=generic), say, clock,
                                                         unstable, stepped, free_all=escalation is not None)
            with phases("acceptance tests"):
                g_choice = _decide(predictor, g_ref, g_screened, options, floor_cost)
            if not g_choice.failed:
                choice, ref, screened, rest, above, screen = g_choice, g_ref, g_screened, g_rest, g_above, "generic form"
            else:
                generic_rejected = rejection(g_choice, "the best generic form")
                say(f"  {generic_rejected}")
        if choice.failed and options.pairs:
            from .pairs import pair_screen  # pairs builds on this module
            with phases("pair screen"):
                pair = pair_screen(predictor, ref, screened, rest, options, floor_cost, say)
            if pair is not None and not pair.failed:
                choice = pair  # its steps' screen says "together with" the other
        if choice.failed and choice.only_inconsistent and options.folds:
            with phases("second fold"):
                choice = second_fold(predictor, base, ref, choice, options, say)
        best, cand, gain = choice.best, choice.cand, choice.gain
        unresolved = above
        if choice.failed:
            rejected = rejection(choice) + (f"; {generic_rejected}" if generic_rejected else "")
            say(f"best candidate {best}: held-out cost {-100 * gain:+.1f} % "
                f"(abs {ref.cost_test - cand.cost_test:.3g}, paired p = {choice.consistency['p']:.3f} on "
                f"{choice.consistency['windows']}): not significant")
            if not steps and not current.robust and options.robust_final:
                # A least-squares base can be held by the few training windows it misses most
                # (breakaways a missing friction term shows in), far from what predicts the
                # rest; the screens start from it. Where its robust estimate (step 5's) predicts
                # the held-out windows better by as much as an addition must, the search runs
                # once more from there.
                say("the base refitted under the robust loss over windows")
                with phases("base fit, robust"):
                    final = _robust_kept(predictor, current, options, iterations, say)
                if final.cost_test < (1.0 - options.min_gain) * current.cost_test:
                    say("nothing passed from the least-squares base: searching again from its robust estimate")
                    current = initial = history[-1] = final
                    final = None
                    continue
            break
        rejected = ""  # a round before this one may have been searched again from
        alternatives, consistency = [a.replace(BUNDLE, ' + ') for a in choice.alternatives], choice.consistency
        tested_on, p_value = consistency["windows"], consistency["p"]
        keys = best.split(PAIR)
        say(f"adding {' and '.join(keys)} (held-out cost -{100 * gain:.1f} %, paired p = {p_value:.3g} on "
            f"{tested_on}), refitting")
        with phases("refit after addition, least squares"):
            refit = fit(predictor, _at_step(predictor, cand.structure, base.nominal.timestep), max_iter=options.fit_iter,
                        progress=iterations)
        if refit.cost_test > cand.cost_test:
            refit = cand  # keep the screened fit if the full refit wandered off on held-out data
        refit = restarted(predictor, refit, floor, options, say, iterations, phases)
        if options.robust_refit:
            # Least squares can stall in a local minimum with the new term (a play's dead zone);
            # the next round would then name a stand-in for the rest (step 4).
            with phases("refit after addition, robust"):
                robust, keep = _robust(predictor, refit, options, iterations)
            if keep:
                say(f"  robust refit: held-out cost {robust.cost_test:.4g} against least squares' "
                    f"{refit.cost_test:.4g}: kept")
                refit = robust
        added = [Step(
            effect=parts(key)[-1], prerequisites=list(parts(key)[:-1]), evidence=_evidence(key, where, signs),
            where=where,
            parameters={p.name: refit.structure.values[p.name] for e in parts(key) for p in EFFECTS[e].params},
            fit_before=current.nrmse_test, fit_after=refit.nrmse_test,
            gain=1.0 - refit.cost_test / current.cost_test,
            screened={k: v[0] for k, v in {**rest, **screened}.items()},
            alternatives=alternatives if len(keys) == 1 else [],
            consistency=consistency,
            screen=screen if len(keys) == 1 else f"{TOGETHER} {' + '.join(parts(other))}")
            for key, other in zip(keys, keys[::-1])]
        unresolved = {}  # screened against the model before this addition
        if options.revise:
            from .revise import one_of_pair, revise, stand_in  # revise builds on this module
            outcomes = []
            for step in added:
                with phases("stand-in guard"):
                    refusal, freer = stand_in(predictor, current, refit, step, steps + [s for s in added if s is not step],
                                              options, floor_cost, say,
                                              [r for r in revisions if r.kind == "stand-in" and not r.rebased])
                if refusal is not None:
                    say(f"  {step.effect} is not named: {refusal.reason}")
                    if len(added) == 2:
                        refusal = dataclasses.replace(refusal, beside=next(s.effect for s in added if s is not step))
                outcomes.append((step, refusal, freer))
            refusals = [r for _, r, _ in outcomes if r is not None]
            alone = one_of_pair(predictor, current, outcomes, options, floor_cost)
            if alone is not None:
                step, refit, refusal = alone
                say(f"  {refusal.effect} refused as a stand-in in the pair: {step.effect} kept alone (held-out cost "
                    f"-{100 * step.gain:.1f} %, paired p = {step.consistency['p']:.3g})")
                added, refusals = [step], [refusal]
            elif refusals and len(added) == 1 and freer is not None and \
                    freer.cost_test <= current.cost_test * (1.0 - options.min_gain) and \
                    not any(r.rebased and r.effect == added[0].effect for r in revisions):
                # The refusal judged the effect against a base stalled far from its optimum,
                # which the effect's fit only helped to leave: once more from there.
                refusals = [dataclasses.replace(refusals[0], rebased=True)]
                say(f"  the model without {added[0].effect}, refitted, predicts the held-out windows "
                    f"{100 * (1 - freer.cost_test / current.cost_test):.1f} % better than the base it was "
                    f"judged against: {added[0].effect} screened again from there")
            if refusals:
                revisions += refusals
                allowed = options.candidates or default_candidates(current.structure, signs)
                search = dataclasses.replace(options, candidates=tuple(e for e in allowed
                                                                       if e not in refused(revisions)))
            if refusals and alone is None:
                # A single step's freer refit is the same structure fitted further; a pair's is
                # the model with the other member, not the one this round extends.
                if len(added) == 1 and freer is not None and freer.cost_test < current.cost_test:
                    current = history[-1] = freer
                continue
        steps += added
        current = refit
        history.append(current)
        if options.revise:
            with phases("revision"):
                current, steps, done = revise(predictor, current, steps, where, search, floor_cost, say,
                                              refused(revisions))
            revisions += done
            if done:
                history.append(current)
    if options.robust_final and current.robust:
        say("final estimate: the last refit's, already under the robust loss over windows")
    elif options.robust_final:
        robust = final
        if robust is not None:
            say("final estimate: the base's, under the robust loss where kept (above)")
        else:
            say("final estimate: refitting under the robust loss over windows")
            # ``current`` is least squares' estimate, or the last addition's robust refit (step 4).
            with phases("final robust estimate"):
                robust = _robust_kept(predictor, current, options, iterations, say)
        if robust is not current:
            current = robust
            if steps:  # the last step's structure, re-estimated: the model "after"
                history[-1] = current
            else:
                history.append(current)
    # The named effects' intervals checked against the model, every interval widened by its
    # estimate's step bias (identify.fit.check_intervals).
    named = [name for s in steps for name in s.parameters]
    twin = Twin(predictor, current.structure)  # one free run for the intervals' bias and the floor
    with phases("interval check"):
        current = check_intervals(predictor, current, named, biased=list(current.intervals), twin=twin)
    current = with_held_noted(current, named)
    with phases("locate"):
        # The last round's model, unchanged since (nothing added, the final robust estimate not
        # kept): its residual is located already.
        final_where = located[1] if located and located[0] is current.structure else \
            residual_location(predictor, current.structure)
    say("noise floor: the final model's simulated twin of the recording")
    with phases("noise floor"):
        current, floor, explained = judged(predictor, current, twin)
    bounds = stand_ins(current)
    if explained:
        unresolved = {}
    revisions = standing(revisions, [s.effect for s in steps])
    verdict = _verdict(steps, initial, current, floor, explained, final_where, rejected, bounds, unresolved, revisions,
                       signs)
    say(f"spent: {phases.line()}")
    return Diagnosis(steps, initial, current, final_where, verdict,
                     predictor.rollouts - roll0, time.perf_counter() - t_start, history,
                     floor, explained, bounds, unstable, unresolved, revisions, phases.as_dict(), signs, open_starts)


def standing(revisions, named) -> list:
    """The ``revisions`` a diagnosis reports: a refusal against a stalled base
    (``Revision.rebased``) only where the screens from the better base did not decide otherwise
    (the effect among the ``named``, or refused again)."""
    decided = set(named) | set(refused(revisions))
    return [r for r in revisions if not (r.rebased and r.effect in decided)]


def refused(revisions) -> tuple[str, ...]:
    """The effects refused as stand-ins (``revise.stand_in``): not screened again, but those
    refused against a stalled base (``Revision.rebased``), once."""
    return tuple(r.effect for r in revisions if r.kind == "stand-in" and not r.rebased)


def with_held_noted(result: FitResult, names) -> FitResult:
    """``result`` with a warning for each of ``names`` (the named effects' parameters) that it
    did not fit: the final model can be a screen that held the rest at an earlier fit's values,
    kept where the refit with every parameter free predicted the held-out windows worse, and
    such a value has no interval of its own."""
    fitted = set() if result.at_optimum is None else set(result.at_optimum.names)
    held = [n for n in names if n not in fitted and n not in result.intervals]
    if not held:
        return result
    values = result.structure.values
    return dataclasses.replace(result, warnings=result.warnings + [
        f"{n} = {values[n]:.4g}: held at an earlier fit's value in the final fit, which fitted the rest (the "
        "refit with every parameter free predicted the held-out windows worse); no 95 % interval of its own"
        for n in held])


def stand_ins(result: FitResult) -> dict[str, str]:
    """{parameter: "lower" | "upper"} for the parameters the fit left on a bound
    (``FitResult.on_bound``): stand-ins for something the structure lacks, not estimates."""
    params = {p.name: p for p in result.structure.params}
    out = {}
    for name in result.on_bound:
        p = params[name]
        x = p.to_unit(result.structure.values[name])
        out[name] = "lower" if x - p.to_unit(p.lo) < p.to_unit(p.hi) - x else "upper"
    return out


# A screen whose least-squares training cost ends this factor above the model it extends did not
# converge: the candidate contains that model (a Bouc-Wen gear with mu = 1 is the linear spring, a
# play of zero width the rigid gear), so its own optimum is at most as high, to within its bounds;
# the screen says nothing against it. A screen that ends above it on the held-out windows only
# did converge: what it fitted does not carry over, which is evidence against it.
UNRESOLVED_RATIO = 1.02


def not_converged(ratios: dict[str, float]) -> dict[str, float]:
    """Of the screens' training costs over the model each extends ({candidate: ratio}), those
    UNRESOLVED_RATIO or more above it, worst first (unstable ones, NaN, as infinite)."""
    ratios = {k: r if np.isfinite(r) else float("inf") for k, r in ratios.items()}
    return dict(sorted(((k, r) for k, r in ratios.items() if r >= UNRESOLVED_RATIO), key=lambda kv: -kv[1]))


def _verdict(steps: list[Step], initial: FitResult, final: FitResult, floor: Floor, explained: bool,
             where: dict, rejected: str, stand_ins: dict[str, str], unresolved: dict[str, float] | None = None,
             revisions=(), signs=None) -> str:
    """One of the four verdicts (module doc), in one paragraph; ``revisions`` (``revise.Revision``):
    the swaps and removals that revised the named effects, and the effects refused as stand-ins;
    ``signs``: the recording's own (``recorded_signs``), stated where no named effect explains them."""
    found = {e for s in steps for e in s.effects}

    def rivals(step: Step) -> str:  # rivals found later are no longer alternatives
        alt = [a for a in step.alternatives if parts(a.replace(" + ", BUNDLE))[-1] not in found]
        return f" (or, indistinguishable here, {' / '.join(alt)})" if alt else ""
    named = ", ".join(s.label + rivals(s) for s in steps)
    if steps and explained:
        text = f"missing physics found: {named}; with it the recording is explained to the noise"
    elif steps:
        text = (f"missing physics found: {named}; a mismatch remains: {mismatch(final, floor, where)}"
                + (f"; {rejected}" if rejected else ""))
    elif explained:
        text = "explained to the noise: nothing is missing" + (f"; {rejected}" if rejected else "")
    else:
        text = (f"unexplained: no catalogued effect explains the mismatch: {mismatch(final, floor, where)}"
                + (f"; {rejected}" if rejected else ""))
    if steps:
        text += f" (held-out cost {initial.cost_test:.4g} -> {final.cost_test:.4g})"
    if unresolved and not explained:
        # "No catalogued effect explains it" holds only for the candidates whose fits converged.
        text += ("; not ruled out, their screens ended above the model they extend (fits that did not "
                 "converge): " + ", ".join(f"{k.replace(BUNDLE, ' + ')} (" + (
                     f"{r:.3g}x its training cost" if np.isfinite(r) else
                     "its prediction unstable at the finest step tried, unstable_screens says why") + ")"
                     for k, r in unresolved.items()))
    revised = [r.line for r in revisions if r.kind != "stand-in"]
    if revised:
        text += "; revised: " + "; ".join(revised)
    refusals = [r.line for r in revisions if r.kind == "stand-in"]
    if refusals:
        text += "; not named, stand-ins: " + "; ".join(refusals)
    if stand_ins:
        text += ("; on a bound, stand-ins rather than estimates: "
                 + ", ".join(f"{k} = {final.structure.values[k]:.4g} ({v})" for k, v in stand_ins.items()))
    for sign, description in (signs or {}).items():
        if not any(sign in EFFECTS[e].evidence for e in found):
            text += f"; unexplained by the model, {description}"
    return text


def mismatch(final: FitResult, floor: Floor, where: dict) -> str:
    """Which signals miss by how much against their floor, and where the worst one does."""
    ratios = floor.ratios(final.nrmse_test)
    over = sorted((s for s, r in ratios.items() if not r <= EXPLAINED_RATIO), key=lambda s: -ratios[s])
    if not over:
        return "none above the noise floor"
    nf = floor.nrmse
    capped = [s for s in over if s in floor.capped]
    # A signal the fit does not score (``--fit-signals``) is judged too, but its miss is no fit's
    # aim; the link angle is scored through the deflection q/N - theta.
    scored = set(floor.scored) | ({"theta"} if "delta" in floor.scored else set())
    unscored = [s for s in over if floor.scored and s not in scored]
    signals = ", ".join(f"{s} held-out NRMSE {final.nrmse_test[s]:.3g} against a floor of {nf[s]:.3g}"
                        + (f" (its twin {floor.twin[s]:.3g})" if s in capped else "")
                        + (" (a signal the fit does not score)" if s in unscored else "") for s in over)
    if capped:  # a model whose own twin misses about as much may be right but for its windows' starts
        signals += (f" (a floor counts the model's own twin up to {WINDOWING_TRUST:g}x the recording's noise; "
                    "its window starts may cost the model as much, so part of the rest may be theirs, not "
                    "missing physics)")
    loc = where.get("signals", {}).get(over[0], {})
    conds = [c["description"] for c in loc.get("conditions", []) if c.get("significant")]
    spans = loc.get("windows", [])[:3]
    at = ", ".join(f"{a:.2f}-{b:.2f} s" for a, b, _ in spans)
    rotor = [c["description"] for c in where.get("signals", {}).get(BALANCE, {}).get("conditions", [])
             if c.get("significant")]
    return (signals + (f"; {over[0]}'s residual concentrates {'; '.join(conds)}" if conds else
                       f"; {over[0]}'s residual concentrates under no condition looked at")
            + (f"; largest at {at}" if at else "")
            + (f"; the rotor's torque balance (the input less a rigid rotor's, under the recorded gear torque) "
               f"is {'; '.join(rotor)}" if rotor else ""))


TIE_SHARE = 0.9  # a candidate explaining >= 90 % of the best one's held-out gain is a rival
# A gear effect that misfits the recorded gear law at most this share as much as the best gear
# effect does is named instead (``_by_gear_law``): a clear difference, not the noise of a fit.
GEAR_LAW_SHARE = 0.5


def _robust(predictor: Predictor, result: FitResult, options: DiagnoseOptions, progress) -> tuple[FitResult, bool]:
    """``result``'s structure refitted under the robust loss over windows, and whether to keep
    it: only if it predicts the held-out windows better, the test every refit passes. The robust
    loss cannot tell a window no model explains from one where physics outside the catalogue
    acts: on EMPS (backward viscous slope 231 against 155 N s/m forward) it discounted the
    backward windows, Fv fell to the forward slope, held-out cost +72 %."""
    robust = fit(predictor, result.structure, max_iter=options.fit_iter, progress=progress, robust=True)
    return robust, robust.cost_test < result.cost_test


def _robust_kept(predictor: Predictor, result: FitResult, options: DiagnoseOptions, progress=None,
                 say=None) -> FitResult:
    """``result`` refitted under the robust loss (``_robust``) where that is kept, else ``result``
    itself; ``say``, if given, hears which."""
    robust, keep = _robust(predictor, result, options, progress)
    if say is not None:
        say(f"robust estimate: held-out cost {robust.cost_test:.4g} against the current estimate's "
            f"{result.cost_test:.4g}: {'kept' if keep else 'not kept'}")
    return robust if keep else result


# Two-stage screening (``_screen``): every candidate is fitted on the seeded share of the
# training windows (the first LM phase of a fit, ``identify.fit``) and scored on the held-out
# windows. The best one goes on over all training windows, and so do the others that predict
# better than the model itself fitted the same way (the null) by at least CONTINUE_SHARE of what
# the best gains on it, at most CONTINUE_MAX in all. Finished, a screen is the whole fit's result
# bit for bit (``identify.fit.finish``), so the acceptance tests see what a full screen gives;
# the candidates left on the subset had no chance to be named or to tie with the one that is.
# A smaller share than the fit's (an eighth) finished and named a false torque ripple beside a
# backlash (CHANGELOG).
CONTINUE_SHARE = 0.5
CONTINUE_MAX = 3


def _screen(predictor: Predictor, current: FitResult, where: dict, options: DiagnoseOptions, say,
            clock: ScreenClock, unstable: dict[str, str], stepped: set[str], signs=(), free_all: bool = False
            ) -> tuple[FitResult, dict[str, tuple[float, FitResult]], dict[str, tuple[float, FitResult]],
                       dict[str, float]]:
    """(the fit candidates are held against, {effect: (held-out cost, fit)} of the screens
    finished over all training windows, the same of those left on the subset, {effect: training
    cost over the model it extends} of the screens that did not converge (``not_converged``)) of
    one screening.

    ``signs``: the recording's (``recorded_signs``), which open the screen to the effects on
    request that declare them (``opened_by``). Held stand-ins (default): each candidate frees
    ``screened_params`` and is held against the current fit. ``free_all``: the current structure
    is first refitted with every parameter free (``fit_iter`` iterations more: a fit that had
    not converged would otherwise credit any
    flexible candidate with the rest of its descent), and each candidate frees every parameter
    from there and is held against that refit (module doc). A screen whose prediction is
    unstable is screened again at the timestep its stability check asks for, and why it was goes
    to ``unstable``; one that ends far above the null it nests, at finer steps (``_refined``; a
    candidate that gains nothing there goes to ``stepped`` and is not refined again); one whose
    training cost ends above where the null started (the model it extends), from other starts
    (``_restarted_screen``).
    Screens run in two stages (CONTINUE_SHARE); a screen left on the subset reports the held-out
    cost of the reference scaled by its subset cost over the null's.
    """
    ref = current
    if free_all:
        with clock.phases("screens, reference refitted"):
            ref = fit(predictor, current.structure, max_iter=options.fit_iter)
        say(f"  reference, the model refitted: held-out cost {current.cost_test:.4g} -> {ref.cost_test:.4g}")
    names = candidates_for(ref.structure, options.candidates, predictor.signals, signs)
    opened = opened_by(signs)
    trials = [(name, values, settings) for name in names
              for values, settings in _candidate_variants(parts(name)[-1], where, ref.structure)]
    say(f"round {clock.round} of {clock.rounds}: screening {len(trials)} candidate fits"
        + (" with every parameter free" if free_all else "") + ", first on a subset of the windows")
    if not trials:
        return ref, {}, {}, {}
    base_names = None if free_all else [p.name for p in base_params(ref.structure.nominal)]
    with clock.phases("screens, subset"):
        null = fit(predictor, ref.structure, base_names, max_iter=options.screen_iter, subset_only=True)
    firsts: list[FitResult] = []
    starts: list[Structure] = []
    descending: list[int] = []  # screens taken to a finer step or another start that still descend (``continued``)
    best_of: dict[str, FitResult] = {}  # each candidate's best subset screen so far (``_nested``)
    # Candidates (with their settings) already fitted from other starts: a variant that differs
    # only in its own parameters' start would draw the same starts again (``restart_points``).
    restarted: set[tuple] = set()
    for i, (name, values, settings) in enumerate(trials, 1):
        start = time.perf_counter()
        trial = with_candidate(ref.structure, name, values, settings)
        freed = None if free_all else screened_params(name, ref.structure)
        with clock.phases("screens, subset"):
            res = fit(predictor, trial, freed, max_iter=options.screen_iter, subset_only=True)
            if not res.cost_test < UNSTABLE_COST:
                unstable[name], again = _instability(trial)
                if again is trial:  # values the model refuses: no step helps
                    say(f"  screened {name}: unstable prediction ({unstable[name]})")
                else:
                    say(f"  screened {name}: unstable prediction ({unstable[name]}); again at timestep "
                        f"{again.nominal.timestep:.3g} s")
                    res = fit(predictor, again, freed, max_iter=options.screen_iter, subset_only=True)
            elif (res.cost_test > FAR_ABOVE_NULL * null.cost_test and name not in stepped
                  and not all(EFFECTS[e].step_resolved for e in parts(name))):
                res, trial = _refined(predictor, trial, res, freed, options, null.cost_test, name, say, stepped)
                if name not in stepped and res.coarse_capped:
                    descending.append(i - 1)
            tried, how = trial, ""
            res, trial = _nested(predictor, name, values, settings, res, trial, best_of, freed, options)
            if trial is not tried:
                how = ", started from its prerequisites' screen"
            key = (name, tuple(sorted(settings.items())))
            # An unstable prediction is the step's (``unstable``), not the start's: no restart.
            if (key not in restarted and res.cost_test < UNSTABLE_COST
                    and training_ratio(predictor, res, null, from_start=True) >= UNRESOLVED_RATIO):
                restarted.add(key)
                res, again = _restarted_screen(predictor, name, res, trial, freed, options, null, say)
                if again is not trial:
                    how = ", from another start"
                    if (res.coarse_capped and i - 1 not in descending
                            and training_ratio(predictor, res, null, from_start=True) < 1.0):
                        descending.append(i - 1)
                trial = again
        if res.coarse_capped and parts(name)[-1] in opened and i - 1 not in descending:
            descending.append(i - 1)
        if name not in best_of or res.cost_test < best_of[name].cost_test:
            best_of[name] = res
        clock.record(time.perf_counter() - start)
        firsts.append(res)
        starts.append(trial)
        label = f"{name} {settings}" if settings else name
        say(f"  screened {label} on the subset: held-out cost {null.cost_test:.4g} -> {res.cost_test:.4g}"
            + (", still descending at the iteration cap" if res.coarse_capped else "")
            + how
            + f" ({clock.status(i, len(trials))})")
    go_on = continued([r.cost_test for r in firsts], null.cost_test, [t[0] for t in trials], descending)
    screened: dict[str, tuple[float, FitResult]] = {}
    for i in go_on:
        name, _, settings = trials[i]
        with clock.phases("screens, finish"):
            res = finish(predictor, firsts[i])
            if not res.cost_test < UNSTABLE_COST and name not in unstable:
                unstable[name], again = _instability(starts[i])
                if again is not starts[i]:
                    res = fit(predictor, again, None if free_all else
                              screened_params(name, ref.structure), max_iter=options.screen_iter)
        if name not in screened or res.cost_test < screened[name][0]:
            screened[name] = (res.cost_test, res)
        label = f"{name} {settings}" if settings else name
        say(f"  screened {label} on all windows: held-out cost {ref.cost_test:.4g} -> {res.cost_test:.4g}")
    # The screens left on the subset: their held-out cost scaled as a finished screen's would be,
    # and the best variant's subset fit (its settings: a ripple's harmonic).
    rest: dict[str, tuple[float, FitResult]] = {}
    for (name, _, _), res in zip(trials, firsts):
        if name not in screened:
            cost = ref.cost_test * res.cost_test / null.cost_test if null.cost_test > 0 else res.cost_test
            if cost < rest.get(name, (np.inf, None))[0]:
                rest[name] = (cost, res)
    ratios = {**{k: training_ratio(predictor, res, null, from_start=True) for k, (_, res) in rest.items()},
              **{k: training_ratio(predictor, res, ref) for k, (_, res) in screened.items()}}
    ratios.update({k: np.inf for k, (_, res) in {**rest, **screened}.items() if not res.cost_test < UNSTABLE_COST})
    return ref, screened, rest, not_converged(ratios)


def continued(costs: list[float], null: float, names: list[str], descending=()) -> list[int]:
    """Which subset screens (held-out ``costs``, against the ``null``'s) go on over all windows
    (CONTINUE_SHARE): the best, and those that gain on the null at least CONTINUE_SHARE of what the
    best gains, at most CONTINUE_MAX; with each bundle the prerequisite screened alone, which
    ``_decide`` prefers when it passes. The ``descending`` go on too: screens a finer step brought
    near the null, or another start below it in training (``_restarted_screen``), whose subset
    phase still descended at its iteration cap, so their subset point ranks nothing (a rod's
    modes, started at the located resonance, end far from there); so do those a sign opened that
    still descended (the exact sign, from a creeping base's values)."""
    order = sorted(range(len(costs)), key=lambda i: costs[i] if np.isfinite(costs[i]) else np.inf)
    gains = [null - c if np.isfinite(c) else -np.inf for c in costs]
    best = gains[order[0]]
    keep = [order[0]] + [i for i in order[1:CONTINUE_MAX] if gains[i] > 0 and gains[i] >= CONTINUE_SHARE * best]
    keep += [i for i in descending if i not in keep]
    for i in list(keep):
        alone = BUNDLE.join(parts(names[i])[:-1])
        keep += [j for j, n in enumerate(names) if alone and n == alone and j not in keep]
    return sorted(keep)


# A screen whose training cost ends UNRESOLVED_RATIO above the model it extends did not converge
# (module doc); it is fitted again from this many seeded starts of the candidate's own
# parameters (``identify.fit.restart_points``), the lowest training cost kept.
SCREEN_RESTARTS = 3


def _restarted_screen(predictor: Predictor, name: str, res: FitResult, trial: Structure, freed,
                      options: DiagnoseOptions, null: FitResult, say) -> tuple[FitResult, Structure]:
    """(the subset screen, its start) of candidate ``name``, whose training cost ended
    UNRESOLVED_RATIO or more above the model it extends (where the ``null`` started): fitted
    again from SCREEN_RESTARTS starts of its own parameters, the others where ``trial`` has them;
    the lowest training cost kept (the held-out windows stay for the acceptance tests)."""
    own = [p.name for e in parts(name) for p in EFFECTS[e].params]
    if not own:
        return res, trial
    starts = restart_points(trial, own, SCREEN_RESTARTS, predictor.design.seed)
    fits = fits_from(predictor, starts, freed, max_iter=options.screen_iter, subset_only=True)
    best = lowest([res] + fits)
    ratio = lambda r: training_ratio(predictor, r, null, from_start=True)  # noqa: E731
    say(f"  screened {name}: training cost {ratio(res):.3g}x the model it extends, a fit that did not converge; "
        f"the best of {len(starts)} other starts {ratio(best):.3g}x")
    return best, next((s for s, f in zip(starts, fits) if f.structure is best.structure), trial)


def _nested(predictor: Predictor, name: str, values: dict, settings: dict, res: FitResult, trial: Structure,
            best_of: dict[str, FitResult], freed, options: DiagnoseOptions) -> tuple[FitResult, Structure]:
    """(the screen, its start) of bundle ``name``, fitted again from its prerequisites' own screen
    where it ended above it: a bundle nests its prerequisites (its effect at zero is them), so
    ending above them is a fit that stalled, not evidence. From their optimum, the effect at
    its start, the bundle begins where they ended. The lower screen is kept."""
    *needed, effect = parts(name)
    prior = best_of.get(BUNDLE.join(needed))
    if not needed or prior is None or not res.cost_test > prior.cost_test:
        return res, trial
    own = {p.name for p in EFFECTS[effect].params}
    again = prior.structure.with_effect(effect, {k: v for k, v in values.items() if k in own}, settings)
    res2 = fit(predictor, again, freed, max_iter=options.screen_iter, subset_only=True)
    return (res2, again) if res2.cost_test < res.cost_test else (res, trial)


# A model that misses its worst signal by this many times the signal's noise floor (held-out
# NRMSE) holds stand-ins: the terms it has were bent toward what it lacks (a rigid link's fit
# of a flexible rod's recording: gravity and the tip mass far below the truth, 2SEP's K on its
# bound), and a candidate screened with those held cannot show its gain. Where nothing passes,
# the screen is repeated with every parameter free, as for a gain the rank test alone refuses;
# a refit after an addition that still holds a parameter on a stand-in bound is tried again from
# the recording's start (``restarted``).
FAR_FROM_FLOOR = 10.0


UNSTABLE_COST = 1e5  # a held-out cost this high holds predictions that diverged (identify.fit._BAD)
# An unstable screen is retried at the timestep its stability check asks for, at most this many
# times finer than the plant's: a stiff term a fit ran into (a gear damper on a flexible rod's
# light hub) needs the step the check names, where half of it left the screen unstable.
MAX_REFINE = 16


# A subset screen this many times above the null it nests has not fitted: where the plant's step
# does not resolve the candidate's term (``Effect.step_resolved``: a flexible rod's modes, stable
# but inaccurate at 0.5 ms on out-of-regime flexible_rod seed 1) a finer step fits it.
FAR_ABOVE_NULL = 2.0


def _refined(predictor: Predictor, trial: Structure, res: FitResult, freed, options: DiagnoseOptions,
             null_cost: float, name: str, say, stepped: set[str]) -> tuple[FitResult, Structure]:
    """(the subset screen, its start structure) of candidate ``name``: ``res``, ended FAR_ABOVE_NULL
    times above the null it nests, fitted again from ``trial``'s start at half the step while that
    lowers its held-out cost by ``min_gain`` and it still ends that far above, down to
    1/MAX_REFINE of the plant's step. A candidate that still ends that far above goes to
    ``stepped``: the step is not what fails it, and later rounds do not refine it again."""
    h0 = trial.nominal.timestep
    while res.cost_test > FAR_ABOVE_NULL * null_cost and trial.nominal.timestep > h0 / MAX_REFINE:
        finer = trial.at_timestep(trial.nominal.timestep / 2.0)
        again = fit(predictor, finer, freed, max_iter=options.screen_iter, subset_only=True)
        say(f"  screened {name}: held-out cost {res.cost_test:.4g}, {res.cost_test / null_cost:.3g}x the model it "
            f"extends, at timestep {trial.nominal.timestep:.3g} s; {again.cost_test:.4g} at {finer.nominal.timestep:.3g} s")
        if not again.cost_test < (1.0 - options.min_gain) * res.cost_test:
            break
        res, trial = again, finer
    if res.cost_test > FAR_ABOVE_NULL * null_cost:
        stepped.add(name)
    return res, trial


def _instability(structure: Structure) -> tuple[str, Structure]:
    """(why a structure's prediction diverged, in one line; the structure at the timestep its
    stability check asks for, a power-of-two share of the plant's down to 1/MAX_REFINE, or half
    of it where the check finds no term too stiff)."""
    from ..identify.windows import _compile
    try:
        model = _compile(*structure.model_params())
    except ValueError as err:  # values the model refuses: no step makes them valid
        return f"the model refuses its values: {err}", structure
    try:
        check_model_stability(model, hint="the plant's timestep")
    except ValueError as err:
        needed = min(h for h, _ in stable_timesteps(model).values())
        share = 2.0 ** min(math.ceil(math.log2(model.opt.timestep / needed)), math.log2(MAX_REFINE))
        return str(err), structure.at_timestep(model.opt.timestep / share)
    return "the simulation diverged from the window starts", structure.at_timestep(model.opt.timestep / 2.0)


def _base_fit(predictor: Predictor, base: Structure, options: DiagnoseOptions, say, iterations) -> FitResult:
    """The base fitted; where its prediction diverges (a start too stiff for the plant's step:
    the LM cannot move from predictions that are all NaN, and every screen would be judged
    against them), fitted again at the timestep its stability check asks for, and from there
    at the plant's step where its fitted values are stable there (``_at_step``)."""
    result = fit(predictor, base, max_iter=options.fit_iter, progress=iterations)
    if result.cost_test < UNSTABLE_COST:
        return result
    why, finer = _instability(base)
    if finer is base:  # values the model refuses: no step helps
        return result
    say(f"  the base model's prediction diverged ({why}); fitted again at timestep {finer.nominal.timestep:.3g} s")
    result = fit(predictor, finer, max_iter=options.fit_iter, progress=iterations)
    back = _at_step(predictor, result.structure, base.nominal.timestep)
    if back is result.structure:
        return result
    say(f"  its fitted values are stable at timestep {base.nominal.timestep:.3g} s: fitted on there")
    coarse = fit(predictor, back, max_iter=options.fit_iter, progress=iterations)
    if not coarse.cost_test < UNSTABLE_COST:
        return result
    return _off_the_floor(predictor, coarse, base, options, say, iterations)


# A parameter within this factor of its physical lower bound is fitted to nearly nothing
# (``_off_the_floor``): a decade above the least the model resolves.
FLOOR_FACTOR = 10.0


def _off_the_floor(predictor: Predictor, result: FitResult, start: Structure, options: DiagnoseOptions, say,
                   iterations) -> FitResult:
    """``result``, or the fit again with the parameters it ran down to a physical lower bound
    back at their ``start`` values, where that reaches the lower training cost. A fit from a
    start its step cannot hold takes its first steps far from any plant and can run a term to
    nothing on the way; in log coordinates the gradient along such a parameter vanishes at
    its floor, and no LM step brings it back."""
    floored = [n for n in result.structure.near_physical_floor(FLOOR_FACTOR)
               if n not in start.near_physical_floor(FLOOR_FACTOR)]
    if not floored:
        return result
    again = fit(predictor, result.structure.with_values({n: start.values[n] for n in floored}),
                max_iter=options.fit_iter, progress=iterations)
    kept = lowest([result, again])
    say(f"  {', '.join(floored)} fitted to nothing: fitted again from its start, training cost "
        f"{result.cost_train:.4g} -> {again.cost_train:.4g}: "
        + ("kept" if kept.structure is again.structure else "not kept"))
    return kept


def restarted(predictor: Predictor, result: FitResult, floor: Floor, options: DiagnoseOptions, say,
               iterations, phases: Phases) -> FitResult:
    """``result``, or the same structure fitted from the recording's initial values where that
    reaches the lower training cost; tried only where ``result`` holds a parameter on a bound that
    marks a stand-in and misses its worst signal by FAR_FROM_FLOOR times its noise floor. A refit
    after an addition starts where the model without it ended, with every term it has bent toward
    what it lacked, and the new term can leave the old ones in that bent valley
    (docs/diagnosis.md, step 4)."""
    far = floor.worst(result.nrmse_test)
    if not result.on_bound or far <= FAR_FROM_FLOOR:
        return result
    starts = restart_points(result.structure, None, 1, predictor.design.seed)
    if not starts:
        return result
    with phases("refit after addition, from the recording's start"):
        (again,) = fits_from(predictor, starts, max_iter=options.fit_iter, progress=iterations)
    kept = lowest([result, again])
    say(f"  {', '.join(result.on_bound)} on a bound {far:.3g} times the noise floor away: refitted from the "
        f"recording's start, training cost {result.cost_train:.4g} -> {again.cost_train:.4g} "
        f"(held-out {result.cost_test:.4g} -> {again.cost_test:.4g}): "
        f"{'kept' if kept.structure is again.structure else 'not kept'}")
    return kept


def _at_step(predictor: Predictor, structure: Structure, timestep: float) -> Structure:
    """``structure`` back at the plant's ``timestep`` where a screen refined it (``_instability``)
    and its fitted values are stable there (a gear damper the screen brought down): every later
    round would otherwise run at the finer step."""
    if structure.nominal.timestep >= timestep:
        return structure
    coarse = structure.at_timestep(timestep)
    return coarse if predictor.stable(coarse) else structure


@dataclass
class _Choice:
    best: str
    cand: FitResult
    gain: float
    alternatives: list[str]
    consistency: dict
    failed: list[str]  # the acceptance tests the best candidate fails; empty: it is named
    only_inconsistent: bool  # material and BIC-supported, failing only the rank test


def rejection(choice: _Choice, what: str = "the best candidate") -> str:
    """Why a round's best candidate (``what``) was not named, for the verdict; where only the rank
    test refused a material gain, how many held-out windows it had."""
    text = (f"{what}, {choice.best}, {'lowers' if choice.gain >= 0 else 'raises'} the held-out cost by "
            f"{100 * abs(choice.gain):.1f} % but fails: {', '.join(choice.failed)}")
    if choice.only_inconsistent:
        folds = " of two folds" if choice.consistency.get("folds") == 2 else ""
        text += (f" on {choice.consistency['n']} held-out windows{folds} (a longer recording, with more of them, "
                 "would decide)")
    return text


def _decide(predictor: Predictor, ref: FitResult, screened: dict[str, tuple[float, FitResult]],
            options: DiagnoseOptions, floor_cost: float, max_p: float | None = None) -> _Choice:
    """The best screened candidate against ``ref`` and the acceptance tests it fails (module doc);
    ``floor_cost``: the noise floor in cost units; ``max_p``: the rank test's level, if not
    ``options.max_p``.

    A bundle opens the path to an effect behind a prerequisite; it does not name that effect
    while the prerequisite alone passes: then the prerequisite is named, and the effect behind
    it screened against it next round (a friction asymmetry bundled with the Coulomb friction it
    shifts would otherwise stand in for any direction-dependent force at once). A passing sensor
    effect gives way to passing physics (``_physics_first``), and a gear effect to one that fits
    the gear's recorded law better (``_by_gear_law``).
    """
    max_p = options.max_p if max_p is None else max_p
    best, alternatives = _choose(screened, ref.cost_test)
    *needed, _ = parts(best)
    alone = BUNDLE.join(needed)
    if alone in screened:
        first = _assess(predictor, ref, screened, alone, [], options, floor_cost, max_p)
        if not first.failed:
            return first
    choice = _assess(predictor, ref, screened, best, alternatives, options, floor_cost, max_p)
    choice = _physics_first(predictor, ref, screened, choice, options, floor_cost, max_p)
    return _by_gear_law(predictor, ref, screened, choice, options, floor_cost, max_p)


def _physics_first(predictor: Predictor, ref: FitResult, screened: dict[str, tuple[float, FitResult]],
                   choice: _Choice, options: DiagnoseOptions, floor_cost: float, max_p: float) -> _Choice:
    """A passing sensor effect screened by default gives way to the best physics candidate that
    passes too. A sensor effect says the recording is wrong; one that shifts a signal in time
    takes up any physics that lags (a link encoder's skew reads as a gear's damper, a bearing, a
    frictional lag) and gains where several terms are still missing (the shipped arm's
    hysteretic route: a skew of 83 us against none recorded, the damper, 2SEP and the bearing
    each passing beside it). Named after the physics, it is screened again next round against
    the model that holds it, where a real skew still passes and the revision's removal drops a
    physics term it stood for. One screened on request (``Effect.on_request``: the torque
    sensor's, opened by a sign of the recording no physics gives) keeps its place."""
    if choice.failed or not _by_default_sensor(choice.best):
        return choice
    physics = sorted((k for k in screened if EFFECTS[parts(k)[-1]].site != "sensor"
                      and screened[k][0] < ref.cost_test), key=lambda k: screened[k][0])
    for key in physics:
        other = _assess(predictor, ref, screened, key, [], options, floor_cost, max_p)
        if not other.failed:
            other.consistency["windows"] += (
                f"; named before {choice.best.replace(BUNDLE, ' + ')} (held-out cost {screened[choice.best][0]:.4g}, "
                "a sensor effect, screened again once it is in)")
            return other
    return choice


def _escalation(choice: _Choice, options: DiagnoseOptions, far: float, explained: bool):
    """(why, second look) where the round is screened once more with every parameter free from
    the model refitted (module doc, step 3), or None. The second look, called as
    ``look(predictor, ref, screened, rest, choice, options, floor_cost)`` on that screening, gives
    the choice that replaces this round's, or None to keep it. Each look at half the level keeps
    the pair at max_p (Bonferroni), so a second look cannot raise the false-addition rate."""
    if not options.free_all:
        return None
    if choice.failed and (choice.only_inconsistent or far > FAR_FROM_FLOOR):
        why = (f"fails only the rank test ({choice.failed[0]})" if choice.only_inconsistent else
               f"fails while the model misses {far:.3g} times its noise floor")
        return why, _second_look
    if not choice.failed and _by_default_sensor(choice.best) and not explained:
        return f"is a sensor effect while the model misses {far:.3g} times its noise floor", _freed_physics
    if not choice.failed and choice.alternatives and not explained:
        rivals = ", ".join(a.replace(BUNDLE, " + ") for a in choice.alternatives)
        return (f"passes with rivals the held-out windows cannot tell apart from it ({rivals}) while the model "
                f"misses {far:.3g} times its noise floor"), _freed_rival
    return None


def _second_look(predictor: Predictor, ref: FitResult, screened: dict[str, tuple[float, FitResult]],
                 rest: dict[str, tuple[float, FitResult]], failed: _Choice, options: DiagnoseOptions,
                 floor_cost: float) -> _Choice:
    """The choice of the screens with every parameter free (against ``ref``) where the
    round's ``failed``: the same question, asked of fits that may bend every term."""
    return _decide(predictor, ref, screened, options, floor_cost, options.max_p / 2)


def _by_default_sensor(key: str) -> bool:
    """Whether candidate ``key`` names a sensor effect screened by default (not on request)."""
    effect = EFFECTS[parts(key)[-1]]
    return effect.site == "sensor" and not effect.on_request


def _freed_physics(predictor: Predictor, ref: FitResult, screened: dict[str, tuple[float, FitResult]],
                   rest: dict[str, tuple[float, FitResult]], sensor: _Choice, options: DiagnoseOptions,
                   floor_cost: float) -> _Choice | None:
    """The physics candidate to name instead of ``sensor``, a passing sensor effect screened by
    default while the model misses its noise floor, from the screens with every parameter free
    (``screened`` against ``ref``; ``rest``: those left on the subset), or None. Held stand-ins
    can keep every physics screen from passing where several terms are missing (a bearing's
    screen that holds gravity and the rod bent toward it ends above the model it extends, while
    a link encoder skew takes up its lag). The physics passes at half the level (a second look,
    as the escalation's) and predicts the held-out windows at least as well as the sensor effect
    fitted the same way (its subset estimate where its screen was not finished), so a real skew,
    which no physics term reproduces, keeps its place."""
    return _freed_choice(predictor, ref, screened, rest, options, floor_cost, _by_default_sensor, [sensor.best],
                         f"{sensor.best.replace(BUNDLE, ' + ')} (a sensor effect, screened again once it is in)")


def _freed_rival(predictor: Predictor, ref: FitResult, screened: dict[str, tuple[float, FitResult]],
                 rest: dict[str, tuple[float, FitResult]], tied: _Choice, options: DiagnoseOptions,
                 floor_cost: float) -> _Choice | None:
    """The candidate to name instead of ``tied``, a passing candidate with rivals the held-out
    windows cannot tell apart from it (``_choose``) while the model misses its noise floor, from
    the screens with every parameter free, or None. Unrelated terms that gain alike show that
    something is missing, not what: each takes up the share of it that its form has (an input
    offset and a friction and a viscous asymmetry, forces that push one way more than the other,
    for a hysteretic gear whose own screen, the gear's stand-ins held, gained nothing). Another
    candidate is named where it passes at half the level and predicts the held-out windows at
    least as well as each of the tied fitted the same way; where one of them wins there too,
    the choice stands."""
    keys = [tied.best, *tied.alternatives]
    return _freed_choice(predictor, ref, screened, rest, options, floor_cost, keys.__contains__, keys,
                         f"{tied.best.replace(BUNDLE, ' + ')} and its rivals (a gain they share, screened again "
                         "once it is in)")


def _freed_choice(predictor: Predictor, ref: FitResult, screened: dict[str, tuple[float, FitResult]],
                  rest: dict[str, tuple[float, FitResult]], options: DiagnoseOptions, floor_cost: float,
                  excluded, rivals: list[str], before: str) -> _Choice | None:
    """The choice of the screens with every parameter free (``screened`` against ``ref``;
    ``rest``: those left on the subset) at half the level, where it passes, is not ``excluded``
    and predicts the held-out windows at least as well as each of ``rivals`` fitted the same way
    (a subset estimate where its screen was not finished); else None. ``before``: what it is
    named before, for its evidence."""
    choice = _decide(predictor, ref, screened, options, floor_cost, options.max_p / 2)
    pool = {**rest, **screened}
    rival = min(pool.get(k, (np.inf, None))[0] for k in rivals)
    if choice.failed or excluded(choice.best) or not choice.cand.cost_test <= rival:
        return None
    choice.consistency["windows"] += f"; named before {before}"
    return choice


def _by_gear_law(predictor: Predictor, ref: FitResult, screened: dict[str, tuple[float, FitResult]],
                 choice: _Choice, options: DiagnoseOptions, floor_cost: float, max_p: float) -> _Choice:
    """Between effects at the gear, the gear's recorded law decides (``gear_law``): a passing
    gear effect gives way to another gear candidate that leaves at most GEAR_LAW_SHARE of its
    misfit of the recorded torque against the recorded deflection and passes every test but,
    at most, the rank test. The passing one has shown, window by window, that the gear misses
    something; which law it misses is what the recording measures directly. Physics missing
    elsewhere (a current loop's lag) moves the held-out cost and its consistency over windows,
    and the law, measured without simulating, not at all (a 1.3 mrad play behind such a lag:
    the hardening cubic's held-out cost 0.218 at p 0.016, the play's 0.270 at p 0.16, the
    play's misfit of the law 0.008 of the linear gear's, the cubic's 0.163)."""
    law = choice.consistency.get("gear_law_ratio")
    if choice.failed or law is None or EFFECTS[parts(choice.best)[-1]].site != "gear":
        return choice
    ratios = {}
    for key, (cost, result) in screened.items():
        if key == choice.best or cost >= ref.cost_test:
            continue
        r = law_ratio(predictor, ref.structure, result.structure, EFFECTS[parts(key)[-1]].site)
        if r is not None and r < GEAR_LAW_SHARE * law:
            ratios[key] = r
    for key in sorted(ratios, key=ratios.get):
        other = _assess(predictor, ref, screened, key, [], options, floor_cost, max_p)
        if not other.failed or other.only_inconsistent:
            other.consistency["windows"] += (
                f"; chosen over {choice.best.replace(BUNDLE, ' + ')} (held-out cost {screened[choice.best][0]:.4g}, "
                f"paired p {choice.consistency['p']:.3g}) by the recorded gear law, which it misfits "
                f"{ratios[key]:.3g} times as much as the model does, against {law:.3g}")
            return dataclasses.replace(other, failed=[], only_inconsistent=False)
    return choice


def _assess(predictor: Predictor, ref: FitResult, screened: dict[str, tuple[float, FitResult]], key: str,
            alternatives: list[str], options: DiagnoseOptions, floor_cost: float, max_p: float) -> _Choice:
    """The acceptance tests of candidate ``key`` against ``ref`` (module doc)."""
    cand = screened[key][1]
    gain, consistency, failed = acceptance(predictor, ref, cand, parts(key)[-1], options, floor_cost, max_p)
    inconsistent = consistency["p"] > max_p
    return _Choice(key, cand, gain, alternatives, consistency, failed, inconsistent and len(failed) == 1)


def acceptance(predictor: Predictor, ref: FitResult, cand: FitResult, effect: str, options: DiagnoseOptions,
               floor_cost: float, max_p: float) -> tuple[float, dict, list[str]]:
    """(relative held-out gain, consistency test record, the tests failed) of ``cand`` against
    ``ref``, the acceptance rule of the module doc; ``effect`` decides the condition of the rank
    test (``Effect.acts_under``). The BIC charges the parameters ``cand`` has beyond ``ref``."""
    gain = 1.0 - cand.cost_test / ref.cost_test
    bic_ok = _bic_lower(predictor, ref, cand)
    consistency = _consistency(predictor, effect, ref.structure, cand.structure)
    min_abs = options.floor_share * floor_cost
    small, immaterial = gain_shortfalls(ref.cost_test, cand.cost_test, options, floor_cost)
    consistency["max_p"] = max_p
    inconsistent = consistency["p"] > max_p
    law = law_ratio(predictor, ref.structure, cand.structure, law_site(EFFECTS[effect]))
    if law is not None:
        consistency["gear_law_ratio"] = law
    failed = [test for test, fails in (
        (f"paired p = {consistency['p']:.3f} > {max_p:g}", inconsistent),
        (f"gain {100 * gain:.1f} % < {100 * options.min_gain:.0f} %", small),
        (f"absolute gain {ref.cost_test - cand.cost_test:.2g} < {min_abs:.2g} ({options.floor_share:g} of the "
         f"noise floor's cost)", immaterial),
        ("BIC higher", not bic_ok),
        (f"the recorded gear torque is fitted {law:.2f}x worse from the recorded deflection (a stand-in for "
         "physics elsewhere)" if law is not None else "", law is not None and law >= 1.0)) if fails]
    return gain, consistency, failed


def gain_shortfalls(ref_cost: float, cand_cost: float, options: DiagnoseOptions, floor_cost: float
                    ) -> tuple[bool, bool]:
    """(the held-out gain from ``ref_cost`` to ``cand_cost`` is below ``min_gain`` relative, below
    ``floor_share`` of the noise floor's cost absolute): the acceptance rule's two gain tests."""
    return (1.0 - cand_cost / ref_cost < options.min_gain,
            ref_cost - cand_cost < options.floor_share * floor_cost)


def _choose(screened: dict[str, tuple[float, FitResult]], cost_now: float) -> tuple[str, list[str]]:
    """The effect to name, and the rivals the held-out data cannot tell apart from it.

    Rivals explain nearly the same held-out cost (e.g. on a drive that seldom rests, friction
    asymmetry and a constant input offset are one and the same force). Among them the most
    parsimonious is named: fewest parameters, then fewest prerequisite effects (a term that
    explains the residual on its own), then the lowest cost.
    """
    best = min(screened, key=lambda k: screened[k][0])
    gain = cost_now - screened[best][0]
    rivals = [k for k in screened if gain > 0 and cost_now - screened[k][0] >= TIE_SHARE * gain]
    chosen = min(rivals or [best], key=lambda k: tie_order(k, screened[k][0]))
    return chosen, sorted(k for k in rivals if k != chosen)


def tie_order(key: str, cost: float) -> tuple:
    """Which of rivals the held-out data cannot tell apart is named first: fewest parameters,
    then fewest prerequisite effects, then the lowest held-out ``cost``."""
    return sum(len(EFFECTS[e].params) for e in parts(key)), len(EFFECTS[parts(key)[-1]].requires), cost


def condition_windows(t: np.ndarray, qd: np.ndarray, starts: np.ndarray, length: int, condition: str) -> np.ndarray:
    """Which windows (``starts``, ``length`` samples) hold ``condition``, from measured signals only.

    "reversal": a motor velocity reversal (``features.reversal_proximity``: a swing past +-5 %
    of the 95th-percentile speed) inside the window or within REVERSAL_WINDOW_S before it.
    """
    if condition != "reversal":
        raise ValueError(f"unknown operating condition {condition!r}")
    near = reversal_proximity(t, qd) <= REVERSAL_WINDOW_S
    idx = np.asarray(starts)[:, None] + np.arange(length)[None, :]
    return near[np.clip(idx, 0, len(near) - 1)].any(axis=1)


def condition_mask(predictor: Predictor, effect: str) -> tuple[np.ndarray | None, str]:
    """Which held-out windows (``predictor.test`` order) hold the condition ``effect`` acts under,
    and in words; None when the effect has none (``Effect.acts_under``)."""
    condition = EFFECTS[effect].acts_under
    if condition is None:
        return None, ""
    m, test = predictor.m, predictor.test
    return (condition_windows(m.t, m.qd, predictor.starts[test], predictor.nwin_samples, condition),
            CONDITION_TEXT[condition])


def rank_p(reductions: np.ndarray) -> float:
    """One-sided Wilcoxon signed-rank p that the per-window reductions (log cost ratios) are
    positive."""
    d = np.asarray(reductions, float)
    if not np.any(d != 0):
        return 1.0
    return float(wilcoxon(d, alternative="greater").pvalue)


def acceptance_p(reductions: np.ndarray, inside: np.ndarray | None = None) -> tuple[float, float, float | None]:
    """(p that decides, p over all held-out windows, p over those ``inside`` the condition, None
    where fewer than MIN_HELDOUT are: no rank test on them could pass).

    Without a condition the all-window p decides. With one, the smaller of the two counts,
    doubled (Bonferroni): the pair of tests keeps the level of one. Where too few held-out
    windows hold the condition to test it, the all-window p is doubled all the same: an
    effect's test is fixed before anything is fitted, and a recording that seldom shows where
    the effect acts does not make it more lenient (its gain then lies where it does not act).
    Where every held-out window holds the condition the two are one test, and its p decides as
    it is.
    """
    d = np.asarray(reductions, float)
    p_all = rank_p(d)
    if inside is None:
        return p_all, p_all, None
    inside = np.asarray(inside, bool)
    if inside.sum() < MIN_HELDOUT:
        return min(1.0, 2.0 * p_all), p_all, None
    p_cond = rank_p(d[inside])
    return (p_all if inside.all() else min(1.0, 2.0 * min(p_all, p_cond))), p_all, p_cond


def held_out_reductions(predictor: Predictor, effect: str, before: Structure, after: Structure
                        ) -> tuple[np.ndarray, np.ndarray | None, str]:
    """(per held-out window, the log cost ratio from ``before`` to ``after``; which of those
    windows hold the condition ``effect`` acts under, and in words: ``condition_mask``)."""
    w = predictor.test
    inside, text = condition_mask(predictor, effect)
    return np.log(window_costs(predictor, before, w) / window_costs(predictor, after, w)), inside, text


def _consistency(predictor: Predictor, effect: str, before: Structure, after: Structure) -> dict:
    """The consistency test of a candidate on the held-out windows (JSON-ready record)."""
    return consistency_record(*held_out_reductions(predictor, effect, before, after))


def consistency_record(d: np.ndarray, inside: np.ndarray | None, text: str, held: str = "held-out windows") -> dict:
    """The rank test's record (``acceptance_p``) of the per-window reductions ``d``, ``inside``
    the condition ``text`` names (None: the effect has none); ``held`` says which windows."""
    n = len(d)
    p, p_all, p_cond = acceptance_p(d, inside)
    if inside is None:
        return {"windows": f"{n} {held}", "n": n, "p": p}
    if p_cond is None:
        return {"windows": f"{n} {held} (p {p_all:.3g}; only {int(inside.sum())} with {text}, too few to test, "
                           "Bonferroni)",
                "n": n, "n_condition": int(inside.sum()), "p_all_heldout": p_all, "p": p}
    return {"windows": f"{n} {held} (p {p_all:.3g}) and the {int(inside.sum())} with {text} "
                       f"(p {p_cond:.3g})" + ("" if inside.all() else ", Bonferroni"),
            "n": n, "n_condition": int(inside.sum()), "p_all_heldout": p_all, "p_condition": p_cond, "p": p}


# The fold whose held-out windows a second look takes (``second_fold``): the next share of the
# same permutation, disjoint from the split every fit so far was made on.
SECOND_FOLD = 1


def second_fold(predictor: Predictor, base: Structure, ref: FitResult, choice: _Choice, options: DiagnoseOptions,
                say) -> _Choice:
    """``choice``, a material gain only the rank test refused at its level, tested once more at
    half that level (Bonferroni: this look adds at most that half to the rate of false
    additions) on the held-out windows of its split and of a second fold
    (``Predictor.refolded``), twice as many. The reference and the candidate are each fitted on
    the second fold's training windows from where their screens ended, so neither has seen the
    new held-out windows but through its start, alike for both; the fold's held-out windows whose
    start the recording leaves open for ``base`` with 2SEP are left out of its score, as the
    split's are (``open_starts``). A short recording's few held-out
    windows make the signed-rank test coarse (ten give p in steps of about 0.001 to 0.01 near the
    level): a gain the recording supports shows again on windows no fit has seen, a gain of chance
    does not. The choice comes back judged on both folds; where the recording holds too few
    windows for another fold, as it was."""
    level = choice.consistency["max_p"] / 2
    try:
        other = predictor.refolded(SECOND_FOLD)
    except ValueError:
        return choice
    leave_out_open_starts(other, base, MIN_HELDOUT, lambda text: say(f"  second fold: {text}"))
    effect = parts(choice.best)[-1]
    refits = [fit(other, r.structure, max_iter=options.fit_iter) for r in (ref, choice.cand)]
    predictor.rollouts = other.rollouts
    d, inside, text = held_out_reductions(predictor, effect, ref.structure, choice.cand.structure)
    d2, inside2, _ = held_out_reductions(other, effect, *(r.structure for r in refits))
    consistency = consistency_record(np.r_[d, d2], None if inside is None else np.r_[inside, inside2], text,
                                     "held-out windows of two folds")
    consistency.update(max_p=level, folds=2, second_fold_gain=1.0 - refits[1].cost_test / refits[0].cost_test)
    failed = [f"paired p = {consistency['p']:.3f} > {level:g}"] if consistency["p"] > level else []
    say(f"  {choice.best} on a second fold: held-out cost {refits[0].cost_test:.4g} -> {refits[1].cost_test:.4g}; "
        f"paired p = {consistency['p']:.3g} on {consistency['windows']}: "
        + (f"fails, {failed[0]}" if failed else "passes"))
    return dataclasses.replace(choice, consistency=consistency, failed=failed, only_inconsistent=bool(failed))


def _bic_lower(predictor: Predictor, ref: FitResult, cand: FitResult) -> bool:
    """Whether ``cand`` has the lower BIC on the training windows both fits were fitted on: a
    window one of them left out (its start open to that model) holds no evidence between them."""
    keep = fitted_on_both(predictor, ref, cand)
    n = int(keep.sum()) * len(predictor.cols) * len(predictor.signals)
    bic = [_bic(float(np.mean(f.train_costs[keep])), n, len(f.structure.params)) for f in (cand, ref)]
    return bic[0] < bic[1]
