"""The harmonic scan's kernel against plain numpy sums (its scores against the SVD basis's
projection: tests/test_locate.py)."""
from __future__ import annotations

import numpy as np
import pytest

from mjjoint.diagnosis.harmonics import BLOCK, CHUNK, harmonic_sums


@pytest.mark.parametrize("seed", (0, 1))
def test_harmonic_sums_equal_the_sums_of_each_harmonic_evaluated_directly(seed):
    """Across chunks of samples and blocks of harmonics (both with a remainder), signed and not."""
    rng = np.random.default_rng(seed)
    n, count = int(2.5 * CHUNK), int(2.5 * BLOCK) + 1
    angle = np.cumsum(rng.standard_normal(n)) * 0.05
    R = rng.standard_normal((n, 3))
    start, step = rng.uniform(0.1, 2.0), rng.uniform(0.01, 0.5)
    for weight in (np.ones(n), np.sign(rng.standard_normal(n))):
        pair, proj = harmonic_sums(angle, weight, start, step, count, R)
        for j in range(count):
            k = start + step * j
            a, b = weight * np.sin(k * angle), weight * np.cos(k * angle)
            np.testing.assert_allclose(pair[:, j], [a.sum(), b.sum(), a @ a, b @ b, a @ b], rtol=1e-9, atol=1e-9)
            np.testing.assert_allclose(proj[2 * j:2 * j + 2], [a @ R, b @ R], rtol=1e-9, atol=1e-9)
