"""``mjjoint.fit``: fit a model structure's parameters to a recording, as ``mjjoint fit`` does."""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from ..identify.fit import FitResult, reported
from ..identify.fit import fit as fit_structure
from ..recordings import MultiRecording, Recording
from .problem import answer, joint_problems


def fit(recording: Recording | MultiRecording | str | Path, *, max_iter: int = 25, restarts: int = 2,
        progress: Callable[[int, float], None] | None = None, **inputs) -> FitResult | dict[int, FitResult]:
    """Fit the parameters of a starting structure to a recording by windowed prediction error.

    The same fit as ``mjjoint fit`` (same windows, same held-out set for the same ``design``
    seed), without writing any file.

    Args:
        recording: a ``Recording`` (arrays t, u, q, theta[, tau], each of shape (n,), SI units),
            a ``MultiRecording`` of several joints, or the path of a .csv/.npz/.mat recording.
        max_iter: Levenberg-Marquardt iterations of each phase, at least 1.
        restarts: further starting points tried when the fit ends on a bound or far above the
            noise floor (the recording's initial values, then seeded random ones), at least 0;
            above 0 the fit is also run staged (``identify.fit.fit``), the better kept.
        progress: called as ``progress(iteration, cost)`` after each LM iteration.
        **inputs: the fields of ``mjjoint.problem.Inputs``: ``gear_ratio`` (required unless
            ``model`` gives it; a tuple gives one per joint), ``base`` (effect names, ``()`` for
            the minimal model; default the seed paper's full joint) or ``model`` (a model file or
            its path), ``k_m`` (u recorded as a current [A]), ``plant`` ("arm", "linear",
            "rotary"), ``joints`` (joint numbers of a multi-joint recording, from 1), ``arm`` (the
            whole arm's model: the other joints' measured motion loads each joint), ``design``
            (``WindowDesign``: window length, held-out seed, lead-in), and for a path
            ``columns``, ``scales``, ``allow_gaps`` (as ``read_recording`` takes them).

    Returns:
        The ``FitResult`` (fitted ``structure``, 95 % ``intervals`` by parameter name, each
        widened by its estimate's step bias (``identify.fit.reported``),
        ``warnings``, held-out ``nrmse_test`` by signal, budget); for a multi-joint recording,
        a dict of them by joint number.

    Raises:
        ValueError: an input out of range, an unknown effect, or a recording that cannot be read
            or does not fit the inputs (one line naming the input).
        TypeError: a keyword that is not an input.
    """
    if isinstance(max_iter, bool) or not isinstance(max_iter, int) or max_iter < 1:
        raise ValueError(f"max_iter={max_iter!r} must be an integer of at least 1")
    if isinstance(restarts, bool) or not isinstance(restarts, int) or restarts < 0:
        raise ValueError(f"restarts={restarts!r} must be an integer of at least 0")
    return answer({j: reported(p.predictor, fit_structure(p.predictor, p.base, max_iter=max_iter, progress=progress,
                                                          restarts=restarts))
                   for j, p in joint_problems(recording, inputs).items()})
