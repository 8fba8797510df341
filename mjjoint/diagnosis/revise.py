"""Revising the search: stepwise forward selection never revisits a choice, so an effect named
early keeps what it absorbed even when a rival would explain it better once later effects are
in, and an effect named late may only re-explain what an earlier one already does.

Three checks, all judged on the held-out windows by the acceptance rule of the additions
(``loop.acceptance``: relative and absolute gain, the paired rank test, the BIC):

- **Stand-in guard**, for every effect accepted after the first: its gain is tested once more
  against the model without it refitted with more freedom (every parameter free, ``fit_iter``
  iterations, then the robust loss, kept if it predicts the held-out windows better); an effect
  whose gain does not survive that, or whose own parameters end on their bounds, is a stand-in: it
  is reported (``stand_in_effects``), not named, and not screened again; so is the first effect
  where every one of its own parameters ends on a bound (none of them an estimate of it); so is an
  effect, the first too, whose term, switched off at its own fit with every other parameter where
  that fit left them, loses less than the acceptance rule's relative or absolute gain while the
  model without it, refitted from there, keeps the gain (it fails the acceptance rule against that
  refit: its gain is the optimum its fit carried the other parameters to, a viscous asymmetry of 2.5
  % "explaining" 75 % of the held-out cost; where the refit loses the gain, the term is what holds
  that optimum, and the other tests decide); so is an effect, the first too, whose characteristic
  speed (the Stribeck velocity) is fitted below the speed the recording resolves
  (``unresolved_speeds``), a sensor's time shift below a tenth of a sample
  (``unresolved_shift``), or a mode above the Nyquist frequency or placed by its parameters' 95 %
  intervals no better than within a factor of two (``unresolved_mode``: a flexible rod's, which
  the recording then does not show); the model without it, refitted from where its fit left
  the other parameters, replaces the current one where it predicts the held-out windows better (a
  term fitted to its bound is often fitted to none, its gain the model's own from another start).
  An effect with a signed size (``sizes``: a skew, an offset, an asymmetry, a ripple; a generic
  form always), the first effect too, is one where its fit cannot tell that size from none, every
  95 % interval holding zero, jointly too (``resolved``): a gain whose term the recording cannot
  place away from none is the other parameters' optimum it carried, not an estimate. So is an
  effect related to one refused before that predicted the held-out windows better than it does:
  it explains a part of what that stand-in did, and the physics acting there is neither.
- **Swap**: each named effect is replaced by each of its rivals (``rivals``: the effects acting
  at the same site under a shared residual condition, and the ones the step found
  indistinguishable), the rest refitted; the swap is kept when the swapped model passes the
  acceptance rule against the current one. A rival whose model predicts the held-out windows as
  well without passing (within a tenth of the step's gain, as rivals tie at a screen) is a tie:
  of the two, the one a screen would name first is named (``loop.tie_order``: fewer parameters,
  fewer prerequisites, the lower cost), and the other is reported indistinguishable from it; a
  tie never brings back the effect a swap replaced (``Step.replaced``). A swap is fitted in a
  screen's two stages (``loop._screen``): on the screens' subset of the windows first, finished
  on all of them only where its subset cost, scaled as a screen's is, could pass the relative
  gain.
- **Removal** (backward elimination): each named effect is tested as if it were added now to the
  model without it; one that no longer passes, given the effects named after it, is removed.

Revisions run after every addition, so the final structure has been revised once the last
addition was; each one is recorded (``Revision``) with the held-out costs that decided it.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.stats import chi2

from ..identify.effects import EFFECTS, base_params, check_effects, plant_effects
from ..identify.fit import FitResult, check_intervals, finish, fit, window_costs
from ..identify.intervals import Z95
from ..identify.structure import Structure
from ..identify.windows import Predictor
from .loop import (BUNDLE, TIE_SHARE, DiagnoseOptions, Step, _candidate_variants, _evidence, _robust_kept,
                   acceptance, bundle, default_candidates, gain_shortfalls, parts, screened_params, tie_order,
                   with_candidate)


@dataclass
class Revision:
    """One revision of the named effects, with the held-out costs that decided it."""

    kind: str                 # "swap", "removal" or "stand-in"
    effect: str               # the effect replaced, removed or refused
    cost_before: float        # held-out cost of the model before the revision
    cost_after: float         # ... and after (a stand-in: with it, against the freer reference)
    reason: str
    by: str = ""              # a swap: the rival that replaced it
    beside: str = ""          # a stand-in refused in a pair: the other member, in the model it was judged in
    # A stand-in refused against a base that the model without it, refitted from its values, beat
    # by the acceptance rule's gain: screened once more from that base (``loop.refused``).
    rebased: bool = False

    def as_dict(self) -> dict:
        return {"kind": self.kind, "effect": self.effect, "by": self.by, "beside": self.beside,
                "heldout_cost_before": self.cost_before, "heldout_cost_after": self.cost_after, "reason": self.reason}

    @property
    def line(self) -> str:
        return revision_line(self.as_dict())


def revision_line(record: dict) -> str:
    """A revision in words, from its ``Revision.as_dict`` record (diagnosis.json data)."""
    costs = f"held-out cost {record['heldout_cost_before']:.4g} -> {record['heldout_cost_after']:.4g}"
    if record["kind"] == "swap":
        return f"{record['effect']} replaced by {record['by'].replace(BUNDLE, ' + ')} ({costs})"
    if record["kind"] == "removal":
        return f"{record['effect']} removed ({costs}): {record['reason']}"
    return f"{record['effect']} ({record['reason']})"


def related(a: str, b: str) -> bool:
    """Whether effects ``a`` and ``b`` act at the same site under a shared residual condition
    (``Effect.site``, ``Effect.evidence``): what one explains, the other can stand in for."""
    ea, eb = EFFECTS[a], EFFECTS[b]
    return ea.site == eb.site and bool(set(ea.evidence) & set(eb.evidence))


def without(structure: Structure, effects) -> Structure:
    """``structure`` with ``effects`` switched off (their values and settings dropped)."""
    gone = set(effects)
    kept = check_effects([e for e in structure.effects if e not in gone], plant_effects(structure.nominal))
    s = dataclasses.replace(structure, effects=kept)
    names = {p.name for p in s.params}
    return dataclasses.replace(s, values={k: v for k, v in structure.values.items() if k in names},
                               settings={k: v for k, v in structure.settings.items() if k.split(".")[0] not in gone})


def removable(structure: Structure, effects) -> bool:
    """Whether no effect left in ``structure`` requires one of ``effects``."""
    gone = set(effects)
    return not any(r in gone for e in structure.effects if e not in gone for r in EFFECTS[e].requires)


def rivals(step: Step, structure: Structure, allowed=None, excluded=()) -> list[str]:
    """The candidates (bundle keys, ``loop.parts``) that could take ``step.effect``'s place in
    ``structure``: catalogued effects it lacks that are ``related`` to it, and those the step
    found indistinguishable; none that needs the effect itself."""
    e = step.effect
    possible = plant_effects(structure.nominal)
    names = [r for r in default_candidates(structure) if related(e, r)]
    names += [parts(a.replace(" + ", BUNDLE))[-1] for a in step.alternatives]
    reduced = without(structure, [e])
    keys = (bundle(r, reduced.effects, possible) for r in dict.fromkeys(names)
            if not (r == e or r in structure.effects or r in excluded or e in EFFECTS[r].requires
                    or (allowed is not None and r not in allowed)))
    return [k for k in keys if k is not None]


def _fit_variants(predictor: Predictor, structure: Structure, key: str, where: dict, options: DiagnoseOptions
                  ) -> FitResult:
    """``key`` added to ``structure`` and fitted as a screen's first stage is (``loop.screened_params``
    on the fit's first-phase subset, ``loop._screen``), from each variant the evidence suggests; the
    lowest held-out cost, to be finished (``identify.fit.finish``)."""
    best = None
    for values, settings in _candidate_variants(parts(key)[-1], where, structure):
        trial = with_candidate(structure, key, values, settings)
        res = fit(predictor, trial, screened_params(key, structure), max_iter=options.screen_iter, subset_only=True)
        if best is None or res.cost_test < best.cost_test:
            best = res
    return best


def stand_in(predictor: Predictor, before: FitResult, after: FitResult, step: Step, named: list[Step],
             options: DiagnoseOptions, floor_cost: float, say: Callable[[str], None], refusals=()
             ) -> tuple[Revision | None, FitResult | None]:
    """Whether ``step``, just accepted (``before`` -> ``after``), is a stand-in (module doc): a signed
    size (``sizes``) its checked 95 % intervals cannot tell from none (``resolved``; the first
    effect too, and no refit of the model without it), its term switched off at its own fit
    losing less than the acceptance rule's relative or absolute gain (``switched_off``,
    ``loop.gain_shortfalls``; the first effect too) while it fails that rule
    against the model without it refitted from its values, its own parameters on their
    bounds (the first effect where every one of them is), a characteristic speed fitted below what
    the recording resolves (``unresolved_speeds``), a sensor's time shift below a tenth of a sample
    (``unresolved_shift``) or a mode above the Nyquist frequency or not placed by the recording
    (``unresolved_mode``; these three
    the first effect too), a related effect already
    refused as a stand-in (one of ``refusals``) predicting the held-out windows better than it does,
    or, when it is ``related`` to an effect already ``named``, its gain gone against the model
    without it refitted with more freedom, from where ``after`` left the other parameters (the added
    term may only have carried them to a better optimum). Returns (the refusal or None, that refit
    of the model without it or None; a refusal for bounds refits it too, which the loop keeps where
    it predicts the held-out windows better than the model it extends)."""
    size = sizes(step.effect)
    generic = EFFECTS[step.effect].generic
    # A catalogued term without intervals (none estimated) is judged by the other tests; the
    # intervals judged are the ones the verdict reports (checked against the cost, widened by
    # the step's bias and the fit's own), not the Jacobian's alone.
    if size and (generic or all(n in after.intervals for n in size)) and \
            not resolved(check_intervals(predictor, after, size), size):
        return Revision("stand-in", step.effect, before.cost_test, after.cost_test,
                        f"passed the acceptance rule with a size its own fit cannot tell from none ({', '.join(size)}: "
                        + ("its 95 % interval holds zero" if len(size) == 1 else
                           "every 95 % interval holds zero, jointly too") + "): "
                        + ("a generic form standing in for what the located residual holds" if generic else
                           "a term standing in for physics elsewhere, not an estimate of its own")), None
    off = switched_off(predictor, after, step)
    carried = off - after.cost_test
    free = None
    if any(gain_shortfalls(off, after.cost_test, options, floor_cost)):
        # The gain may be where the new term's fit carried the other parameters, not the term:
        # then the model without it, refitted from there, keeps that gain without naming it. Where
        # that refit loses it instead, the term is what holds the optimum: the other tests decide.
        free = _robust_kept(predictor, _refit_without(predictor, after, step, options), options)
        refit_keeps = bool(acceptance(predictor, free, after, step.effect, options, floor_cost, options.max_p)[2])
        say(f"  {step.effect} switched off at its fit: held-out cost {off:.4g} (with it {after.cost_test:.4g}); "
            f"the model without it refitted from its values: {free.cost_test:.4g}"
            + ("" if refit_keeps else f", against which {step.effect} passes the acceptance rule: its term holds "
               "that optimum"))
        if refit_keeps:
            return Revision("stand-in", step.effect, off, after.cost_test,
                            f"passed the acceptance rule, but at its own fit its term lowers the held-out cost by "
                            f"{100 * carried / off:.1f} % only ({off:.4g} switched off, every other parameter where "
                            f"that fit left them; {after.cost_test:.4g} with it): its gain is the optimum its fit "
                            "carried the other parameters to"), free
    # (not a stand-in refused beside this very effect: that model's cost was partly this effect's)
    better = [r for r in refusals if related(r.effect, step.effect) and r.cost_after <= after.cost_test
              and r.beside != step.effect]
    if better:
        return Revision("stand-in", step.effect, before.cost_test, after.cost_test,
                        f"explains less of the residual at its site than {better[0].effect}, refused as a stand-in, "
                        f"did (held-out cost {after.cost_test:.4g} with it, {better[0].cost_after:.4g} with "
                        f"{better[0].effect}): what acts there is neither"), None
    unresolved = (unresolved_speeds(predictor, after, step.effect) or unresolved_shift(predictor, after, step.effect)
                  or unresolved_mode(predictor, after, step.effect))
    bound = own_on_bound(after, step.effect)
    if not named and len(bound) < len(EFFECTS[step.effect].params):
        bound = []  # the first effect: only where none of its own is an estimate
    if not (named or unresolved or bound):
        return None, None
    if bound or unresolved:
        # A term fitted to a bound is often fitted to none at all (a Stribeck ratio of 1, a delay
        # of 0): its gain is then the model's own, reached from another start, which the model
        # without it refitted from there keeps.
        if free is None:
            free = _robust_kept(predictor, _refit_without(predictor, after, step, options), options)
        say(f"  the model without {step.effect} refitted from its values: held-out cost {free.cost_test:.4g} "
            f"(before it {before.cost_test:.4g}, with it {after.cost_test:.4g})")
        values = after.structure.values
        why = (f"its parameters on their bounds ({', '.join(f'{n} = {values[n]:.4g}' for n in bound)})" if bound else
               unresolved)
        return Revision("stand-in", step.effect, before.cost_test, after.cost_test,
                        f"passed the acceptance rule with {why}: a stand-in, not an estimate"), free
    earlier = [s.effect for s in named if related(s.effect, step.effect)]
    if not earlier:
        return None, None
    say(f"  {step.effect} acts where {', '.join(earlier)} does: its gain tested against the model without it "
        "refitted from its values, every parameter free")
    if free is None:
        ref = _robust_kept(predictor, min(before, _refit_without(predictor, after, step, options),
                                          key=lambda r: r.cost_test), options)
    else:  # refitted and robust-kept by the switched-off test
        ref = free if free.cost_test < before.cost_test else _robust_kept(predictor, before, options)
    _, consistency, failed = acceptance(predictor, ref, after, step.effect, options, floor_cost, options.max_p)
    say(f"  held-out cost {ref.cost_test:.4g} without {step.effect} refitted, {after.cost_test:.4g} with it "
        f"(p {consistency['p']:.3g})" + (f"; fails: {', '.join(failed)}" if failed else ""))
    if not failed:
        return None, ref
    return Revision("stand-in", step.effect, ref.cost_test, after.cost_test,
                    f"re-explains what {', '.join(earlier)} and the rest explain: against the model without it "
                    f"refitted from its values it fails {', '.join(failed)}"), ref


def one_of_pair(predictor: Predictor, before: FitResult, outcomes, options: DiagnoseOptions, floor_cost: float
                ) -> tuple[Step, FitResult, Revision] | None:
    """A pair named together of which a member is refused (``stand_in``) holds at most the other:
    the member left in the refit without the refused one (where each is refused as explaining what
    the other does, the better of the two refits), named alone where that refit passes the
    acceptance rule against ``before``, the model the pair extends. Refusing both would drop the
    physics the stand-in's gain was the other's. ``outcomes``: (step, refusal, refit without it)
    per member; none is kept whose own parameters that refit left on their bounds. Returns (that
    member's step, its fit, the other's refusal) or None."""
    if len(outcomes) != 2:
        return None
    kept = [(freer, keep, refusal) for (step, refusal, freer), (keep, _, _) in zip(outcomes, outcomes[::-1])
            if refusal is not None and freer is not None and keep.effect in freer.structure.effects
            and step.effect not in freer.structure.effects]
    refused = {step.effect for step, refusal, _ in outcomes if refusal is not None}
    # a member refused itself is kept only where each re-explains the other (both refits found)
    kept = [k for k in kept if k[1].effect not in refused or len(kept) == 2]
    if not kept:
        return None
    freer, keep, refusal = min(kept, key=lambda k: k[0].cost_test)
    if own_on_bound(freer, keep.effect):
        return None  # alone it would be a stand-in too (``stand_in``: its own parameters on their bounds)
    gain, consistency, failed = acceptance(predictor, before, freer, keep.effect, options, floor_cost, options.max_p)
    if failed:
        return None
    values = freer.structure.values
    step = dataclasses.replace(keep, parameters={n: values[n] for n in keep.parameters if n in values},
                               fit_after=freer.nrmse_test, gain=gain, consistency=consistency,
                               screen=f"{keep.screen}; kept alone, {refusal.effect} refused as a stand-in")
    return step, freer, refusal


def own_on_bound(result: FitResult, effect: str) -> list[str]:
    """``effect``'s own parameters that ``result`` left on a bound."""
    own = {p.name for p in EFFECTS[effect].params}
    return [n for n in result.on_bound if n in own]


