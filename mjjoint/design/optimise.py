"""Search the input families for the experiment that best separates two rivals, within limits.

Deterministic and frugal: each family is sampled at a few scrambled-Sobol points of its
[0, 1]^k coordinates (fixed seed), and the best feasible point overall is refined by a short
Nelder-Mead run (scipy). Each evaluation simulates both rivals and their parameter draws under
the candidate input, and scores it with the noise floor of its own recording
(``criterion.input_floor``). An input whose run (either rival's fitted model or any parameter
draw) uses more than ``margin`` of the speed or angle limit is infeasible: it scores below
every feasible one, by how far it overshoots, so the search is pulled back inside; one that
makes a rival diverge scores worst. The margin stands for what neither the fit nor its
intervals cover (the truth is neither rival). Of the ``rehearse`` best feasible inputs by D,
the one whose rehearsed decisions (``rehearsal``) separate the rivals most surely is chosen.
The winner is checked once more on both rivals' runs (``limits.violations``) before it is
returned.

The design must beat the same-length default chirp on D by ``min_gain`` (relative). Where
nothing sampled or refined does, the search goes on (``push`` evaluations): a compass search
from the chirp's own point in the chirp family, then from the best points of the other
families, stopping at the first input that beats it within the limits. Where none does, the
chirp is the design and ``Design.unbeaten`` says why: the limit the inputs with a higher D
broke, or that none evaluated had one (the search's budget binds).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize
from scipy.stats import qmc

from ..excitation import Chirp
from ..identify.windows import WindowDesign
from ..rehearse import Controller
from ..sim import Trace
from .criterion import discrimination
from .families import FAMILIES, chirp_point, programme
from .limits import Limits, shares, violations
from .criterion import input_floor
from .loop import ClosedLoop
from .rehearsal import Rehearsal, rehearse
from .response import Diverged, RivalModel, Windowed, windowed
from .rivals import Rival

_WORST = 1e9  # objective of an input under which a rival diverges
REFERENCE_TRIES = 6  # halvings of the default chirp's amplitude tried before it keeps within the limits
PUSH_STEP = 0.15     # first step of the compass search past the chirp (coordinates in [0, 1])
PUSH_SMALLEST = 0.02  # the compass search stops refining below this step
PUSH_STARTS = 3      # points the compass search goes on from: the chirp's, then the best others


@dataclass(frozen=True)
class SearchOptions:
    starts: int = 8                 # Sobol points per family (a power of two keeps Sobol balanced)
    refine: int = 16                # Nelder-Mead evaluations from the best point
    draws: int = 4                  # parameter draws per rival (antithetic pairs)
    seed: int = 0
    families: tuple[str, ...] = tuple(FAMILIES)
    rehearse: int = 2               # best inputs by D whose decision is rehearsed (0: choose by D)
    rehearse_iter: int = 8          # LM iterations of each rehearsed refit
    margin: float = 0.9             # share of the speed and angle limits the rivals' runs may use
    limit_draws: int = 2            # draws of every parameter per rival whose runs the limits are checked on
    min_gain: float = 0.05          # relative gain in D over the default chirp the design must reach
    push: int = 18                  # evaluations spent going on past the chirp where nothing beats it

    def __post_init__(self) -> None:
        if not 0 < self.margin <= 1:
            raise ValueError(f"margin={self.margin!r} must lie in (0, 1]")
        if not 0 <= self.min_gain < 10:
            raise ValueError(f"min_gain={self.min_gain!r} must lie in [0, 10)")
        for name in ("starts", "refine", "draws", "seed", "rehearse", "rehearse_iter", "limit_draws", "push"):
            value = getattr(self, name)
            least = 1 if name in ("starts", "rehearse_iter") else 0
            if not isinstance(value, int) or value < least:
                raise ValueError(f"{name}={value!r} must be an integer >= {least}")
        unknown = [f for f in self.families if f not in FAMILIES]
        if not self.families or unknown:
            raise ValueError(f"families={','.join(self.families)} must name input families "
                             f"(allowed: {', '.join(FAMILIES)})")


@dataclass
class Candidate:
    """One evaluated input: its family, coordinates, excitation and torque samples, score D,
    largest share of a limit used (by the rivals' fitted models and their parameter draws; speed
    and excursion against ``SearchOptions.margin`` of their limits),
    both rivals' runs, their windowed predictions in each run (None where a
    rival diverged), the noise floor D was computed with, for the inputs rehearsed, the
    rehearsed decisions, and the share of each limit used (as ``usage``, per limit)."""

    family: str
    point: tuple[float, ...]
    excitation: object
    u: np.ndarray
    score: float | None              # None: past a limit, not scored (``Evaluator.input``)
    usage: float
    traces: tuple[Trace, Trace] | None
    windowed: tuple[Windowed, Windowed] | None = None
    floor: dict[str, float] | None = None
    rehearsal: Rehearsal | None = None
    shares: dict[str, float] = field(default_factory=dict)
    row: int | None = field(default=None, repr=False)  # its row in ``Evaluator.evaluated``, once logged

    @property
    def feasible(self) -> bool:
        return self.traces is not None and self.usage <= 1.0

    def objective(self) -> float:
        """What the optimiser minimises: -D when feasible, the overshoot when not."""
        if self.traces is None:
            return _WORST
        return -self.score if self.feasible else self.usage


@dataclass
class Design:
    """The chosen experiment, the default chirp of the same length on the same criterion, and
    every input evaluated (family, point, D, usage)."""

    best: Candidate
    reference: Candidate
    rivals: tuple[Rival, Rival]
    noise: dict[str, float]
    limits: Limits
    evaluated: list[tuple[str, tuple[float, ...], float, float]] = field(default_factory=list)
    rehearsed: list[Candidate] = field(default_factory=list)
    loop: Controller | None = None   # closed loop: the controller (capped); inputs are link-angle references
    unbeaten: str | None = None      # why nothing beat the chirp by min_gain (None: the design does, or no chirp)

    @property
    def heldout_discrimination(self) -> float:
        """D scaled to the held-out windows the decision compares (D counts every window): the
        expected log-likelihood ratio of the decision, for the rivals as fitted."""
        return self.best.score * float(np.mean(self.best.windowed[0].holdout))

    @property
    def rehearsed_ratio(self) -> float | None:
        """The smaller of the chosen input's two rehearsed decisions' log-likelihood ratios (None:
        not rehearsed): the figure the realised ratio reached in most benchmark draws, not all
        (docs/design-experiments.md, Calibration), where D held-out over- or understates it;
        not a bound."""
        return None if self.best.rehearsal is None else self.best.rehearsal.score

    @property
    def beats_reference(self) -> bool | None:
        """Whether the design beats the chirp (None: the chirp breaks the limits, no comparison)."""
        return None if not self.reference.feasible else self.unbeaten is None


class Evaluator:
    """Scores inputs for one pair of rivals under the limits and noise floor (``noise`` None:
    each input's own, ``criterion.input_floor``)."""

    def __init__(self, rivals: tuple[Rival, Rival], noise: dict[str, float] | None, limits: Limits,
                 options: SearchOptions = SearchOptions(), window: WindowDesign = WindowDesign(),
                 loop: Controller | None = None):
        self.loop = None if loop is None else ClosedLoop(loop).capped(limits.max_torque)
        # An open-loop input is a torque within the torque limit; a reference, a link angle within
        # the range and no larger than the speed limit allows a sine at the band's lowest
        # frequency (2 periods per record): A 2 pi (2 / T) <= max_speed / N.
        gear = rivals[0].structure.gear_ratio
        self.peak = limits.max_torque if loop is None else min(
            limits.angle_range, limits.max_speed * limits.duration / (4 * np.pi * gear))
        self.models = tuple(RivalModel(r, limits.rate, options.draws, options.seed, self.loop, options.limit_draws)
                            for r in rivals)
        self.noise, self.limits, self.window, self.margin = noise, limits, window, options.margin
        self.evaluated: list[tuple[str, tuple[float, ...], float, float]] = []
        self._seen: dict[tuple, Candidate] = {}

    def input(self, family: str, point, excitation, u: np.ndarray, score_past_limits: bool = False,
              stop_early: bool = False, score: bool = True) -> Candidate:
        """Run and score one input. An input past a limit is not scored (``score`` None; the
        search only needs how far past it is), nor run for the parameter draws where the
        fitted models' runs already break a limit (its usage is then at least that), unless
        ``score_past_limits``: half the search's evaluations and most of the reference's
        bisection used to go on scoring inputs that could never be chosen. ``stop_early``: not
        even the second rival's run once the first breaks a limit (whether it does is all
        that is asked); ``score`` False: not scored even within the limits (``scored`` does it
        later)."""
        traces, runs = [], []
        try:
            for m in self.models:
                traces.append(m.run(u))
                runs.append(shares(traces[-1], self.limits, self.margin))
                if stop_early and max(runs[-1].values()) > 1.0:
                    break
            if score_past_limits or max(v for r in runs for v in r.values()) <= 1.0:
                runs += [shares(tr, self.limits, self.margin) for m in self.models for tr in m.draw_runs(u)]
        except Diverged:
            cand = Candidate(family, tuple(point), excitation, u, 0.0, np.inf, None)
        else:
            traces = tuple(traces)
            share = {k: max(r[k] for r in runs) for k in runs[0]}
            use = max(share.values())
            cand = Candidate(family, tuple(point), excitation, u, None, use, traces, shares=share)
            if score and (use <= 1.0 or score_past_limits):
                return self.scored(cand)
        self._log(cand)
        return cand

    def _log(self, cand: Candidate) -> None:
        """``cand``'s row in ``evaluated``: one per input run, its D filled in where it is
        scored after it was logged (the reference chirp's chosen amplitude)."""
        row = (cand.family, cand.point, cand.score, cand.usage)
        if cand.row is not None:
            self.evaluated[cand.row] = row
        else:
            cand.row = len(self.evaluated)
            self.evaluated.append(row)

    def scored(self, cand: Candidate) -> Candidate:
        """``cand`` with its D, the windowed predictions and the floor it was computed with."""
        traces = cand.traces
        cand.floor = self.noise if self.noise is not None else input_floor(self.models, traces, self.window)
        cand.windowed = tuple(windowed(self.models, tr, k, self.window) for k, tr in enumerate(traces))
        cand.score = discrimination(list(cand.windowed), cand.floor, self.limits.signals)
        self._log(cand)
        return cand

    def point(self, family: str, point) -> Candidate:
        """The input of ``family`` at ``point`` (clipped to [0, 1]^k), evaluated once: a point
        met again returns its first evaluation."""
        point = tuple(float(v) for v in np.clip(point, 0.0, 1.0))
        key = (family, tuple(round(v, 12) for v in point))
        if key not in self._seen:
            excitation, u = programme(family, point, self.limits, self.peak, log_amplitude=self.loop is not None)
            self._seen[key] = self.input(family, point, excitation, u)
        return self._seen[key]


def default_chirp(peak: float, scale: float = 1.0) -> Chirp:
    """The reference experiment: the shipped default chirp (30 -> 1 Hz), its amplitude capped
    at ``peak`` (the torque limit; in closed loop the angle range) and times ``scale``."""
    base = Chirp()
    return Chirp(amplitude=scale * min(base.amplitude, peak), f_start=base.f_start,
                 f_end=base.f_end, sweep=base.sweep)


def reference(ev: "Evaluator", limits: Limits, tolerance: float) -> Candidate:
    """The default chirp at the largest amplitude at which both rivals' runs keep within the
    limits, to within a factor ``1 + tolerance``: the fair comparison for a designed experiment.
    The amplitude is halved (up to REFERENCE_TRIES times) until it keeps within them, then
    bisected geometrically between the last two; only the chosen one is scored. Where even the
    smallest tried amplitude breaks a limit (a rival whose offset alone drives the link out of
    range), that run is returned, infeasible, scored all the same."""
    def attempt(scale: float) -> Candidate:
        chirp = default_chirp(ev.peak, scale)
        return ev.input("default chirp", (), chirp, chirp.sample(limits.rate, limits.duration),
                        stop_early=True, score=False)

    scale, hi, found, last = 1.0, None, None, None
    for _ in range(REFERENCE_TRIES):
        last = attempt(scale)
        if last.feasible:
            found = last
            break
        hi, scale = scale, scale / 2
    if found is None:
        return ev.input("default chirp", (), last.excitation, last.u, score_past_limits=True)
    lo = scale
    while hi is not None and hi / lo > 1 + tolerance:
        mid = float(np.sqrt(lo * hi))
        c = attempt(mid)
        if c.feasible:
            lo, found = mid, c
        else:
            hi = mid
    return ev.scored(found)


def design(rivals: tuple[Rival, Rival], noise: dict[str, float] | None, limits: Limits,
           options: SearchOptions = SearchOptions(), window: WindowDesign = WindowDesign(),
           progress=None, loop: Controller | None = None) -> Design:
    """The input that maximises D between ``rivals`` within ``limits`` (module doc); ``noise``
    None: each input's own floor (``criterion.input_floor``); ``loop``: the recording's
    controller, the input then a link-angle reference (``design.loop``).

    ``progress(evaluations, best D)`` is called after each evaluation. Raises ``ValueError`` when
    no evaluated input keeps both rivals within the limits.
    """
    ev = Evaluator(rivals, noise, limits, options, window, loop)
    best: Candidate | None = None
    pool: list[Candidate] = []
    family_best: dict[str, Candidate] = {}
    scored: list[tuple[float, dict[str, float]]] = []   # every input's D and limit shares ({}: diverged)

    met: set[int] = set()   # candidates already considered (a point met again is the same object)

    def consider(c: Candidate) -> Candidate:
        nonlocal best
        if id(c) not in met:
            met.add(id(c))
            scored.append((c.score, c.shares))
            if c.feasible:
                pool.append(c)
        if best is None or c.objective() < best.objective():
            best = c
        if c.family not in family_best or c.objective() < family_best[c.family].objective():
            family_best[c.family] = c
        if progress is not None:
            progress(len(ev.evaluated), best.score if best.feasible else 0.0)
        return c

    # The chirp's amplitude to within the square root of the gain: D grows as the square of a
    # linear response's amplitude, so the chirp itself, a little louder, cannot pass for a design.
    ref = reference(ev, limits, float(np.sqrt(1 + options.min_gain)) - 1)
    seed_point = (chirp_point(ref.excitation, limits, ev.peak, ev.loop is not None, nearest=True)
                  if "chirp" in options.families and ref.feasible else None)
    for family in options.families:
        dim = FAMILIES[family][0]
        points = list(qmc.Sobol(dim, scramble=True, seed=options.seed).random(options.starts))
        if family == "chirp" and seed_point is not None:  # the default chirp itself (or its nearest member)
            points.append(np.array(seed_point))
        for p in points:
            consider(ev.point(family, p))
    if options.refine and best is not None:
        start, family = np.array(best.point), best.family
        minimize(lambda p: consider(ev.point(family, p)).objective(), start, method="Nelder-Mead",
                 options={"maxfev": options.refine, "initial_simplex": _simplex(start)})
    target = (1 + options.min_gain) * ref.score
    if ref.feasible and options.push and not any(c.score > target for c in pool):
        starts = [("chirp", seed_point)] if seed_point is not None else []
        for c in sorted(family_best.values(), key=lambda c: c.objective()):
            if c.point and all(f != c.family or not np.allclose(p, c.point) for f, p in starts):
                starts.append((c.family, c.point))
        _push(ev, consider, starts[:PUSH_STARTS], target, options.push)
    # Only inputs that beat the default chirp on D by min_gain are rehearsed, so that the choice
    # among them never trades the design's advantage over the chirp away; where there are none,
    # the chirp is among the candidates and the design says why nothing beat it.
    unbeaten = None
    if ref.feasible:
        eligible = [c for c in pool if c.score > target]
        if not eligible:
            unbeaten = _why_unbeaten(scored, ref, options.min_gain)
            eligible = [c for c in [*pool, ref] if c.score >= ref.score]
    else:
        eligible = pool
    if not eligible:
        raise ValueError("no input of the families tried keeps both rivals within the limits "
                         "(raise --max-speed / --angle-range or lower --max-torque)")
    rehearsed = _rehearsed(eligible, rivals, window, options)
    best = max(rehearsed, key=lambda c: c.rehearsal.score) if rehearsed else max(eligible, key=lambda c: c.score)
    problems = [v for r, tr in zip(rivals, best.traces) for v in violations(tr, limits, r.effect)]
    if problems:  # the feasibility test above and this check read the same runs
        raise RuntimeError("; ".join(problems))
    return Design(best, ref, rivals, dict(best.floor), limits, ev.evaluated, rehearsed, ev.loop, unbeaten)


def _push(ev: Evaluator, consider, starts, target: float, budget: int) -> Candidate | None:
    """Compass search from each of ``starts`` ((family, point)) in turn, the budget shared
    evenly among those left, until an input within the limits has D above ``target``."""
    for k, (family, start) in enumerate(starts):
        share = budget // (len(starts) - k)
        before = len(ev.evaluated)
        found = _compass(ev, consider, family, np.asarray(start, float), target, share)
        budget -= len(ev.evaluated) - before
        if found is not None:
            return found
    return None


def _compass(ev: Evaluator, consider, family: str, x: np.ndarray, target: float, budget: int) -> Candidate | None:
    """Step each coordinate up and down by ``PUSH_STEP``, moving to any better point, halving the
    step where none is better; stop at an input within the limits with D above ``target``, when
    ``budget`` new evaluations are spent or the step falls below ``PUSH_SMALLEST``."""
    first = len(ev.evaluated)
    here, step = consider(ev.point(family, x)), PUSH_STEP
    while step >= PUSH_SMALLEST:
        moved = False
        for i in range(len(x)):
            for sign in (1.0, -1.0):
                y = x.copy()
                y[i] = np.clip(y[i] + sign * step, 0.0, 1.0)
                if y[i] == x[i]:
                    continue
                if len(ev.evaluated) - first >= budget:
                    return None
                c = consider(ev.point(family, y))
                if c.feasible and c.score > target:
                    return c
                if c.objective() < here.objective():
                    x, here, moved = y, c, True
                    break
        if not moved:
            step /= 2
    return None


def _why_unbeaten(scored, reference: Candidate, gain: float) -> str:
    """Why no input within the limits beat the chirp's D by ``gain``: the limit the chirp itself
    sits against, and the limits the inputs evaluated past them broke (each counted where it
    was the most used; none: the search's budget binds)."""
    within = sum(1 for score, s in scored if score is not None and s and max(s.values()) <= 1.0)
    counts: dict[str, int] = {}
    for _, s in scored:
        if not s or max(s.values()) > 1.0:
            name = max(s, key=s.get) if s else "a rival diverging"
            counts[name] = counts.get(name, 0) + 1
    name = max(reference.shares, key=reference.shares.get)
    text = (f"none of the {within} inputs evaluated within the limits had a D {gain:.0%} above the default "
            f"chirp's (which uses {reference.shares[name]:.2f} of the {name} limit)")
    if not counts:
        return text + "; none evaluated broke a limit: the search's budget binds"
    broken = ", ".join(f"{name} in {n}" for name, n in sorted(counts.items(), key=lambda kv: -kv[1]))
    return (text + f"; {sum(counts.values())} broke a limit (speed and excursion at the search's margin): "
            f"{broken}")


def _rehearsed(pool: list[Candidate], rivals, window: WindowDesign, options: SearchOptions) -> list[Candidate]:
    """The ``options.rehearse`` best distinct feasible inputs by D, each with its rehearsed
    decisions (``rehearsal``)."""
    seen, top = set(), []
    for c in sorted(pool, key=lambda c: -c.score):
        key = (c.family, c.point)
        if key in seen or len(top) >= options.rehearse:
            continue
        seen.add(key)
        c.rehearsal = rehearse(rivals, c.traces, c.floor, window, options.rehearse_iter)
        top.append(c)
    return top


def _simplex(x: np.ndarray, step: float = 0.15) -> np.ndarray:
    """A Nelder-Mead start simplex about x inside [0, 1]^k (each vertex steps inward)."""
    verts = [x]
    for i in range(len(x)):
        v = x.copy()
        v[i] += step if x[i] + step <= 1.0 else -step
        verts.append(v)
    return np.array(verts)
