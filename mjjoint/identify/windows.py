"""k-step-ahead prediction of a recording in short windows, batched through mujoco.rollout.

Why windows: recordings are taken in closed loop, and an open-loop replay of the measured
input drifts away from the measured motion (friction and gravity make free runs unstable
integrators of small errors), so a whole-record simulation error mostly measures drift.
Instead every window of ``length`` starts from the measured state (positions measured,
velocities from a Savitzky-Golay derivative, flexible segments at rest, the 2SEP states run
along the measured motor angle, or simulated through the dwell where a window starts at rest
or just after the motor turned or stopped, and the Bouc-Wen state along the measured deflection
up to the window) and predicts ``length`` ahead under the measured input. This is multiple
shooting without continuity constraints: errors cannot accumulate beyond one window, yet each window is
long enough (hundreds of ms) for dynamics — resonance, lag, hysteresis, play — to show. The
first ``warmup`` of every window is left out of the cost while the internal states settle. One
evaluation of all windows costs the same number of MuJoCo steps as one full-length rollout of
the recording.

Held-out data: a seeded random quarter of the windows is kept out of fitting. Random, because
any periodic pattern can alias with a periodic excitation (a step every 0.5 s and every 4th
0.25 s window held out puts no step onset in the test set at all).
"""
from __future__ import annotations

import copy
import ctypes
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from functools import cached_property

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout
from scipy.signal import lfilter, savgol_coeffs, savgol_filter

from ..coupling.kernels import friction_history, hysteresis_history
from ..coupling.layout import TRANSMISSION, X, steady_states, term_slots, term_states
from ..assets.stability import check_model_stability
from ..coupling.mjlog import mujoco_log_silenced
from ..coupling.plugin import register_model
from ..params import substeps
from ..recordings.rates import savgol_rate
from ..recordings.resample import STEP_TOLERANCE
from ..physics.twosep import TwoSEP
from ..sim import FULL, joint_indices, state_velocity
from .stages import for_prediction
from .structure import Structure

SIGNALS = ("q", "delta", "tau")
# Window-start velocities: a 7 ms cubic Savitzky-Golay derivative. Longer or lower-order
# filters bias the velocity of the ~40 Hz transmission mode, which then rings through the
# lightly damped window; 7 ms / order 3 gives the true model the lowest prediction cost on
# quantised closed-loop recordings of the shipped arm.
VELOCITY_WINDOW = 0.007
VELOCITY_ORDER = 3
# Rollout output buffer per predict() call [bytes]. MuJoCo writes the full state of every
# step (2 steps x (37 + 5) doubles = 672 B per sample and model for the shipped arm); holding
# a whole batch grows with recording x models (3 GB for a 10-minute recording's 10-model
# Jacobian), so the batch is rolled out in chunks of this size (and a free run of the whole
# recording in stretches of it, ``Predictor._stretches``). 64 MiB holds ~400 windows of
# 0.25 s, so a 4-model Jacobian of recordings up to ~30 s stays one call; chunking costs no
# speed (716 window rollouts of a 60 s lab recording, 2 cores: 0.69 s in two chunks, 0.76 s
# in one). Peak memory: scripts/bench_fit.py --memory.
ROLLOUT_BUFFER = 64 * 2 ** 20
# The internal states' histories along the recording kept for reuse (``Predictor._history``):
# a 10-minute recording's 2SEP history is 24 MB, its Bouc-Wen history 5 MB.
HISTORY_BYTES = 32 * 2 ** 20
# A rollout call of at most this many steps in all runs on the calling thread: handing its rows to
# the thread pool costs more than they take (a flexible lead-in's sample, ~10 rows of 2 steps of
# the shipped arm: 63 us on the calling thread, 97 us on 2 threads; 10 rows of 20 steps: 559 us
# and 352 us).
SERIAL_STEPS = 100
# 2SEP's window-start states are run along the measured motor angle, with the angle's retraces
# smaller than its measurement noise taken for none: a play operator of half-width
# REVERSAL_BAND x the noise std (``Measured.q_path``). A resting motor's quantised encoder
# toggles between two counts (peak to peak sqrt(12) std for uniform quantisation error), and
# a Savitzky-Golay velocity of that chatter crosses zero again and again; each crossing is a
# reversal to 2SEP, which resets its pre-sliding memory. Run along that velocity the TRUE model
# of the 20 s dynamic_friction case predicted held-out windows hardly better than the base
# model without 2SEP (cost 0.00253 vs 0.00267); along the play-filtered angle it reaches
# 0.00034 (half-widths of 1-5 std: 0.00034-0.00039). 3 std: a retrace must exceed 6 std, well
# beyond one quantisation toggle (sqrt(12) = 3.5 std) even when the estimate is 10-20 % low.
# Bouc-Wen's history runs along the deflection filtered the same way (``Measured.delta_path``).
REVERSAL_BAND = 3.0
# Window starts are kept off input jumps. The start velocity is a centred Savitzky-Golay
# derivative, and a step of u puts a kink in q inside its stencil: the biased velocity then
# drifts through the whole lightly damped window. The lab excitation steps on whole seconds,
# on the 0.25 s window grid: in the TRUE model's predictions of the 20 s dynamic_friction case
# the four windows starting on a step held 85 % of the training cost, and starts moved off
# the steps cut the mean window cost 7x. A jump is a change of u's per-sample slope by more
# than JUMP_SHARE of u's 1-99 % range within one sample: a 30 Hz chirp turns its slope by
# 1.8 % of its range per sample, a lab step by 20-50 %.
JUMP_SHARE = 0.05
# Lead-in of every window of a flexible link [s] (Predictor._flexible_start): a few periods of
# the rod's first bending mode (25 Hz on the shipped arm), so the vibration a straight start
# sets off has died down and what remains is the vibration the hub's motion drove.
FLEX_LEAD = 0.1
# Longest lead-in a window may ask for [s] (WindowDesign.lead): far beyond any dwell a lead-in is
# for, and a bound on its cost.
MAX_LEAD = 60.0
# A resting window's 2SEP states come from a free lead-in through the stop before it, whose
# start is a choice: the last sample faster than f x ``Measured.moving_speed``, f in
# LEAD_FACTORS. Where the model's predictions from those starts differ by more than UNDETERMINED
# noise floors (mean square per window), the recording does not fix the window's start state
# for that model and the window is left out of its fit (``Predictor.undetermined``). On the
# concealed dynamic_friction cases (``scripts/lead_in_spread.py``) the spread is 6-69 000 noise
# floors on the breakaways after dwells, at most 1.2 on every other resting window.
LEAD_FACTORS = (1.0, 3.0, 10.0)
UNDETERMINED = 3.0
# A window that starts moving but within its warmup of a sample slower than TRANSIENT x
# ``Measured.moving_speed`` (a reversal, a stop) starts inside 2SEP's transient: the pre-sliding
# force since the reversal and the lag's windup depend on where the motor turned to within a
# fraction of an encoder count, which the measured angle does not give. Its 2SEP states come
# from a lead-in too, from the last sample faster than that before the slow one (on a rigid
# link: ``_start_states``). On the concealed dynamic_friction case of seed 1 the TRUE model's
# least-squares fit (from the truth) put the lag gain B at 31.2 (truth 40.3) with the states run
# along the measured angle there, and at 38.6 with these lead-ins (ideal sensors and the
# simulator's own states at every start: 40.2).
TRANSIENT = LEAD_FACTORS[-1]