def switched_off(predictor: Predictor, after: FitResult, step: Step) -> float:
    """The held-out cost of ``after`` with ``step``'s effects switched off, every other parameter
    where ``after`` has it: what the model loses without the term itself."""
    return float(np.mean(window_costs(predictor, without(after.structure, step.effects), predictor.test)))


def unresolved_speeds(predictor: Predictor, result: FitResult, effect: str) -> str:
    """``effect``'s characteristic speeds (``Param.dim`` "speed": the Stribeck velocity) that
    ``result`` fitted below ``Measured.moving_speed``, as "name = value, below the speed ...", or
    "" where none is. A curve over speeds the recording cannot tell from rest is shaped by the
    breakaway transients alone, where the pre-sliding physics acts: it stands in for that,
    whatever it gains."""
    slow = [(p.name, result.structure.values[p.name]) for p in EFFECTS[effect].params
            if p.dim == "speed" and result.structure.values[p.name] < predictor.m.moving_speed]
    if not slow:
        return ""
    return (", ".join(f"{n} = {v:.3g}" for n, v in slow) + f", below the speed the recording resolves "
            f"({predictor.m.moving_speed:.3g}: one noise band a sample), a law over speeds the recording cannot "
            "tell from rest")


# A sensor's time shift below this share of the sample period is finer than the clock the
# recording states its samples on.
SHIFT_RESOLUTION = 0.1


