"""The held-out windows whose start the recording leaves open, left out of every score.

A window that starts at rest takes 2SEP's states from a free lead-in through the stop before it,
and for a breakaway after a dwell no lead-in start is right (``Predictor.undetermined``). A fit
leaves such training windows out for its own model; a held-out one still scored would charge
every model with 2SEP for a start the recording cannot give, and may hold most of the truth's
own held-out cost: the lag would then lose to the model without it on that window alone. The
set is decided once per recording, from the base with 2SEP at its catalogue values, before the
base fit, so every model the diagnosis compares is scored on the same windows and the paired
tests stay paired.
"""
from __future__ import annotations

import numpy as np

from ..identify.effects import EFFECTS, incompatible, plant_effects
from ..identify.structure import Structure
from ..identify.windows import Predictor

LAG = "dynamic_friction"


def with_lag(base: Structure) -> Structure | None:
    """``base`` with 2SEP (and what it requires) at their catalogue values; None where the plant
    or the base's effects admit none."""
    if LAG in base.effects:
        return base
    added = [e for e in (*EFFECTS[LAG].requires, LAG) if e not in base.effects]
    if LAG not in plant_effects(base.nominal) or any(incompatible(a, b) for a in added for b in base.effects):
        return None
    for effect in added:
        base = base.with_effect(effect)
    return base


def leave_out_open_starts(predictor: Predictor, base: Structure, keep: int, say) -> list[float]:
    """Leaves the held-out windows the base with 2SEP leaves open (``Predictor.undetermined``)
    out of ``predictor.test`` (``Predictor.leave_out``), unless fewer than ``keep`` would remain:
    a short recording is then scored on all of them, as the rank test needs. Says which, and
    returns their starts [s]. Decided over every held-out window, so a second call on the same
    predictor finds the same ones."""
    lagged = with_lag(base)
    if lagged is None:
        return []
    held = np.flatnonzero(predictor.holdout)
    windows = predictor.undetermined(lagged, held)
    starts = [round(float(predictor.m.t[predictor.starts[w]]), 4) for w in windows]
    if not starts:
        return []
    if len(held) - len(windows) < keep:
        say(f"{_windows_at(starts)} start at rest where the recording leaves the state open; kept in the score, "
            f"since leaving them out would leave fewer than {keep} held-out windows")
        return []
    predictor.leave_out(windows)
    say(left_out_line(starts))
    return starts


def left_out_line(starts) -> str:
    """What the user reads of the windows left out, at their ``starts`` [s]."""
    return f"{_windows_at(starts)} left out of every score: the recording leaves their start at rest open"


def _windows_at(starts) -> str:
    return f"held-out windows at {', '.join(f'{t:g}' for t in starts)} s"
