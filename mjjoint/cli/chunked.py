"""Long rollouts in chunks, each continuing from the last state, so progress can be shown.

Exact by construction: a chunk rolls out one sample more than it keeps; the state at that
extra instant is reached before its input acts, so it is the next chunk's initial state and
the stitched states equal one unchunked rollout bit for bit.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
from tqdm import tqdm

from ..coupling.mjlog import mujoco_log_silenced
from ..sim import Simulator, Trace

CHUNK_SAMPLES = 10_000  # ~0.1 s of wall time per chunk on the default arm


def rollout_chunked(sim: Simulator, u: np.ndarray, chunk: int = CHUNK_SAMPLES,
                    progress: Callable[[int], object] | None = None) -> np.ndarray:
    """``sim.rollout_states(u)`` computed ``chunk`` samples at a time; reports each chunk's size."""
    if chunk < 1:
        raise ValueError(f"chunk={chunk} is outside the allowed range [1, inf)")
    n = len(u)
    x = sim.initial_state()
    parts = []
    for k0 in range(0, n, chunk):
        k1 = min(k0 + chunk, n)
        # past the end the slice just stops at n
        states = sim.rollout_states(u[k0:k1 + 1], x, u[k0 - 1] if k0 else 0.0)
        if k1 < n:
            x, states = states[-1], states[:-1]
        parts.append(states)
        if progress is not None:
            progress(k1 - k0)
    return np.vstack(parts)


def simulate_chunked(sim: Simulator, u: np.ndarray, chunk: int = CHUNK_SAMPLES,
                     show_progress: bool | None = None) -> list[Trace]:
    """One Trace per joint for inputs ``u``, with a progress bar when there is more than one chunk.

    ``show_progress=None`` shows it only on a terminal.
    """
    disable = True if len(u) <= chunk else (None if show_progress is None else not show_progress)
    with mujoco_log_silenced(), tqdm(total=len(u), unit="sample", desc="simulate", disable=disable,
                                     leave=False) as bar:
        states = rollout_chunked(sim, u, chunk, bar.update)
    return sim.traces(states, u)