def unresolved_shift(predictor: Predictor, result: FitResult, effect: str) -> str:
    """A sensor's time shift (``Effect.plot`` "time_shift" at the sensor site: the link encoder's
    skew) that ``result`` fitted below ``SHIFT_RESOLUTION`` sample periods, in words, or "". A
    skew between two encoders is a latching offset of the controller's cycle; one far below a
    sample is finer than the recording's clock, and in the deflection it reads as a torque in
    proportion to the link's speed, which dissipation anywhere in the gear and the link gives (the
    skew's ``stand_ins``): it stands in for that physics."""
    e = EFFECTS[effect]
    if e.site != "sensor" or e.plot != "time_shift":
        return ""
    period = 1.0 / predictor.m.rate
    fine = [(p.name, result.structure.values[p.name]) for p in e.params
            if abs(result.structure.values[p.name]) < SHIFT_RESOLUTION * period]
    if not fine:
        return ""
    return (", ".join(f"{n} = {v:.3g} s" for n, v in fine) + f", below {SHIFT_RESOLUTION:g} of the sample period "
            f"({period:.3g} s), finer than the recording's clock")


# A mode the recording shows is placed by it within this factor (the ratio of the highest to the
# lowest frequency over the ends of the term's 95 % intervals); one placed no better is not shown.
MODE_SPREAD = 2.0