@dataclass(frozen=True)
class WindowDesign:
    length: float = 0.25       # [s] prediction horizon of each window
    warmup: float = 0.02       # [s] excluded from the cost at each window start
    decimate: int = 2          # residual every k-th sample
    holdout: float = 0.25      # share of windows held out of fitting
    seed: int = 0              # which windows: random, so the split cannot alias with the excitation
    lead: float = 1.0          # [s] longest lead-in of a window that starts at rest (Predictor._start_states)

    def __post_init__(self) -> None:
        if not self.warmup > 0:
            raise ValueError(f"warmup={self.warmup} must be positive")
        if not self.length > self.warmup:
            raise ValueError(f"window length={self.length} s must exceed its warm-up of {self.warmup} s, "
                             "excluded from the cost at each start (--window-length)")
        if not 0 <= self.lead <= MAX_LEAD:
            raise ValueError(f"lead={self.lead} must lie in [0, {MAX_LEAD:g}] s")


@dataclass
class Measured:
    """The recording on a uniform grid with what the windows need.

    ``theta`` is None for a plant without an output side (a direct drive): only q is predicted.
    """

    t: np.ndarray
    u: np.ndarray
    q: np.ndarray
    theta: np.ndarray | None
    tau: np.ndarray | None
    qd: np.ndarray
    thetad: np.ndarray | None
    gear_ratio: float
    rate: float
    joins: tuple[int, ...] = ()  # samples where a further recording begins (stacked logs)
    # False where theta is the motor angle over the gear (a servo with one encoder, its theta
    # taken as q/N): the deflection is then not measured, so neither scored nor reported.
    link_encoder: bool = True

    @property
    def delta(self) -> np.ndarray | None:
        return None if self.theta is None else self.q / self.gear_ratio - self.theta

    @property
    def measured_delta(self) -> np.ndarray | None:
        """The deflection as a sensor pair measured it: None with one encoder (``link_encoder``)."""
        return self.delta if self.link_encoder else None

    @property
    def segments(self) -> list[tuple[int, int]]:
        """(first, end) sample of each recording stacked here (one pair for a single recording)."""
        bounds = [0, *self.joins, len(self.t)]
        return list(zip(bounds[:-1], bounds[1:]))

    def step_velocity(self, name: str, h: float, at: np.ndarray) -> np.ndarray:
        """The velocity of ``name`` (q or theta) at samples ``at`` (fractional: interpolated) as a
        semi-implicit Euler state of step h holds it (``sim.state_velocity``). With the input
        held centred on the steps (``Predictor._controls``) the positions are then second-order
        accurate at the samples."""
        v = self.qd if name == "q" else self.thetad
        samples = np.arange(len(v))
        return state_velocity(np.interp(at, samples, v), np.interp(at, samples, self.acceleration[name]), h)

    @cached_property
    def acceleration(self) -> dict[str, np.ndarray]:
        """The second derivatives of q and theta (those recorded), segment by segment."""
        dt = 1.0 / self.rate
        acc = lambda x: savgol_filter(x, _sg_window(dt), VELOCITY_ORDER, deriv=2, delta=dt)  # noqa: E731
        return {k: self.per_segment(acc, x) for k, x in (("q", self.q), ("theta", self.theta)) if x is not None}

    def per_segment(self, f, x: np.ndarray) -> np.ndarray:
        """``f`` applied to each segment of ``x`` on its own: no filter or operator runs across a join."""
        return np.concatenate([f(x[a:b]) for a, b in self.segments])

    @cached_property
    def delta_path(self) -> np.ndarray | None:
        """The deflection with retraces within its noise band removed (REVERSAL_BAND): the path
        Bouc-Wen's history runs along. A quantised encoder's toggles are tiny reversals, each of
        which moves a hysteresis state; a smoothing filter passes them on as slow wiggles, the
        play does not (docs/diagnosis.md, "The cost")."""
        d = self.delta
        return None if d is None else self._retrace_free(d, noise_std(d, self.rate, self.per_segment))

    @cached_property
    def q_noise(self) -> float:
        """Measurement noise (std) of q (``noise_std``), each stacked recording smoothed on its own."""
        return noise_std(self.q, self.rate, self.per_segment)

    @property
    def moving_speed(self) -> float:
        """[rad/s] One play band (REVERSAL_BAND noise std) per sample: below it the motor is taken
        at rest (a window's lead-in, a resting start)."""
        return REVERSAL_BAND * self.q_noise * self.rate

    @cached_property
    def q_path(self) -> np.ndarray:
        """The motor angle with retraces within its noise band removed (REVERSAL_BAND): the path
        2SEP's history runs along, so that encoder chatter at rest is no reversal."""
        return self._retrace_free(self.q, self.q_noise)

    def _retrace_free(self, x: np.ndarray, noise: float) -> np.ndarray:
        """``x`` with retraces within REVERSAL_BAND noise std removed, each stacked recording on its own."""
        return self.per_segment(lambda seg: _play(seg, REVERSAL_BAND * noise), x)

    @classmethod
    def from_recording(cls, rec, gear_ratio: float, output: bool = True) -> "Measured":
        """Resample ``rec`` on its mean period; ``output=False`` ignores its theta (direct drive)."""
        t = np.asarray(rec.t, float)
        # The mean period, not the median: stored time stamps carry rounding (EMPS: median
        # 0.99998 ms for a 1 kHz record), which would put the grid off the simulator's step.
        dt = float(t[-1] - t[0]) / (len(t) - 1)
        grid = t[0] + dt * np.arange(len(t))
        names = ("u", "q", "theta", "tau") if output else ("u", "q", "tau")
        # Samples already on the grid but for the stamps' rounding are taken as they are:
        # interpolating by fractions of 1e-13 would blend neighbours into values a quantised
        # sensor cannot read, and hide its step from the noise floor.
        on_grid = np.max(np.abs(t - grid)) <= STEP_TOLERANCE * dt  # the reader's test of a uniform clock
        take = (lambda x: x) if on_grid else (lambda x: np.interp(grid, t, x))  # noqa: E731
        cols = {k: None if getattr(rec, k, None) is None else take(np.asarray(getattr(rec, k), float))
                for k in names}
        cols.setdefault("theta", None)
        deriv = lambda x: None if x is None else velocity(x, dt)  # noqa: E731
        return cls(t=grid, qd=deriv(cols["q"]), thetad=deriv(cols["theta"]),
                   gear_ratio=float(gear_ratio), rate=1.0 / dt,
                   link_encoder=not _one_encoder(cols["q"], cols["theta"], gear_ratio), **cols)

    @classmethod
    def stack(cls, parts: Sequence["Measured"]) -> "Measured":
        """Several recordings end to end on one uniform time line, kept apart as segments
        (``joins``): no window spans two, and each one's velocities, paths, internal-state
        history and lead-ins start afresh as at a recording's start (``Predictor``)."""
        first = parts[0]
        for k, m in enumerate(parts[1:], start=2):
            if abs(m.rate - first.rate) > 1e-6 * first.rate:
                raise ValueError(f"recordings to stack must share one sample rate: recording 1 has "
                                 f"{first.rate:.6g} Hz, recording {k} {m.rate:.6g} Hz")
            if (m.theta is None) != (first.theta is None) or (m.tau is None) != (first.tau is None):
                raise ValueError(f"recordings to stack must hold the same signals (theta, tau): recording {k} differs")
            if m.gear_ratio != first.gear_ratio:
                raise ValueError(f"recordings to stack must share one gear ratio: {first.gear_ratio:g}, {m.gear_ratio:g}")
            if m.link_encoder != first.link_encoder:
                raise ValueError(f"recordings to stack must all have a link encoder or none: in recording {k} "
                                 f"theta {'is' if first.link_encoder else 'is not'} q/N")
        cat = lambda k: None if getattr(first, k) is None else np.concatenate([getattr(m, k) for m in parts])  # noqa: E731
        offsets = np.cumsum([0, *(len(m.t) for m in parts)])
        joins = tuple(int(o + j) for m, o in zip(parts, offsets) for j in (*m.joins, len(m.t)))[:-1]
        return cls(t=first.t[0] + np.arange(offsets[-1]) / first.rate, u=cat("u"), q=cat("q"), theta=cat("theta"),
                   tau=cat("tau"), qd=cat("qd"), thetad=cat("thetad"), gear_ratio=first.gear_ratio,
                   rate=first.rate, joins=joins, link_encoder=first.link_encoder)


