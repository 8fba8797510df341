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
from .limits import Limits, usage, violations
from .criterion import input_floor
from .loop import ClosedLoop
from .rehearsal import Rehearsal, rehearse
from .response import Diverged, RivalModel, Windowed, windowed
from .rivals import Rival

_WORST = 1e9  # objective of an input under which a rival diverges
REFERENCE_TRIES = 6  # amplitudes of the default chirp tried, bisecting towards the limits


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

    def __post_init__(self) -> None:
        if not 0 < self.margin <= 1:
            raise ValueError(f"margin={self.margin!r} must lie in (0, 1]")
        for name in ("starts", "refine", "draws", "seed", "rehearse", "rehearse_iter", "limit_draws"):
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
    rival diverged), the noise floor D was computed with and, for the inputs rehearsed, the
    rehearsed decisions."""

    family: str
    point: tuple[float, ...]
    excitation: object
    u: np.ndarray
    score: float
    usage: float
    traces: tuple[Trace, Trace] | None
    windowed: tuple[Windowed, Windowed] | None = None
    floor: dict[str, float] | None = None
    rehearsal: Rehearsal | None = None

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

    def input(self, family: str, point, excitation, u: np.ndarray) -> Candidate:
        try:
            traces = tuple(m.run(u) for m in self.models)
            drawn = [tr for m in self.models for tr in m.draw_runs(u)]
        except Diverged:
            cand = Candidate(family, tuple(point), excitation, u, 0.0, np.inf, None)
        else:
            use = max(usage(tr, self.limits, self.margin) for tr in (*traces, *drawn))
            floor = self.noise if self.noise is not None else input_floor(self.models, traces, self.window)
            ws = tuple(windowed(self.models, tr, k, self.window) for k, tr in enumerate(traces))
            score = discrimination(list(ws), floor, self.limits.signals)
            cand = Candidate(family, tuple(point), excitation, u, score, use, traces, ws, floor)
        self.evaluated.append((family, cand.point, cand.score, cand.usage))
        return cand

    def point(self, family: str, point) -> Candidate:
        point = tuple(float(v) for v in np.clip(point, 0.0, 1.0))
        excitation, u = programme(family, point, self.limits, self.peak, log_amplitude=self.loop is not None)
        return self.input(family, point, excitation, u)


def default_chirp(peak: float, scale: float = 1.0) -> Chirp:
    """The reference experiment: the shipped default chirp (30 -> 1 Hz), its amplitude capped
    at ``peak`` (the torque limit; in closed loop the angle range) and times ``scale``."""
    base = Chirp()
    return Chirp(amplitude=scale * min(base.amplitude, peak), f_start=base.f_start,
                 f_end=base.f_end, sweep=base.sweep)


def reference(ev: "Evaluator", limits: Limits) -> Candidate:
    """The default chirp at the largest amplitude (bisected, REFERENCE_TRIES runs) at which both
    rivals' runs keep within the limits: the fair comparison for a designed experiment. Where
    even the smallest tried amplitude breaks a limit (a rival whose offset alone drives the link
    out of range), that run is returned, infeasible."""
    lo, hi, feasible, last = 0.0, 1.0, None, None
    for k in range(REFERENCE_TRIES):
        scale = 1.0 if k == 0 else 0.5 * (lo + hi)
        chirp = default_chirp(ev.peak, scale)
        last = ev.input("default chirp", (), chirp, chirp.sample(limits.rate, limits.duration))
        if last.feasible:
            feasible, lo = last, scale
            if k == 0:
                break
        else:
            hi = scale
    return feasible if feasible is not None else last


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

    def consider(c: Candidate) -> Candidate:
        nonlocal best
        if c.feasible:
            pool.append(c)
        if best is None or c.objective() < best.objective():
            best = c
        if progress is not None:
            progress(len(ev.evaluated), best.score if best.feasible else 0.0)
        return c

    ref = reference(ev, limits)
    for family in options.families:
        dim = FAMILIES[family][0]
        points = list(qmc.Sobol(dim, scramble=True, seed=options.seed).random(options.starts))
        seed_point = (chirp_point(ref.excitation, limits, ev.peak, ev.loop is not None)
                      if family == "chirp" and ref.feasible else None)
        if seed_point is not None:  # the default chirp itself: the design is at least as good
            points.append(np.array(seed_point))
        for p in points:
            consider(ev.point(family, p))
    if options.refine and best is not None:
        start, family = np.array(best.point), best.family
        minimize(lambda p: consider(ev.point(family, p)).objective(), start, method="Nelder-Mead",
                 options={"maxfev": options.refine, "initial_simplex": _simplex(start)})
    if best is None or not best.feasible:
        raise ValueError("no input of the families tried keeps both rivals within the limits "
                         "(raise --max-speed / --angle-range or lower --max-torque)")
    # Only inputs at least as good as the default chirp on D are rehearsed, so that the choice
    # among them never trades the design's advantage over the chirp away.
    # The chirp itself is a candidate: where nothing searched does better, it is the design.
    eligible = [c for c in [*pool, ref] if c.score >= ref.score] if ref.feasible else pool
    rehearsed = _rehearsed(eligible or pool, rivals, window, options)
    if rehearsed:
        best = max(rehearsed, key=lambda c: c.rehearsal.score)
    problems = [v for r, tr in zip(rivals, best.traces) for v in violations(tr, limits, r.effect)]
    if problems:  # the feasibility test above and this check read the same runs
        raise RuntimeError("; ".join(problems))
    return Design(best, ref, rivals, dict(best.floor), limits, ev.evaluated, rehearsed, ev.loop)


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