def unresolved_mode(predictor: Predictor, result: FitResult, effect: str) -> str:
    """The mode ``effect`` adds (``Effect.mode_hz``: a flexible rod's) where ``result`` fitted it
    above the Nyquist frequency or placed it no better than within ``MODE_SPREAD`` (``mode_span``),
    in words, or "". The recording then does not show that mode; what the term still does (a
    little compliance, a damper on the link) is what the gear's spring and damper hold or
    dissipation elsewhere gives (the effect's ``stand_ins``): it stands in for that physics."""
    mode_hz = EFFECTS[effect].mode_hz
    if mode_hz is None:
        return ""
    mode, nyquist = mode_hz(result.structure), predictor.m.rate / 2.0
    if mode > nyquist:
        return (f"its mode at {mode:.3g} Hz, above the recording's Nyquist frequency ({nyquist:.3g} Hz): a mode the "
                "recording cannot show")
    low, high = mode_span(result, effect)
    if not high > MODE_SPREAD * low:
        return ""
    return (f"its mode at {mode:.3g} Hz placed only within {low:.3g} .. {high:.3g} Hz by its parameters' 95 % "
            "intervals: a mode the recording does not show")


def mode_span(result: FitResult, effect: str) -> tuple[float, float]:
    """The lowest and highest frequency [Hz] of ``effect``'s mode over the ends of its parameters'
    95 % intervals in ``result``, each parameter moved alone (one held has none)."""
    mode_hz = EFFECTS[effect].mode_hz
    modes = [mode_hz(result.structure)]
    for p in EFFECTS[effect].params:
        modes += [mode_hz(result.structure.with_values({p.name: end})) for end in result.intervals.get(p.name, ())]
    return min(modes), max(modes)


