"""Cost of the periodic conditions' harmonic scan: the blocked kernel against each k projected alone.

``diagnosis.harmonics.harmonic_scores`` gathers, one pass over the samples per block of
harmonics, the sums a centred sine/cosine pair's projection needs; the baseline projects each
k's pair on the residual columns directly, a dozen passes over the record per k (what the scan
did before the kernel). Both score the same synthetic recordings (a motor swept over hundreds of
radians, a residual with a real-period torque in noise, 1 + 19 null columns as ``locate``
scores them), in one process and thread (this thread's CPU time, the best of the repeats), and
must agree to 1e-9; the ratio is the figure.

    python scripts/bench_harmonics.py                  # 60 s and 10-minute recordings (~2 min)
"""
from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # one thread: its CPU time is all the work
import numpy as np  # noqa: E402

from mjjoint.diagnosis.harmonics import _direct, harmonic_scores  # noqa: E402


def direct_scores(angle: np.ndarray, start: float, step: float, count: int, R: np.ndarray) -> np.ndarray:
    energy = np.sum(R**2, axis=0)
    return np.stack([_direct(np.sin(k * angle), np.cos(k * angle), R, energy)
                     for k in start + step * np.arange(count)])


def recording(seconds: float, rate: float = 1000.0, columns: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """(motor angle, residual columns): a slow swing of +-seconds rad with a 3.7-cycle torque."""
    rng = np.random.default_rng(0)
    t = np.arange(0.0, seconds, 1.0 / rate)
    q = seconds * np.sin(2 * np.pi * 3 * t / seconds)
    r = 0.1 * np.sin(3.7 * q) + rng.standard_normal(t.size)
    return q, np.column_stack([r - r.mean(), *(rng.permutation(r - r.mean()) for _ in range(columns - 1))])


def cpu(fn, repeats: int) -> tuple[float, np.ndarray]:
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.thread_time()
        out = fn()
        best = min(best, time.thread_time() - t0)
    return best, out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--count", type=int, default=200, help="harmonics scanned (default 200)")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    harmonic_scores(np.zeros(10), 1.0, 1.0, 2, np.ones((10, 1)))  # compiled (or loaded) before timing
    print("| recording | samples x columns | kernel s | per-k baseline s | **baseline / kernel** |\n|---|---|---|---|---|")
    for seconds in (60.0, 600.0):
        q, R = recording(seconds)
        fast, a = cpu(lambda: harmonic_scores(q, 1.0, 0.05, args.count, R), args.repeats)
        slow, b = cpu(lambda: direct_scores(q, 1.0, 0.05, args.count, R), 1)
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-14)
        print(f"| {seconds:g} s at 1 kHz, {args.count} harmonics | {R.shape[0]} x {R.shape[1]} | {fast:.2f} | "
              f"{slow:.2f} | **{slow / fast:.1f}x** |", flush=True)


if __name__ == "__main__":
    main()
