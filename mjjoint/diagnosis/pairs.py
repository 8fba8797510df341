"""Two effects at once: a recording may need two missing terms whose residuals mask each other.

A backlash and a current-loop lag both act on the gear torque near reversals; with one of them
missing, the other's screen fits part of its residual with the wrong shape and gains less than
the acceptance rule asks, so forward selection, one effect a round, stops with both missing.
When no single candidate passes, the best finished screen and the best other screen (finished,
or left on the subset by the stage that ranks single additions) are fitted together (each from
its own screen's values, the parameters both screens free) and judged as one addition:

- against the model they extend, by the acceptance rule at half its level (a second look at the
  same round, Bonferroni, as the screen with every parameter free is);
- against each of the two alone, by the relative gain: each must earn its place beside the
  other, the test the revisions' removal applies to every named effect once more afterwards.

Only screens that gain PAIR_SHARE of the relative gain on their own are paired: a term whose
screen explains nothing has no residual of its own to be masked, and fewer pairs keep the
second look to one test a round.
"""
from __future__ import annotations

from typing import Callable

from ..identify.effects import EFFECTS, incompatible
from ..identify.fit import FitResult, fit
from ..identify.windows import Predictor
from .loop import BUNDLE, PAIR, DiagnoseOptions, _Choice, acceptance, parts, screened_params, with_candidate

PAIR_SHARE = 0.5  # a screen gaining this share of ``min_gain`` on its own may be paired


def compatible(a: str, b: str) -> bool:
    """Whether candidates ``a`` and ``b`` (bundle keys) can be added to one model together."""
    pa, pb = parts(a), parts(b)
    return not set(pa) & set(pb) and not any(incompatible(x, y) for x in pa for y in pb)


def paired(costs: dict[str, float], finished: set[str], ref: FitResult, min_gain: float) -> tuple[str, str] | None:
    """The best finished screen and the best other screen (finished or left on the subset: its
    ``costs`` entry is then the subset's estimate) that each gain PAIR_SHARE of ``min_gain``
    against ``ref`` and can be in one model; None if there are not two."""
    keen = sorted((k for k, c in costs.items() if c <= ref.cost_test * (1.0 - PAIR_SHARE * min_gain)),
                  key=lambda k: costs[k])
    for a in keen:
        if a not in finished:
            continue
        for b in keen:
            if b != a and compatible(a, b):
                return a, b
    return None


def pair_screen(predictor: Predictor, ref: FitResult, screened: dict[str, tuple[float, FitResult]],
                rest: dict[str, tuple[float, FitResult]], options: DiagnoseOptions, floor_cost: float,
                say: Callable[[str], None]) -> _Choice | None:
    """The pair of the round's screens to name together (module doc), or None. ``rest``: the
    held-out costs estimated for the screens left on the subset, with their subset fits
    (``loop._screen``); one of them may be the second of a pair, started from the catalogue's
    values with its best variant's settings, since the stage that left it there ranks single
    additions, not partners."""
    candidates = {**rest, **screened}  # a name in both: the finished screen
    costs = {k: c for k, (c, _) in candidates.items()}
    pair = paired(costs, set(screened), ref, options.min_gain)
    if pair is None:
        return None
    a, b = pair
    first = screened[a][1].structure
    second = candidates[b][1].structure
    settings = {k: v for k, v in second.settings.items() if k.split(".")[0] in parts(b)}
    if b in screened:
        own = {p.name: second.values[p.name] for e in parts(b) for p in EFFECTS[e].params}
        trial = with_candidate(first.at_timestep(min(first.nominal.timestep, second.nominal.timestep)), b, own,
                               settings)
    else:
        trial = with_candidate(first, b, None, settings)
    freed = list(dict.fromkeys([*screened_params(a, ref.structure), *screened_params(b, ref.structure)]))
    key = a + PAIR + b
    cand = fit(predictor, trial, freed, max_iter=options.screen_iter)
    gain, consistency, failed = acceptance(predictor, ref, cand, parts(a)[-1], options, floor_cost, options.max_p / 2)
    for alone in (a, b):
        share = 1.0 - cand.cost_test / costs[alone]
        if share < options.min_gain:
            failed.append(f"{100 * share:.1f} % below {alone} alone < {100 * options.min_gain:.0f} %")
    apart = f"alone {costs[a]:.4g}, {costs[b]:.4g}" + ("" if b in screened else " on the subset")
    say(f"  screened {key.replace(BUNDLE, ' + ')} together: held-out cost {ref.cost_test:.4g} -> {cand.cost_test:.4g} "
        f"({apart})" + (f"; fails {', '.join(failed)}" if failed else "; passes"))
    return _Choice(key, cand, gain, [], consistency, failed, False)