def _refit_without(predictor: Predictor, after: FitResult, step: Step, options: DiagnoseOptions) -> FitResult:
    """The model ``after`` without ``step``'s effects, refitted from the values ``after`` reached,
    every parameter free (``fit_iter`` iterations)."""
    return fit(predictor, without(after.structure, step.effects), max_iter=options.fit_iter)


def sizes(effect: str) -> list[str]:
    """``effect``'s signed size parameters, zero for none (a skew, an offset, an asymmetry, a
    ripple's amplitudes): the ones whose interval can hold the term switched off."""
    return [p.name for p in EFFECTS[effect].params if not p.log and p.initial == 0.0]


def resolved(result: FitResult, names: list[str]) -> bool:
    """Whether the parameters ``names`` (signed, zero for none) are jointly away from zero: their
    Wald statistic, sum (value / se)^2 with each se from its 95 % interval, above chi^2's 95 %
    point (the sinusoid's two amplitudes are nearly uncorrelated over many periods). Each se is
    taken from the interval's end toward zero, so that one parameter is resolved exactly where its
    interval, checked and so not symmetric, leaves zero out."""
    wald = 0.0
    for name in names:
        lo, hi = result.intervals.get(name, (-math.inf, math.inf))
        value = result.structure.values[name]
        se = abs(value - (lo if value > 0.0 else hi)) / Z95
        wald += (value / se) ** 2 if 0.0 < se < math.inf else 0.0
    return wald > chi2.ppf(0.95, len(names))


