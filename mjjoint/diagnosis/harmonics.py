"""How much of each residual column a harmonic of an angle explains, for a scan of many k.

The periodic conditions score, for k = start + j step, the share of a residual's variance that
the centred pair [sin(k angle), cos(k angle)] (times a per-sample sign, for a friction level)
explains. Taken one k at a time, each k is a dozen passes over the record and a product with
every residual column, memory-bound: a 10-minute record's scan of thousands of real periods
took minutes. Here one pass over the samples per block of BLOCK harmonics gathers the sums a
pair's projection needs (the pair's sums, its Gram matrix, its products with every column), the
harmonics stepped by angle addition in registers, and the scores follow from those sums in
closed form. Where a pair is nearly degenerate (an angle that barely moves: its centred cosine
is a sliver of its mean, or the pair nearly one direction) the sums lose those digits to
cancellation, and that k is projected directly instead.
"""
from __future__ import annotations

import numpy as np
from numba import njit

CHUNK = 4096           # samples taken at a time (their harmonics stay in the cache)
BLOCK = 32             # harmonics of a chunk projected on the residual columns at once (one product)
# A pair whose centred part, or whose second direction, is under this share of the squared norm
# it comes from is projected directly: below it the sums' cancellation costs more than 1e-10.
CANCELLATION = 1e-6
DEGENERATE = 1e-18     # a second direction under 1e-9 of the first's norm is dropped, as an SVD basis's


@njit(cache=True, error_model="numpy", fastmath=True)
def harmonic_sums(angle: np.ndarray, weight: np.ndarray, start: float, step: float, count: int,
                  R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For a = weight sin(k angle), b = weight cos(k angle), k = start + j step: ``pair[:, j]`` =
    (sum a, sum b, a.a, b.b, a.b) and ``proj[2 j]``, ``proj[2 j + 1]`` = a.R, b.R (a row each)."""
    n, m = R.shape
    pair = np.zeros((5, count))
    proj = np.zeros((2 * count, m))
    for i0 in range(0, n, CHUNK):
        x, w = angle[i0:i0 + CHUNK], weight[i0:i0 + CHUNK]
        length = x.size
        s, c = np.sin(start * x), np.cos(start * x)
        s_step, c_step = np.sin(step * x), np.cos(step * x)
        rows = np.ascontiguousarray(R[i0:i0 + length])
        for j0 in range(0, count, BLOCK):
            jn = min(BLOCK, count - j0)
            basis = np.empty((2 * jn, length))
            for jj in range(jn):
                sum_a = sum_b = sum_aa = sum_bb = sum_ab = 0.0
                for i in range(length):
                    a, b = w[i] * s[i], w[i] * c[i]
                    basis[2 * jj, i], basis[2 * jj + 1, i] = a, b
                    sum_a += a
                    sum_b += b
                    sum_aa += a * a
                    sum_bb += b * b
                    sum_ab += a * b
                    s[i], c[i] = s[i] * c_step[i] + c[i] * s_step[i], c[i] * c_step[i] - s[i] * s_step[i]
                j = j0 + jj
                pair[0, j] += sum_a
                pair[1, j] += sum_b
                pair[2, j] += sum_aa
                pair[3, j] += sum_bb
                pair[4, j] += sum_ab
            proj[2 * j0:2 * (j0 + jn)] += basis @ rows
    return pair, proj


def _direct(a: np.ndarray, b: np.ndarray, R: np.ndarray, energy: np.ndarray) -> np.ndarray:
    """The share of each column of R the centred pair (a, b) explains, by Gram-Schmidt on the
    vectors themselves (twice: enough for an orthogonal pair in floating point), from the longer
    one; a direction under 1e-9 of the longer's norm is dropped."""
    a, b = a - a.mean(), b - b.mean()
    if a @ a < b @ b:
        a, b = b, a
    scale = float(np.sqrt(a @ a))
    if scale == 0.0:
        return np.zeros(R.shape[1])
    first = a / scale
    for _ in range(2):
        b = b - (first @ b) * first
    norm = float(np.sqrt(b @ b))
    out = (first @ R) ** 2
    if norm > 1e-9 * scale:
        out = out + ((b / norm) @ R) ** 2
    return out / energy


def harmonic_scores(angle: np.ndarray, start: float, step: float, count: int, R: np.ndarray,
                    sign: np.ndarray | None = None) -> np.ndarray:
    """The share of each column of R's energy that the centred pair [sin(k angle), cos(k angle)]
    explains (its least-squares fit), for k = start + j step, j < count, one row per k; with
    ``sign`` (+-1 per sample) the pair is ``sign`` times them: a level periodic in the angle that
    acts with the sign of a motion. A pair with no centred part explains nothing."""
    angle = np.ascontiguousarray(angle, dtype=float)
    R = np.ascontiguousarray(R, dtype=float)
    weight = np.ones_like(angle) if sign is None else np.ascontiguousarray(sign, dtype=float)
    energy = np.sum(R**2, axis=0)
    n = angle.size
    pair, proj = harmonic_sums(angle, weight, float(start), float(step), int(count), R)
    sa, sb, saa, sbb, sab = pair
    total = R.sum(axis=0)
    # centred: x.y - sum x sum y / n, for the pair and for its products with each column
    caa, cbb, cab = saa - sa * sa / n, sbb - sb * sb / n, sab - sa * sb / n
    pa = proj[0::2] - np.outer(sa / n, total)
    pb = proj[1::2] - np.outer(sb / n, total)
    swap = caa < cbb                      # the longer direction first
    c1, c2 = np.where(swap, cbb, caa), np.where(swap, caa, cbb)
    p1, p2 = np.where(swap[:, None], pb, pa), np.where(swap[:, None], pa, pb)
    rest = c2 - cab**2 / np.where(c1 > 0, c1, 1.0)           # the second direction's squared norm
    with np.errstate(divide="ignore", invalid="ignore"):
        first = np.where(c1[:, None] > 0, p1**2 / c1[:, None], 0.0)
        ortho = p2 - (cab / c1)[:, None] * p1
        second = np.where((rest > DEGENERATE * c1)[:, None], ortho**2 / rest[:, None], 0.0)
        scores = (first + second) / energy
    lost = ((saa > 0) & (caa < CANCELLATION * saa)) | ((sbb > 0) & (cbb < CANCELLATION * sbb)) \
        | ((c1 > 0) & (rest < CANCELLATION * c1))
    for j in np.flatnonzero(lost):
        k = start + step * j
        scores[j] = _direct(weight * np.sin(k * angle), weight * np.cos(k * angle), R, energy)
    return scores
