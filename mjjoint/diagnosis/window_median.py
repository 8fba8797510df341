"""Medians of many contiguous windows of one array, as ``np.median`` gives them, without sorting
each window anew.

The resonance score's background is the median spectral level on the flanks of every band: one
window per frequency bin, each up to a third of the spectrum long. Sorted window by window, a
10-minute record's spectrum (65 537 bins) costs minutes per batch of residuals. Here each sample
enters and leaves a tree of counts over the column's ranks as the window's ends pass it, and a
window's middle ranks are found by descending the tree: O(n log n) when consecutive windows
overlap, as the flanks of neighbouring bins do.
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _kth(tree: np.ndarray, top: int, k: int) -> int:
    """0-based rank of the k-th smallest (1-based k) counted element."""
    pos = 0
    while top:
        nxt = pos + top
        if nxt < tree.size and tree[nxt] < k:
            pos = nxt
            k -= tree[nxt]
        top >>= 1
    return pos


@njit(cache=True)
def _count(tree: np.ndarray, rank: int, by: int) -> None:
    i = rank + 1
    while i < tree.size:
        tree[i] += by
        i += i & -i


@njit(cache=True)
def _medians(rank: np.ndarray, ordered: np.ndarray, starts: np.ndarray, stops: np.ndarray,
             out: np.ndarray) -> None:
    """out[i] = median of the values ranked rank[starts[i]:stops[i]]; ordered[r] is the value of
    rank r. The window grows before it shrinks, so no count goes below zero."""
    tree = np.zeros(rank.size + 1, np.int64)
    top = 1
    while top * 2 <= rank.size:
        top *= 2
    lo = hi = 0
    for i in range(starts.size):
        a, b = starts[i], stops[i]
        while hi < b:
            _count(tree, rank[hi], 1)
            hi += 1
        while lo > a:
            lo -= 1
            _count(tree, rank[lo], 1)
        while hi > b:
            hi -= 1
            _count(tree, rank[hi], -1)
        while lo < a:
            _count(tree, rank[lo], -1)
            lo += 1
        m = b - a
        if m % 2:
            out[i] = ordered[_kth(tree, top, (m + 1) // 2)]
        else:
            out[i] = (ordered[_kth(tree, top, m // 2)] + ordered[_kth(tree, top, m // 2 + 1)]) / 2.0


def window_medians(x: np.ndarray, starts: np.ndarray, stops: np.ndarray) -> np.ndarray:
    """``np.median(x[a:b], axis=0)`` for every (a, b) of ``zip(starts, stops)``, stacked: shape
    ``(len(starts),) + x.shape[1:]``. Windows must be non-empty and inside x; a window holding a
    NaN has median NaN."""
    x = np.asarray(x, dtype=float)
    starts = np.asarray(starts, dtype=np.int64)
    stops = np.asarray(stops, dtype=np.int64)
    if starts.shape != stops.shape or starts.ndim != 1:
        raise ValueError(f"starts {starts.shape} and stops {stops.shape} must be 1-d of one length")
    if starts.size and not (starts.min() >= 0 and stops.max() <= len(x) and np.all(stops > starts)):
        raise ValueError(f"every window [a, b) must satisfy 0 <= a < b <= {len(x)}")
    columns = x.reshape(len(x), -1)
    out = np.empty((columns.shape[1], starts.size))
    for j, col in enumerate(columns.T):
        order = np.argsort(col, kind="stable")  # NaN last: never among a NaN-free window's ranks
        rank = np.empty(col.size, np.int64)
        rank[order] = np.arange(col.size)
        _medians(rank, col[order], starts, stops, out[j])
        nans = np.concatenate([[0], np.cumsum(np.isnan(col))])
        out[j, nans[stops] > nans[starts]] = np.nan
    return out.T.reshape((starts.size,) + x.shape[1:])