def revise(predictor: Predictor, current: FitResult, steps: list[Step], where: dict, options: DiagnoseOptions,
           floor_cost: float, say: Callable[[str], None], excluded=()) -> tuple[FitResult, list[Step], list[Revision]]:
    """Swaps and removals of the named ``steps`` (module doc) until none passes; the revised fit,
    steps and what was revised."""
    done: list[Revision] = []
    for _ in range(2 * len(steps)):  # each pass changes one step; a cycle cannot outlast this
        change, tied = _removal(predictor, current, steps, options, floor_cost, say), []
        if change is None:
            change, tied = _swap(predictor, current, steps, where, options, floor_cost, say, excluded)
        if change is None:
            steps = _with_ties(steps, tied)
            break
        current, steps, revision = change
        done.append(revision)
        say(f"  revised: {revision.line}")
    return current, steps, done


def _tie_cost(current: FitResult, step: Step) -> float:
    """The held-out cost up to which a model with a rival in ``step``'s place predicts as well as
    ``current``: within (1 - TIE_SHARE) of the step's own gain, as rivals tie at a screen
    (``loop._choose``); the gain rescaled to the current cost, so an early step's band is no
    wider than it was."""
    g = min(max(step.gain, 0.0), 0.99)
    return current.cost_test * (1.0 + (1.0 - TIE_SHARE) * g / (1.0 - g))


