"""``mjjoint.diagnose``: name the physics a model lacks for a recording, as ``mjjoint diagnose`` does."""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from ..diagnosis.loop import DiagnoseOptions, Diagnosis
from ..diagnosis.loop import diagnose as diagnose_problem
from ..recordings import MultiRecording, Recording
from .problem import answer, joint_problems


def diagnose(recording: Recording | MultiRecording | str | Path, *, options: DiagnoseOptions | None = None,
             progress: Callable[[str], None] | None = None, **inputs) -> Diagnosis | dict[int, Diagnosis]:
    """Fit the starting model, locate where it misses, name the missing effect, add it, refit; repeat.

    The same loop as ``mjjoint diagnose`` (same result for the same inputs), without writing
    the report.

    Args:
        recording: a ``Recording`` (arrays t, u, q, theta[, tau], each of shape (n,), SI units),
            a ``MultiRecording`` of several joints (each diagnosed on its own), or the path of a
            .csv/.npz/.mat recording.
        options: the loop's budget and acceptance rule (``DiagnoseOptions``: ``min_gain``,
            ``max_rounds``, ``candidates``, ``fit_iter``, ``screen_iter``, ...); default
            ``DiagnoseOptions()``, as the command line's defaults.
        progress: called with one line of text per step.
        **inputs: the fields of ``mjjoint.problem.Inputs``, as for ``mjjoint.fit``: ``gear_ratio``,
            ``base`` or ``model``, ``k_m``, ``plant``, ``joints``, ``arm``, ``design``, and for a path
            ``columns``, ``scales``, ``allow_gaps``.

    Returns:
        The ``Diagnosis``: ``missing`` (effect names in the order found), ``steps`` (each with
        its evidence), the ``initial`` and ``final`` ``FitResult``, the ``verdict`` line and the
        budget; for a multi-joint recording, a dict of them by joint number.

    Raises:
        ValueError: an input out of range, an unknown effect, a recording that cannot be read or
            does not fit the inputs, or too few held-out windows to name an effect.
        TypeError: a keyword that is not an input, or ``options`` not a ``DiagnoseOptions``.
    """
    options = DiagnoseOptions() if options is None else options
    if not isinstance(options, DiagnoseOptions):
        raise TypeError(f"options must be a DiagnoseOptions, not {type(options).__name__}")
    return answer({j: diagnose_problem(p.predictor, p.base, options, progress=progress)
                   for j, p in joint_problems(recording, inputs).items()})
