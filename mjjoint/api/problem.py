"""The problems of an API call: ``problem.load_problem`` on the keyword inputs, its notes as warnings."""
from __future__ import annotations

import warnings
from pathlib import Path

from ..problem import Inputs, Problem, load_problem
from ..recordings import MultiRecording, Recording


def joint_problems(recording: Recording | MultiRecording | str | Path, inputs: dict) -> dict[int | None, Problem]:
    """``load_problem`` with ``inputs`` as the fields of ``problem.Inputs``, by joint number
    (the key ``None`` alone for a single-joint recording).

    ``base`` may be any sequence of effect names. What a model file could not hold, and how a
    recording was resampled, are issued as ``UserWarning`` s (the command line prints them as notes).
    """
    if inputs.get("base") is not None:
        inputs = {**inputs, "base": tuple(inputs["base"])}
    problem = load_problem(recording, Inputs(**inputs))
    for note in problem.notes:
        warnings.warn(note, stacklevel=3)
    return {None: problem} if isinstance(problem, Problem) else dict(problem.problems)


def answer(results: dict):
    """The one result of a single-joint recording, else the results by joint number."""
    return results[None] if None in results else results