def _with_ties(steps: list[Step], tied: list[tuple[int, str]]) -> list[Step]:
    """``steps`` with each tied rival (step index, key) among its step's alternatives: the
    recording cannot tell them apart, and the verdict says so."""
    steps = list(steps)
    for i, key in tied:
        name = key.replace(BUNDLE, " + ")
        if name not in steps[i].alternatives:
            steps[i] = dataclasses.replace(steps[i], alternatives=[*steps[i].alternatives, name])
    return steps


def _removal(predictor, current, steps, options, floor_cost, say):
    """The first named step (oldest first) that, tested as an addition to the model without it,
    no longer passes; None if each still does. The newest step has just passed that test. A step
    whose prerequisites a later effect needs loses its effect only, and names them instead."""
    for i, step in enumerate(steps[:-1]):
        gone = next((g for g in (step.effects, (step.effect,)) if removable(current.structure, g)), None)
        if gone is None:
            continue
        reduced = without(current.structure, gone)
        ref = fit(predictor, reduced, screened_params(BUNDLE.join(gone), reduced), max_iter=options.screen_iter)
        _, consistency, failed = acceptance(predictor, ref, current, step.effect, options, floor_cost, options.max_p)
        say(f"  removal test of {step.effect}: held-out cost {ref.cost_test:.4g} without it, {current.cost_test:.4g}"
            f" with it (p {consistency['p']:.3g})" + (f": fails {', '.join(failed)}" if failed else ": still needed"))
        if failed:
            refit = _refit(predictor, ref, options)
            kept = [e for e in step.effects if e not in gone]
            rest = [] if not kept else [dataclasses.replace(
                step, effect=kept[-1], prerequisites=kept[:-1], evidence=_evidence(BUNDLE.join(kept), step.where),
                parameters={p.name: refit.structure.values[p.name] for e in kept for p in EFFECTS[e].params})]
            return refit, [*steps[:i], *rest, *steps[i + 1:]], Revision(
                "removal", step.effect, current.cost_test, refit.cost_test,
                f"given the effects named after it, it fails {', '.join(failed)}")
    return None