# Relative agreement of theta with q/N past which they are one encoder's angle, not two: two
# encoders differ by the gear's deflection, orders above a float's rounding.
ONE_ENCODER = 1e-9


def _one_encoder(q: np.ndarray, theta: np.ndarray | None, gear_ratio: float) -> bool:
    """Whether ``theta`` is ``q / gear_ratio`` to rounding (``Measured.link_encoder``)."""
    if theta is None:
        return False
    scale = max(float(np.max(np.abs(theta))), float(np.max(np.abs(q))) / gear_ratio)
    return bool(np.max(np.abs(q / gear_ratio - theta)) <= ONE_ENCODER * scale)


def noise_std(x: np.ndarray, rate: float, per_segment=None) -> float:
    """Measurement noise (std) of a signal: robust spread of x about its Savitzky-Golay smoothing.

    The median absolute deviation ignores the few samples where the smoothing misses fast
    motion; the factor undoes the share of the noise the smoothing itself follows. On a
    15-bit resolver it returns the quantisation step / sqrt(12) within 10 %. ``per_segment``
    (``Measured.per_segment``): smooth each stacked recording on its own.
    """
    win = _sg_window(1.0 / rate)
    smooth = lambda y: savgol_filter(y, win, VELOCITY_ORDER)  # noqa: E731
    r = x - (smooth(x) if per_segment is None else per_segment(smooth, x))
    follow = savgol_coeffs(win, VELOCITY_ORDER)[win // 2]
    return float(1.4826 * np.median(np.abs(r - np.median(r))) / np.sqrt(1.0 - follow))


def _play(x: np.ndarray, eps: float) -> np.ndarray:
    """Play (backlash) operator of half-width ``eps``: follows x once it is more than eps away."""
    x = np.asarray(x, float)
    if eps <= 0.0:
        return x.copy()
    y = np.empty_like(x)
    yi = float(x[0])
    for i, xi in enumerate(x.tolist()):
        if xi > yi + eps:
            yi = xi - eps
        elif xi < yi - eps:
            yi = xi + eps
        y[i] = yi
    return y


def window_starts(total: int, n: int, u: np.ndarray, half: int, max_shift: int,
                   joins: tuple[int, ...] = ()) -> np.ndarray:
    """Starts of ``n``-sample windows tiling ``total`` samples, each kept off jumps of u.

    Each window starts where the one before ended, unless a jump of u (JUMP_SHARE) lies inside
    that start's velocity stencil (``half`` samples either side): then it starts earlier, by the
    most of ``max_shift`` samples that clears the stencil. Moved back at most by the warmup, a
    window shares no cost sample with its predecessor; the step falls late in its warmup or in
    its cost; and the windows still cover the recording without a gap. A start that no shift
    clears stays where it is. At ``joins`` the tiling starts afresh, and no window crosses one.
    A log's first window starts at its first sample, whose velocity stencil is one-sided, unless
    the input jumps inside that stencil: then where the whole centred stencil is clear of jumps,
    at most ``max_shift`` in, if such a start exists (the later windows keep their grid: the
    first ends inside the second's warmup). A one-sided stencil fits one polynomial through whatever the loop did
    first; through a controller's first kicks it gave a resting motor 1.6 rad/s, which rang
    through the window.
    """
    lo, hi = np.percentile(u, [1.0, 99.0])
    kink = np.abs(np.diff(u, 2)) > JUMP_SHARE * max(hi - lo, np.finfo(float).tiny)
    # kink[i]: u's slope turns at sample i + 1, a kink of q between samples i + 1 and i + 2.
    at = np.concatenate([[0], np.cumsum(kink)])

    def clear(s: int, since: int = 0) -> bool:  # no kink strictly inside the stencil s - half .. s + half
        a, b = (min(max(k, since), len(kink)) for k in (s - half - 1, s + half - 1))  # none before the log
        return at[b] == at[a]

    starts = []
    for first, end in zip((0, *joins), (*joins, total - 1)):
        s, last_end = first, first
        while s + n <= end:
            if s == first:  # at the log's start, unless the input jumps inside its one-sided stencil
                start = first if clear(first + half, first) else first + next(
                    (d for d in range(half + 1, max_shift + 1) if clear(first + d, first)), 0)
            else:  # back off a jump by what the warmup holds beyond the last window's end
                room = max_shift - max(last_end - s, 0)
                start = s = s - (0 if clear(s) else next((d for d in range(room, 0, -1) if clear(s - d)), 0))
            if start + n > end:
                break
            starts.append(start)
            last_end = start + n
            s += n
    return np.array(starts, dtype=int)


def velocity(x: np.ndarray, dt: float) -> np.ndarray:
    """The derivative of a uniformly sampled signal, the Savitzky-Golay one of window starts."""
    width = _sg_window(dt)
    if len(x) < width:
        raise ValueError(f"{len(x)} samples at {1.0 / dt:.6g} Hz are fewer than the derivative's window of {width} "
                         f"({VELOCITY_WINDOW * 1e3:g} ms): record longer (or check t's unit)")
    return savgol_rate(x, width, VELOCITY_ORDER, dt)


def _sg_window(dt: float) -> int:
    """Savitzky-Golay window [samples] of about VELOCITY_WINDOW, odd, at least 5."""
    return max(5, int(round(VELOCITY_WINDOW / dt)) | 1)


class Predictor:
    """Windowed predictions of one recording for any number of model structures."""

    # What the columns of ``_controls`` set each step (mujoco.mjtState bits); a subclass that
    # applies more per step (``manipulator.LoadedPredictor``: a known load) extends both.
    control_spec = int(mujoco.mjtState.mjSTATE_CTRL)

    def __init__(self, measured: Measured, design: WindowDesign = WindowDesign(), nthread: int | None = None,
                 fit_signals: tuple[str, ...] | None = None):
        """``fit_signals``: the measured signals the cost scores (default all of SIGNALS the
        recording has); NRMSE still reports every one."""
        unknown = sorted(set(fit_signals or ()) - set(SIGNALS))
        if unknown:
            raise ValueError(f"fit_signals: {unknown[0]!r} is not allowed (allowed: {', '.join(SIGNALS)})")
        self.m = measured
        self.design = design
        self.fit_signals = fit_signals
        n = int(round(design.length * measured.rate))
        self.nwin_samples = n
        w0 = int(round(design.warmup * measured.rate))
        starts = window_starts(len(measured.t), n, measured.u, _sg_window(1.0 / measured.rate) // 2, w0,
                                measured.joins)
        if len(starts) < 8:
            raise ValueError(f"recording of {measured.t[-1] - measured.t[0]:.2f} s is too short for "
                             f"{design.length} s windows: it holds {len(starts)} whole ones past the start's "
                             "derivative stencil, at least 8 are needed (record longer, or --window-length)")
        self.starts = starts
        self.samples = starts[:, None] + np.arange(n)[None, :]  # recording sample of each window sample
        # The samples each window is the first to cover: a moved start's warmup repeats the end
        # of the window before it; views of the whole recording take each sample once.
        lead = np.maximum(np.r_[0, starts[:-1] + n - starts[1:]], 0)
        self.owned = np.arange(n)[None, :] >= lead[:, None]
        self.holdout = held_out(design, len(starts))
        self.left_out = np.zeros(len(starts), bool)  # held-out windows no model is scored on (``leave_out``)
        self.cols = np.arange(w0, n, design.decimate)  # sample offsets used in the cost
        self.nthread = nthread if nthread is not None else _cores()
        meas = self.measured_windows()
        # Fixed per-signal normalisation: spread of each signal around its window mean.
        self.scale = {}
        for s, w in meas.items():
            if w is None:
                continue
            spread = w - w.mean(axis=1, keepdims=True)
            self.scale[s] = float(np.sqrt(np.mean(spread ** 2))) or 1.0
        self.meas = meas
        self.rollouts = 0.0  # in full-recording equivalents
        self._scratch: dict = {}  # rollout MjData per model signature (_datas)
        self._histories: dict = {}  # internal states along the recording (_history)

    def _model(self, structure: Structure):
        """The compiled model a structure is simulated on (memoised): the single joint's."""
        return _compile(*structure.model_params())

    def stable(self, structure: Structure) -> bool:
        """Whether the structure's compiled model passes the stability check (memoised). Values
        the model refuses (a range the recording's estimate widened past a validated limit, as
        g beyond 100 m/s^2) score as an unstable model does, not stop the fit."""
        try:
            model = self._model(structure)
        except ValueError:
            return False
        return _stable(model)

    def _joint(self, model):
        """The joint the recording measures, in ``model``."""
        return joint_indices(model)[0]

    def on(self, measured: Measured, fit_signals: tuple[str, ...] | None = None) -> "Predictor":
        """A predictor of the same model kind and windows for other measurements (a twin of the
        recording, ``identify.twin``), scoring ``fit_signals`` (default every signal they hold)."""
        return Predictor(measured, self.design, self.nthread, fit_signals)

    # ---- measured ----------------------------------------------------------------------
    def measured_windows(self) -> dict[str, np.ndarray | None]:
        idx = self.samples
        m = self.m
        pick = lambda x: None if x is None else x[idx]  # noqa: E731
        return {"q": m.q[idx], "delta": pick(m.measured_delta), "theta": pick(m.theta), "tau": pick(m.tau)}

    @property
    def signals(self) -> tuple[str, ...]:
        """The signals the cost scores."""
        return tuple(s for s in SIGNALS if self.meas.get(s) is not None
                     and (self.fit_signals is None or s in self.fit_signals))

    @property
    def reported_signals(self) -> tuple[str, ...]:
        """Every signal the recording holds, scored or not (the NRMSE reports each)."""
        return tuple(s for s in ("q", "theta", "delta", "tau") if self.meas.get(s) is not None)

    # ---- prediction --------------------------------------------------------------------
    def predict(self, structures: list[Structure], windows: np.ndarray | None = None,
                assume_stable: bool = False) -> list[dict[str, np.ndarray]]:
        """Predicted q, theta, delta, tau (windows x samples) for each structure.

        ``assume_stable``: the caller vouches that the structures are stable (a finite-difference
        Jacobian's models, each 1e-8 from a point that was checked), so their compiled models are
        not checked (``_stable``: a few ms each, as much as a short window batch's rollout)."""
        return list(self.predictions(structures, windows, assume_stable))

    def predictions(self, structures: list[Structure], windows: np.ndarray | None = None,
                    assume_stable: bool = False) -> Iterator[dict[str, np.ndarray]]:
        """``predict``'s predictions one structure at a time, each as soon as its windows are
        rolled out: a caller that reduces each one (to residuals) holds one structure's
        predictions, not a whole batch's (they grow with recording x models). To be used up
        before the predictor is used again."""
        windows = np.arange(len(self.starts)) if windows is None else np.asarray(windows)
        stable = [True] * len(structures) if assume_stable else [self.stable(s) for s in structures]
        if not all(stable):
            # Explicitly unstable parameters are not simulated: they score as NaN (worst).
            good = [s for s, ok in zip(structures, stable) if ok]
            done = self.predictions(good, windows) if good else iter(())
            nan = np.full((len(windows), self.nwin_samples), np.nan)
            for ok in stable:
                yield next(done) if ok else {k: nan for k in ("q", "theta", "delta", "tau")}
            return
        models, delays, skews = [], [], []
        for s in structures:
            delays.append(s.model_params()[0].input_delay)
            skews.append(s.skew)
            models.append(self._model(s))
        sig = {_signature(m) for m in models}
        if len(sig) > 1:
            for s in structures:
                yield from self.predictions([s], windows)
            return
        for mod in models:
            register_model(mod)  # a memoised model's registry row may have been recycled
        jis = [self._joint(mod) for mod in models]  # parsed once per model and call
        i0 = self.starts[windows]
        lead_ins: list = []  # the flexible lead-ins of all models, run together (``_flexible_start``)
        x0 = [self._start_states(mod, ji, d, windows, k, lead_ins) for mod, d, ji, k in zip(models, delays, jis, skews)]
        self._flexible_start(lead_ins)
        x0 = np.concatenate(x0)
        n, nw = self.nwin_samples, len(windows)

        def controls(a: int, b: int) -> np.ndarray:  # rows a..b: model k's windows are rows k nw..(k + 1) nw
            return np.concatenate([self._controls(models[k], i0[max(a - k * nw, 0):b - k * nw], n, delays[k], jis[k])
                                   for k in range(a // nw, (b - 1) // nw + 1)])
        batch_models = [mod for mod in models for _ in windows]
        sub = self._substeps(models[0])
        self.rollouts += len(structures) * nw / len(self.starts)
        parts: list = []  # the model's windows rolled out so far, by chunk
        for a, b, state in self._rollouts(batch_models, x0, controls, (n - 1) * sub):
            for k in range(a // nw, (b - 1) // nw + 1):  # the models whose windows this chunk holds
                lo, hi = max(a, k * nw), min(b, (k + 1) * nw)
                picked = state[lo - a:hi - a, sub - 1::sub][:, : n - 1]
                parts.append(self._signals(models[k], np.concatenate([x0[lo:hi, None], picked], axis=1), jis[k]))
                if hi == (k + 1) * nw:  # model k's last window
                    yield structures[k].measured(_joined(parts), self.m.rate)
                    parts = []  # gone before the next model's windows are rolled out

    def free_run(self, structure: Structure) -> dict[str, np.ndarray]:
        """The structure simulated under the measured input without restarts: from the first
        window of each stacked recording to its end, as the recording would have been made.

        Returns q, theta, delta, tau over the whole recording as the structure's sensors read
        them (``Structure.measured``, as its window predictions are; samples no run reaches,
        before a recording's first window, keep the measured values; NaN where the run diverged).
        The run is rolled out in consecutive stretches (``_rollouts``), so its memory does not
        grow with the recording's length.
        """
        arm = structure.model_params()[0]
        model = self._model(structure)
        register_model(model)
        ji = self._joint(model)
        sub = self._substeps(model)
        m = self.m
        measured = {"q": m.q, "theta": m.theta, "delta": m.delta, "tau": m.tau}
        out = {k: np.array(v, float) if v is not None else np.full(len(m.t), np.nan) for k, v in measured.items()}
        for first, end in m.segments:
            inside = np.flatnonzero((self.starts >= first) & (self.starts < end))
            if inside.size == 0:
                continue
            w = inside[0]
            i0 = int(self.starts[w])
            n = end - i0
            x0 = self._start_states(model, ji, arm.input_delay, np.array([w]), structure.skew)
            ctrl = self._controls(model, np.array([i0]), n, arm.input_delay, ji)
            for k, v in self._signals(model, x0[:, None], ji).items():
                out[k][i0] = v[0, 0]
            for step, state in self._stretches(model, x0, ctrl, sub):
                at = i0 + 1 + step // sub  # the sample the stretch's first kept step ends on
                for k, v in self._signals(model, state[:, sub - 1::sub], ji).items():
                    out[k][at:at + v.shape[1]] = v[0]
            seen = structure.measured({k: v[i0:end] for k, v in out.items()}, m.rate)
            for k, v in out.items():
                v[i0:end] = seen[k]
        return out

    def _rollouts(self, models: list, x0: np.ndarray, ctrl, nstep: int | None = None):
        """Roll out rows (models, x0, ctrl) in chunks that fit ROLLOUT_BUFFER; yields (a, b,
        states of rows a..b), a view valid until the next chunk. ``ctrl``: the controls of all
        rows, or a function (a, b) -> those of rows a..b over ``nstep`` steps, built per chunk
        (a whole batch's controls grow with recording x models)."""
        rows = ctrl if callable(ctrl) else (lambda a, b: ctrl[a:b])
        datas = self._datas(models[0])
        nrow, nx, nsens = len(models), x0.shape[1], models[0].nsensordata
        nstep = ctrl.shape[1] if nstep is None else nstep
        chunk = min(nrow, max(len(datas), ROLLOUT_BUFFER // (8 * nstep * (nx + nsens))))
        pooled = nrow * nstep > SERIAL_STEPS
        state, sens = np.empty((chunk, nstep, nx)), np.empty((chunk, nstep, nsens))
        for a in range(0, nrow, chunk):
            b = min(a + chunk, nrow)
            with mujoco_log_silenced():  # shapes are right by construction: unchecked, as a sample's call is short
                mj_rollout.rollout(models[a:b], datas if pooled else datas[:1], np.ascontiguousarray(x0[a:b]),
                                   np.ascontiguousarray(rows(a, b)), control_spec=self.control_spec,
                                   state=state[:b - a], sensordata=sens[:b - a], nstep=nstep, skip_checks=True,
                                   persistent_pool=pooled)
            yield a, b, state[:b - a]
            release_freed(state.nbytes + sens.nbytes)  # the chunk's arrays, consumed (sized as its buffers)

    def _stretches(self, model, x0: np.ndarray, ctrl: np.ndarray, sub: int):
        """One row (x0 (1, nx), ctrl (1, steps, nu)) rolled out in consecutive stretches of whole
        samples that fit ROLLOUT_BUFFER, each from the full physics state the one before ended
        in; yields (first step, states (1, stretch, nx)), a view valid until the next stretch.
        The same run as one rollout: the state carries everything a step reads but the
        constraint solver's warm start, which restarts at zero (the same solution, to the
        solver's tolerance, where a constraint is active at a stretch's start; none in the
        plants built here)."""
        nstep = ctrl.shape[1]
        per = ROLLOUT_BUFFER // (8 * (x0.shape[1] + model.nsensordata))
        per = max(sub, per - per % sub)
        x = x0
        for a in range(0, nstep, per):
            for _, _, state in self._rollouts([model], x, ctrl[:, a:a + per]):
                yield a, state
                x = state[:, -1].copy()

    def _datas(self, model) -> list:
        """Scratch MjData for the rollout threads, one set per model signature, kept across
        calls (each new MjData runs the plugin's init): the rows set every state they read."""
        key = (_signature(model), self.nthread)
        if key not in self._scratch:
            self._scratch[key] = [mujoco.MjData(model) for _ in range(max(1, self.nthread))]
        return self._scratch[key]

    def _signals(self, model, full: np.ndarray, ji) -> dict[str, np.ndarray]:
        nw, ns, nx = full.shape
        flat = full.reshape(nw * ns, nx)
        q, _, th, _ = ji.motion(model, flat)
        tau = ji.transmission(model, flat)
        shape = (nw, ns)
        # Copies: views of q and theta would keep all of ``full`` (every state column) alive.
        return {"q": q.reshape(shape).copy(), "theta": th.reshape(shape).copy(),
                "delta": (q / ji.gear_ratio - th).reshape(shape), "tau": tau.reshape(shape)}

    def _substeps(self, model) -> int:
        return substeps(self.m.rate, model.opt.timestep, "the recording's rate")

    def _initial_states(self, model, i0: np.ndarray, ji, skew: float = 0.0) -> np.ndarray:
        """Full MuJoCo states at samples ``i0``: measured motion, internal states from the history.

        ``skew`` [s]: the link encoder reads that late, so the link's state at a start is the one
        it reports ``skew`` later."""
        d = self._datas(model)[0]  # a rollout's scratch data: each row sets every state it reads
        mujoco.mj_resetData(model, d)
        template = np.empty(mujoco.mj_stateSize(model, FULL))
        mujoco.mj_getState(model, d, template, FULL)
        x0 = np.tile(template, (len(i0), 1))
        m = self.m
        x0[:, 0] = 0.0
        x0[:, 1 + ji.motor_qpos] = m.q[i0]
        h = model.opt.timestep
        x0[:, 1 + model.nq + ji.motor_dof] = m.step_velocity("q", h, i0)
        if ji.link_qpos >= 0:
            at = np.clip(i0 + skew * m.rate, 0, len(m.t) - 1)
            samples = np.arange(len(m.t))
            x0[:, 1 + ji.link_qpos] = np.interp(at, samples, m.theta)
            x0[:, 1 + model.nq + ji.link_dof] = m.step_velocity("theta", h, at)
        # Flexible segments of the link move with the hub at the window start.
        states = steady_states(ji.params, self._motion(i0))
        # The internal states are the model's memory of the motion, run from the recording's
        # first sample (on its steady branches) to each window start by the plugin's kernels.
        # Each stacked recording's history starts afresh at its first sample.
        firsts = np.array([a for a, _ in m.segments])
        start = steady_states(ji.params, self._motion(firsts, path=True))
        if isinstance(ji.params.friction, TwoSEP):
            # 2SEP (last reversal, pre-sliding, lag) along the measured motor angle, its noise
            # chatter removed (REVERSAL_BAND), not guessed from the velocity's sign: the step
            # velocity is the path's displacement per sample.
            fs = term_states("friction")
            # The gear torque sets load-dependent levels: measured, else the spring's on the
            # measured deflection (its stiffness then part of the key), else none (no gear side).
            spring = m.tau is None and m.delta is not None and ji.params.friction.load_gain > 0.0
            k1 = ji.block[TRANSMISSION.k1:TRANSMISSION.k1 + 1] if spring else ji.block[:0]
            torque = m.tau if m.tau is not None else (k1[0] * m.delta if spring else np.zeros(len(m.t)))

            def friction() -> np.ndarray:
                return np.concatenate([
                    friction_history(ji.block, np.diff(m.q_path[a:b], prepend=m.q_path[a]) * m.rate, torque[a:b],
                                     1.0 / m.rate, s0)[:, fs] for (a, b), s0 in zip(m.segments, start)])
            states[:, fs] = self._history((ji.block[term_slots("friction")], k1, start[:, fs]), friction)[i0]
        if ji.params.term("hysteresis") is not None and m.delta is not None:
            # Bouc-Wen x along the measured deflection (rate independent: the path fixes it); the
            # loading-branch guess can be off by the whole loop for the entire window.
            def hysteresis() -> np.ndarray:
                return np.concatenate([hysteresis_history(ji.block, m.delta_path[a:b], s0[X])
                                       for (a, b), s0 in zip(m.segments, start)])
            key = (ji.block[term_slots("hysteresis")], ji.block[TRANSMISSION.backlash:TRANSMISSION.backlash + 1],
                   start[:, X])
            states[:, X] = self._history(key, hysteresis)[i0]
        ji.plugin_states(x0)[:] = states
        return x0

    def _history(self, key: tuple[np.ndarray, ...], run) -> np.ndarray:
        """A term's states along the recording, ``run()``, memoised on ``key`` (the term's block
        slots and its states at the recording's first samples): a Jacobian's columns that move
        other parameters share one. The last HISTORY_BYTES of them are kept."""
        k = tuple(a.tobytes() for a in key)
        cache = self._histories
        if k in cache:
            cache[k] = cache.pop(k)  # the most recently used last
        else:
            cache[k] = run()
            while sum(h.nbytes for h in cache.values()) > HISTORY_BYTES and len(cache) > 1:
                del cache[next(iter(cache))]
        return cache[k]

    def _motion(self, i: np.ndarray, path: bool = False) -> dict[str, np.ndarray]:
        """The measured motion at samples ``i`` (``Term.steady``): with ``path``, the deflection
        of the noise-free path the histories run on, and the motor at rest where it moves by
        less than ``Measured.moving_speed``."""
        m, zero = self.m, np.zeros(len(i))
        delta = zero if m.delta is None else (m.delta_path if path else m.delta)[i]
        link = m.theta is not None
        w = m.qd[i]
        if path:  # a recording that starts within the noise band starts at rest, not sliding
            w = np.where(np.abs(w) > m.moving_speed, w, 0.0)
        return {"q": m.q[i], "w": w, "theta": m.theta[i] if link else zero,
                "wtheta": m.thetad[i] if link else zero, "delta": delta}

    def _start_states(self, model, ji, delay: float, windows: np.ndarray, skew: float = 0.0,
                      lead_ins: list | None = None) -> np.ndarray:
        """Full MuJoCo states at the starts of ``windows``; for 2SEP, those that start at rest or
        (on a rigid link) in the transient after a reversal or a stop (TRANSIENT) take 2SEP's
        states from a lead-in.

        At a resting start the 2SEP states hold what the measured angle does not: pre-sliding
        below one encoder count and the lag state's windup over the dwell (Eq. 14 keeps
        integrating at rest); just after a reversal, where the motor turned to within a fraction
        of a count. The model itself, simulated under the measured input from the last sample
        where the motor still moved (``lead_samples``), supplies them. Only the 2SEP
        states are taken: the window still starts from the measured motion, and Bouc-Wen's x
        follows the path anyway. The lead-ins cost up to ``design.lead`` of simulation per
        window that has one. A flexible link's lead-in (``_flexible_start``) is appended to
        ``lead_ins``, if given, to be run with other models' (it completes the returned states in
        place), else run here.
        """
        i0 = self.starts[windows]
        lead = self.lead_samples[windows] if isinstance(ji.params.friction, TwoSEP) else np.zeros(len(i0), int)
        if _hidden_coordinates(model, ji) is not None:
            # A lead-in starts with the rod straight, and it rings for FLEX_LEAD: through a
            # transient's short lead-in that ringing, not the recording, would set the states.
            lead = np.where(self.resting[windows], lead, 0)
        rows = np.flatnonzero(lead > 0)
        lead = lead[rows]
        flex = self._flexible_rows(model, ji, i0)
        flex_lead = int(round(FLEX_LEAD * self.m.rate))
        # One history run serves the window starts and both kinds of lead-in's starts.
        starts = np.concatenate([i0, i0[rows] - lead, i0[flex] - flex_lead])
        x = self._initial_states(model, starts, ji, skew)
        if model.na:
            x[:, 1 + model.nq + model.nv + model.actuator_actadr[ji.actuator]] = self._activation(model, ji, delay, starts)
        x0, first, bent = x[:len(i0)], x[len(i0):len(i0) + len(rows)], x[len(i0) + len(rows):]
        if flex.size:
            job = _FlexLead(model, ji, delay, i0[flex] - flex_lead, bent, x0, flex)
            if lead_ins is None:
                self._flexible_start([job])
            else:
                lead_ins.append(job)
        if rows.size == 0:
            return x0
        sub = self._substeps(model)
        n = int(lead.max()) + 1
        ctrl = self._controls(model, i0[rows] - lead, n, delay, ji)
        end = np.empty_like(first)
        for a, b, state in self._rollouts([model] * len(rows), first, ctrl):
            end[a:b] = state[np.arange(b - a), lead[a:b] * sub - 1]  # each at its own window's start
        st, _ = ji.settled(model, end)
        fs = term_states("friction")
        ji.plugin_states(x0)[rows, fs] = st[:, fs]
        self.rollouts += len(rows) * (n - 1) / (len(self.starts) * (self.nwin_samples - 1))
        return x0

    def _activation(self, model, ji, delay: float, i0: np.ndarray) -> np.ndarray:
        """The input lag's state (the actuator's activation) at samples ``i0``: the model's own
        activation step (``assets.builder.set_input``) run over the recording's delayed held
        input from each stacked recording's first sample, where it starts settled on that input."""
        h = model.opt.timestep
        decay = math.exp(-h / model.actuator_dynprm[ji.actuator, 0])
        sub = self._substeps(model)

        def run() -> np.ndarray:
            parts = []
            for a, b in self.m.segments:
                c = self._controls(model, np.array([a]), b - a, delay, ji)[0, :, ji.actuator]
                after = lfilter([1.0 - decay], [1.0, -decay], c, zi=[decay * c[0]])[0]  # after each step
                parts.append(np.concatenate([c[:1], after[sub - 1::sub]]))
            return np.concatenate(parts)
        return self._history((np.array([decay, delay, sub]),), run)[i0]

    def _flexible_rows(self, model, ji, i0: np.ndarray) -> np.ndarray:
        """Which window starts ``i0`` get a flexible link's lead-in (``_flexible_start``): all, on
        a link with segments, but those closer than FLEX_LEAD to their recording's start."""
        lead = int(round(FLEX_LEAD * self.m.rate))
        if lead == 0 or _hidden_coordinates(model, ji) is None:
            return np.zeros(0, int)
        return np.flatnonzero(i0 - lead >= _segment_first(i0, self.m.joins))

    def _flexible_start(self, jobs: list["_FlexLead"]) -> None:
        """Runs each job's states ``x`` at samples ``at`` over FLEX_LEAD (in place) and takes its
        segments' angles and rates into its window starts: the model's rod driven by the measured
        hub, so that its segments at the window starts are bent as the hub bent them. All jobs
        (the models of one batch) step together, one rollout call per sample, not one per model
        and sample: each call costs more than the step of its rows.

        The encoders see the hub only; the rod's bending and vibration are states no sample
        gives. A straight rod at each start sets off a vibration the recording does not hold
        (the right model of the shipped 4-segment arm then misses a 10 s multisine by NRMSE
        0.56 in delta, 0.08 with this lead-in). A free lead-in does not do: its hub drifts from
        the measured one, and the bending follows the hub. So the lead-in runs one sample at a
        time with the encoders' joints put back on the record, and only the segments' relative
        angles and rates are taken (``_start_states``).
        """
        if not jobs:
            return
        m = self.m
        lead = int(round(FLEX_LEAD * m.rate))
        seen = []  # per job: (state column, its measured values (lead, starts)) of the encoders' joints
        for job in jobs:
            model, ji = job.model, job.ji
            h = model.opt.timestep
            at = job.at[None, :] + np.arange(lead)[:, None]
            cols = [(1 + ji.motor_qpos, m.q[at]), (1 + model.nq + ji.motor_dof, m.step_velocity("q", h, at))]
            if ji.link_qpos >= 0:
                cols += [(1 + ji.link_qpos, m.theta[at]), (1 + model.nq + ji.link_dof, m.step_velocity("theta", h, at))]
            seen.append(cols)
        models = [job.model for job in jobs for _ in job.at]
        ends = np.cumsum([len(job.at) for job in jobs])
        x = np.concatenate([job.x for job in jobs])
        parts = np.split(x, ends[:-1])  # views: each job's rows of x
        # every sample's controls at once, (lead, rows, steps, nu): one call, not one per sample
        ctrl = np.concatenate([self._controls(job.model, (job.at[None, :] + np.arange(lead)[:, None]).ravel(), 2,
                                              job.delay, job.ji).reshape(lead, len(job.at), -1, job.model.nu)
                               for job in jobs], axis=1)
        for k in range(lead):  # one sample at a time, the encoders' joints put back on the record
            for part, job, cols in zip(parts, jobs, seen):
                for col, meas in cols:
                    part[:, col] = meas[k]
            for a, b, state in self._rollouts(models, x, ctrl[k]):
                x[a:b] = state[:, -1]
        for part, job in zip(parts, jobs):
            job.x[:] = part
            qadr, vadr = _hidden_coordinates(job.model, job.ji)
            nq = job.model.nq
            job.x0[job.rows[:, None], 1 + qadr[None, :]] = part[:, 1 + qadr]
            job.x0[job.rows[:, None], 1 + nq + vadr[None, :]] = part[:, 1 + nq + vadr]
        self.rollouts += int(ends[-1]) * lead / (len(self.starts) * (self.nwin_samples - 1))

    @cached_property
    def lead_samples(self) -> np.ndarray:
        """Lead-in of each window [samples] (``_start_states``): for a window that starts at rest,
        back to the last sample where the motor moved faster than ``Measured.moving_speed``; for
        one that starts moving within its warmup of a slow sample, back past it (TRANSIENT); at
        most ``design.lead`` and never across a join; 0 for every other window."""
        return self._lead_samples(1.0)

    @cached_property
    def resting(self) -> np.ndarray:
        """Whether each window starts at rest (slower than ``Measured.moving_speed``)."""
        m = self.m
        return np.abs(m.qd[self.starts]) <= m.moving_speed

    def _lead_samples(self, factor: float) -> np.ndarray:
        """``lead_samples`` with the resting windows' lead-ins from the last sample faster than
        ``factor`` x moving_speed (the windows in a transient keep theirs)."""
        m = self.m
        cap = int(round(self.design.lead * m.rate))
        resting = lead_samples(m.qd, m.moving_speed, self.starts, m.joins, cap)
        if factor != 1.0:
            far = lead_samples(m.qd, factor * m.moving_speed, self.starts, m.joins, cap)
            resting = np.where(resting > 0, np.maximum(resting, far), 0)
        return np.where(self.resting, resting, self._transient_lead)

    @cached_property
    def _transient_lead(self) -> np.ndarray:
        """The lead-ins of the windows that start in a transient (TRANSIENT), whatever the factor."""
        m = self.m
        cap = int(round(self.design.lead * m.rate))
        within = int(round(self.design.warmup * m.rate))
        return transient_lead(m.qd, TRANSIENT * m.moving_speed, self.starts, m.joins, cap, within)

    def with_lead(self, factor: float) -> "Predictor":
        """This predictor (the same windows, scratch data and rollout count) with the resting
        windows' lead-ins started at the last sample faster than ``factor`` x moving_speed."""
        shifted = copy.copy(self)
        shifted.__dict__["lead_samples"] = self._lead_samples(factor)
        return shifted

    def refolded(self, fold: int) -> "Predictor":
        """This predictor (the same windows, scratch data and rollout count) with another share of
        its windows held out (``held_out``): the ``fold``-th of k-fold cross-validation, fold 0
        its own split. A fit on it sees none of that fold's held-out windows. Its score counts
        every one of them until some are left out of it (``leave_out``): those left out of this
        one's lie in this one's fold."""
        other = copy.copy(self)
        other.holdout = held_out(self.design, len(self.starts), fold)
        return other

    def lead_in_spread(self, structure: Structure, windows: np.ndarray, factors=LEAD_FACTORS) -> np.ndarray:
        """Per window, the largest mean squared difference between the structure's predictions
        from lead-ins started at each of ``factors`` (``with_lead``), in noise floors."""
        preds = []
        for factor in factors:
            shifted = self.with_lead(factor)
            preds.append(shifted.predict([structure], windows)[0])
            self.rollouts = shifted.rollouts
        spread = np.zeros(len(windows))
        for a in range(len(preds)):
            for b in range(a + 1, len(preds)):
                d = np.nan_to_num(self.residuals(preds[a], windows) - self.residuals(preds[b], windows), nan=1e3)
                spread = np.maximum(spread, self.window_mean_squares(d, len(windows)))
        return spread / self.noise_floor

    def undetermined(self, structure: Structure, windows: np.ndarray) -> np.ndarray:
        """Those of ``windows`` whose start state the recording leaves open for ``structure``:
        resting windows whose ``lead_in_spread`` exceeds UNDETERMINED. Empty, and no rollout,
        for a structure without lead-in states (no 2SEP), an unstable one, or no resting window."""
        windows = np.asarray(windows)
        rest = windows[self.resting[windows] & (self.lead_samples[windows] > 0)]
        if rest.size == 0 or not isinstance(structure.model_params()[1].friction, TwoSEP) \
                or not self.stable(structure):
            return rest[:0]
        return rest[self.lead_in_spread(structure, rest) > UNDETERMINED]

    def leave_out(self, windows: np.ndarray) -> None:
        """Leaves held-out ``windows`` out of ``test`` for every model scored afterwards."""
        self.left_out = self.left_out | np.isin(np.arange(len(self.starts)), windows)

    @cached_property
    def _held_input(self) -> tuple[np.ndarray, np.ndarray]:
        """(knots, integral of the zero-order-held input at them) (``_controls``): computed once,
        not per call (a flexible lead-in makes one call per sample)."""
        m = self.m
        period = 1.0 / m.rate
        cum = np.concatenate([[0.0], np.cumsum(m.u) * period])
        return m.t[0] + period * np.arange(len(cum)), cum

    def _controls(self, model, i0: np.ndarray, n: int, delay: float, ji) -> np.ndarray:
        """Per-step controls of ``n``-sample runs from samples ``i0``: at each step the
        zero-order-held input averaged over [t - h/2, t + h/2], the half steps a step's impulse
        stands for (``sim.held_controls``), read ``delay`` late as MuJoCo's native actuator delay
        reads them (``assets.builder.set_input``): the history of the steps' controls, linearly
        interpolated between the steps at t - d. The model the windows predict is then the MJCF a
        simulation runs, whatever d is against the step; d stays continuous, so it is fitted by
        gradients. Before its recording's first sample (the start of the record or a join) the
        input is zero.
        """
        sub = self._substeps(model)
        h = model.opt.timestep
        m = self.m
        knots, cum = self._held_input
        # A delayed window at a join would otherwise take the previous recording's input.
        begin = m.t[_segment_first(i0, m.joins)][:, None]

        def held(lo):  # the control of the step whose half steps start at lo
            return (np.interp(np.maximum(lo + h, begin), knots, cum) - np.interp(np.maximum(lo, begin), knots, cum)) / h
        lo = m.t[i0][:, None] + h * np.arange((n - 1) * sub)[None, :] - delay - 0.5 * h
        if delay > 0:
            step = m.t[0] - 0.5 * h + h * np.floor((lo - m.t[0] + 0.5 * h) / h)  # the steps lie on the samples' grid
            f = (lo - step) / h
            u = (1.0 - f) * held(step) + f * held(step + h)
        else:
            u = held(lo)
        ctrl = np.zeros((len(i0), (n - 1) * sub, model.nu))
        ctrl[:, :, ji.actuator] = u / ji.k_m
        return ctrl

    # ---- cost --------------------------------------------------------------------------
    def residuals(self, pred: dict[str, np.ndarray], windows: np.ndarray) -> np.ndarray:
        parts = []
        for s in self.signals:
            e = (pred[s][:, self.cols] - self.meas[s][windows][:, self.cols]) / self.scale[s]
            parts.append(e.ravel())
        return np.concatenate(parts)

    def window_mean_squares(self, r: np.ndarray, nwindows: int) -> np.ndarray:
        """Mean square of a ``residuals()`` vector (or of each column of a matrix of them) per
        window: shape (nwindows,) or (nwindows, columns)."""
        return np.mean(self.window_blocks(r, nwindows) ** 2, axis=(0, 2))

    def window_blocks(self, r: np.ndarray, nwindows: int) -> np.ndarray:
        """A ``residuals()`` vector or matrix as (signals, windows, samples[, columns]) (a view)."""
        r = np.asarray(r)
        return r.reshape(len(self.signals), nwindows, len(self.cols), *r.shape[1:])

    def nrmse(self, pred: dict[str, np.ndarray], windows: np.ndarray) -> dict[str, float]:
        """Prediction NRMSE per signal: rms error over the signal's spread within windows."""
        out = {}
        for s in ("q", "theta", "delta", "tau"):
            if self.meas.get(s) is None:
                continue
            err = pred[s][:, self.cols] - self.meas[s][windows][:, self.cols]
            out[s] = float(np.sqrt(np.mean(err ** 2)) / self.spread(s, windows))
        return out

    @cached_property
    def noise_floor(self) -> float:
        """The cost measurement noise alone gives: the mean over the scored signals of
        (noise std / normalisation)^2 (``noise_std``)."""
        full = {"q": self.m.q, "delta": self.m.delta, "tau": self.m.tau}
        return float(np.mean([(noise_std(full[s], self.m.rate) / self.scale[s]) ** 2 for s in self.signals]))

    def spread(self, signal: str, windows: np.ndarray) -> float:
        """The rms of a measured signal about each window's mean, over the cost samples of
        ``windows``: what ``nrmse`` divides by."""
        w = self.meas[signal][windows]
        dev = w[:, self.cols] - w.mean(axis=1, keepdims=True)
        return max(float(np.sqrt(np.mean(dev ** 2))), 1e-300)

    @property
    def train(self) -> np.ndarray:
        return np.flatnonzero(~self.holdout)

    @property
    def scored_holdout(self) -> np.ndarray:
        """Per window, whether it is held out and scored: ``holdout`` less ``left_out``."""
        return self.holdout & ~self.left_out

    @property
    def test(self) -> np.ndarray:
        return np.flatnonzero(self.scored_holdout)


def held_out(design: WindowDesign, n: int, fold: int = 0) -> np.ndarray:
    """Which of ``n`` windows are held out: the ``fold``-th share (``design.holdout``, at least
    two windows) of a permutation drawn from ``design.seed``, so the folds are disjoint and fold
    0 is a fit's own split."""
    order = np.random.default_rng(design.seed).permutation(n)
    k = max(2, int(round(design.holdout * n)))
    if not 0 <= fold < n // k:
        raise ValueError(f"fold={fold} must lie in [0, {n // k - 1}] for {n} windows with {k} held out each")
    mask = np.zeros(n, bool)
    mask[order[fold * k: (fold + 1) * k]] = True
    return mask


def _glibc_trim():
    try:
        return ctypes.CDLL("libc.so.6").malloc_trim
    except (OSError, AttributeError):  # not glibc: its allocator keeps no such pages, or they stay
        return None


_MALLOC_TRIM = _glibc_trim()


_UNTRIMMED = [0]  # bytes freed since the last trim (``release_freed``)
# Each trim walks the heap (~0.2 ms), as long as a small batch's rollout: trimmed once this
# much has been freed, the resident memory stays within it of what the arrays hold at once.
TRIM_BYTES = 32 * 2 ** 20


def release_freed(freed: int | None = None) -> None:
    """Hands the heap pages of freed arrays back to the system (glibc's ``malloc_trim``): at
    once, or with ``freed`` (bytes just freed) once TRIM_BYTES have been freed since the last.

    Once glibc has freed a mapped block of a few MB it raises its mapping threshold to that size
    (up to 32 MB), and later arrays of that size come from the heap; freed, their pages stay
    resident. A batch of windows makes many such arrays per rollout chunk, so without this the
    resident memory of a long recording's fit grows by what its chunks ever held, not by what
    they hold at once (a 120 s recording's base fit kept ~75 MB more). A no-op elsewhere."""
    if freed is not None:
        _UNTRIMMED[0] += freed
        if _UNTRIMMED[0] < TRIM_BYTES:
            return
    _UNTRIMMED[0] = 0
    if _MALLOC_TRIM is not None:
        _MALLOC_TRIM(0)


def _joined(parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """One model's predictions from those of its chunks of windows, in order."""
    return parts[0] if len(parts) == 1 else {s: np.concatenate([p[s] for p in parts]) for s in parts[0]}


@dataclass
class _FlexLead:
    """One model's flexible lead-in (``Predictor._flexible_start``): the states ``x`` at samples
    ``at``, run over FLEX_LEAD, give the hidden coordinates of the window starts ``x0[rows]``."""

    model: object
    ji: object
    delay: float
    at: np.ndarray
    x: np.ndarray
    x0: np.ndarray
    rows: np.ndarray


def _segment_first(samples: np.ndarray, joins) -> np.ndarray:
    """The first sample of the stacked recording each of ``samples`` lies in (joins: the others' firsts)."""
    bounds = np.array([0, *joins])
    return bounds[np.searchsorted(bounds, samples, side="right") - 1]


def _last_index(mask: np.ndarray) -> np.ndarray:
    """Per sample, the last sample at or before it where ``mask`` holds; -1 where none does."""
    return np.maximum.accumulate(np.where(mask, np.arange(len(mask)), -1))


def lead_samples(qd: np.ndarray, moving_speed: float, starts: np.ndarray, joins, cap: int) -> np.ndarray:
    """Samples from the last one where |qd| exceeded ``moving_speed`` to each start, at most
    ``cap`` and not across a join; 0 for a start where the motor moves (or ``cap`` is 0)."""
    starts = np.asarray(starts)
    if cap <= 0:
        return np.zeros(len(starts), int)
    moving = np.abs(qd) > moving_speed
    last = _last_index(moving)
    floor = np.maximum(_segment_first(starts, joins), starts - cap)
    prev = np.where(starts > 0, last[np.maximum(starts - 1, 0)], -1)
    return np.where(moving[starts], 0, starts - np.maximum(prev, floor))


def transient_lead(qd: np.ndarray, speed: float, starts: np.ndarray, joins, cap: int, within: int) -> np.ndarray:
    """Samples of lead-in for each start that comes at most ``within`` samples after one where
    |qd| was at most ``speed``: back to the last sample faster than ``speed`` before that one, at
    most ``cap`` and not across a join; 0 for every other start."""
    starts = np.asarray(starts)
    last = _last_index(np.abs(qd) <= speed)[starts]
    near = (last >= _segment_first(starts, joins)) & (starts - last <= within)
    back = lead_samples(qd, speed, np.where(near, last, starts), joins, cap)
    return np.where(near & (back > 0), np.minimum(starts - last + back, cap), 0)


def _hidden_coordinates(model, ji) -> tuple[np.ndarray, np.ndarray] | None:
    """(qpos, dof) addresses of the joints no encoder sees (a flexible link's segments), or None."""
    seen_q = {ji.motor_qpos, ji.link_qpos}
    seen_v = {ji.motor_dof, ji.link_dof}
    qadr = [a for a in range(model.nq) if a not in seen_q]
    vadr = [a for a in range(model.nv) if a not in seen_v]
    if not vadr or len(qadr) != len(vadr):  # hinge and slide segments only: one qpos per dof
        return None
    return np.array(qadr), np.array(vadr)


def stable(structure) -> bool:
    """Whether a structure's model is stable at its step (``assets.stability``)."""
    return _stable(_compile(*structure.model_params()))


def _stable(model) -> bool:
    """Stability of a compiled (memoised) model, computed once per model."""
    key = id(model)
    if key not in _STABLE:
        try:
            check_model_stability(model)
            _STABLE[key] = True
        except ValueError:
            _STABLE[key] = False
    return _STABLE[key]


_STABLE: dict[int, bool] = {}


_MODEL_CACHE: dict = {}


def _compile(arm, joint):
    """Compile (memoised on the exact parameters: FD columns repeat across iterations)."""
    from dataclasses import replace

    from ..assets.plant import build_plant
    key = (replace(arm, input_delay=0.0), joint)
    model = _MODEL_CACHE.get(key)
    if model is None:
        if len(_MODEL_CACHE) > 256:
            _MODEL_CACHE.clear()
            _STABLE.clear()
        spec = build_plant(key[0], joint)
        model = for_prediction(spec.compile())  # not load_model: unstable candidates are scored, not rejected
        register_model(model)
        _MODEL_CACHE[key] = model
    return model


def _signature(model) -> tuple:
    return (model.nq, model.nv, model.nu, model.na, model.nhistory, model.npluginstate, model.nsensordata)


def _cores() -> int:
    import os
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