def _swap(predictor, current, steps, where, options, floor_cost, say, excluded):
    """(the best swap of a named step for a rival that passes the acceptance rule against the
    current model, else for a tied rival (one whose model predicts the held-out windows as well,
    ``_tie_cost``) that a screen would have named before it (``loop.tie_order``), or None if there
    is neither; the tied rivals (step index, key) where there is none)."""
    best = null = None
    ties = []  # (step index, key, the swapped fit, refitted)
    for i, step in enumerate(steps):
        if not removable(current.structure, [step.effect]):
            continue
        reduced = without(current.structure, [step.effect])
        tie = _tie_cost(current, step)
        for key in rivals(step, current.structure, options.candidates, excluded):
            first = _fit_variants(predictor, reduced, key, where, options)
            if null is None:  # the current model fitted on the same subset, as a screen's null is
                null = fit(predictor, current.structure, [p.name for p in base_params(current.structure.nominal)],
                           max_iter=options.screen_iter, subset_only=True)
            # As a screen left on the subset is scored (``loop._screen``): the current model's
            # held-out cost scaled by the swap's subset cost over the null's.
            guess = current.cost_test * first.cost_test / null.cost_test if null.cost_test > 0 else first.cost_test
            if not guess < current.cost_test * (1.0 - options.min_gain):
                say(f"  swap {step.effect} -> {key} on a subset of the windows: held-out cost "
                    f"{current.cost_test:.4g} -> ~{guess:.4g}")
                if guess <= tie:  # as good, maybe: finished, it tells
                    trial = finish(predictor, first)
                    say(f"    finished: {trial.cost_test:.4g}" + (", a tie" if trial.cost_test <= tie else ""))
                    if trial.cost_test <= tie:
                        ties.append((i, key, trial, False))
                continue  # cannot pass the relative gain, not worth the refit
            trial = finish(predictor, first)
            say(f"  swap {step.effect} -> {key}: held-out cost {current.cost_test:.4g} -> {trial.cost_test:.4g}")
            if not trial.cost_test < current.cost_test * (1.0 - options.min_gain):
                if trial.cost_test <= tie:
                    ties.append((i, key, trial, False))
                continue  # cannot pass the relative gain, not worth the full refit
            trial = _refit(predictor, trial, options)
            gain, consistency, failed = acceptance(predictor, current, trial, parts(key)[-1], options, floor_cost,
                                                   options.max_p)
            say(f"    refitted: {trial.cost_test:.4g} (p {consistency['p']:.3g})"
                + (f": fails {', '.join(failed)}" if failed else ": passes"))
            if failed and trial.cost_test <= tie:
                ties.append((i, key, trial, True))
            if not failed and (best is None or trial.cost_test < best[1].cost_test):
                best = (i, trial, key, consistency)
    if best is not None:
        i, trial, key, consistency = best
        return _swapped(current, steps, i, trial, key, consistency,
                        f"the model with {parts(key)[-1]} in its place passes the acceptance rule "
                        f"(p {consistency['p']:.3g})"), []
    for i, key, trial, refitted in sorted(ties, key=lambda t: t[2].cost_test):
        step = steps[i]
        # A tie never brings back the effect a swap replaced: within the tie band two rivals of one
        # size are ranked by cost alone, and refits that go on descending would trade them back and
        # forth, each a little lower than the last.
        if not tie_order(key, trial.cost_test) < tie_order(step.effect, current.cost_test) or \
                step.replaced == parts(key)[-1]:
            continue
        trial = trial if refitted else _refit(predictor, trial, options)
        _, consistency, _ = acceptance(predictor, current, trial, parts(key)[-1], options, floor_cost, options.max_p)
        if trial.cost_test <= _tie_cost(current, step) and (
                tie_order(key, trial.cost_test) < tie_order(step.effect, current.cost_test)):
            return _swapped(current, steps, i, trial, key, consistency,
                            f"the model with {parts(key)[-1]} in its place predicts as well (p "
                            f"{consistency['p']:.3g}), and a screen names it first of the two", tied=True), []
    return None, [(i, key) for i, key, _, _ in ties]


def _swapped(current, steps, i, trial, key, consistency, reason, tied=False):
    """(the fit, the steps, the revision) with step ``i``'s effect swapped for ``key`` fitted as
    ``trial``; a ``tied`` swap keeps the effect replaced among the step's rivals."""
    old = steps[i]
    *needed, effect = parts(key)
    others = [a for a in old.alternatives if a.replace(" + ", BUNDLE) != key]
    new = dataclasses.replace(
        old, effect=effect, prerequisites=[*old.prerequisites, *needed], evidence=_evidence(key, old.where),
        parameters={p.name: trial.structure.values[p.name] for e in (*old.prerequisites, *parts(key))
                    for p in EFFECTS[e].params},
        alternatives=[*others, old.effect] if tied else others,
        consistency=consistency, screen=f"swapped for {old.effect}", replaced=old.effect)
    return trial, [*steps[:i], new, *steps[i + 1:]], Revision(
        "swap", old.effect, current.cost_test, trial.cost_test, reason, by=key)


def _refit(predictor: Predictor, result: FitResult, options: DiagnoseOptions) -> FitResult:
    """A revised structure fitted as an added one is: every parameter free (``fit_iter``), then
    under the robust loss (``options.robust_refit``), each kept only if it predicts the held-out
    windows better."""
    full = fit(predictor, result.structure, max_iter=options.fit_iter)
    best = full if full.cost_test < result.cost_test else result
    return _robust_kept(predictor, best, options) if options.robust_refit else best


def step_models(initial: Structure, final: Structure, steps: list[Step]) -> list[Structure]:
    """The models before the first step and after each (``report.build``'s labels) as the final
    fit has them: the final structure without the effects of the steps after each."""
    added = [s.effects for s in steps]
    models = [initial]
    for k in range(1, len(steps)):
        later = {e for effects in added[k:] for e in effects}
        models.append(without(final, later))
    return models + [final] if steps else [initial]
