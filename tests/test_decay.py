"""The kernels' e^-x against libm's."""
import math

import numpy as np
import pytest

from mjjoint.physics.decay import DECAY_RANGE, decay


def ulps(a: float, b: float) -> float:
    return abs(a - b) / math.ulp(b)


def test_decay_is_within_two_ulp_of_libm_over_its_range():
    rng = np.random.default_rng(0)
    xs = np.concatenate([np.linspace(0.0, DECAY_RANGE, 20001, endpoint=False), rng.uniform(0.0, DECAY_RANGE, 20000),
                         np.geomspace(1e-300, 1.0, 2000),
                         # the reduction's boundaries, k ln2 +- half an ulp of k ln2
                         [k * math.log(2) * (1 + e) for k in range(1, 58) for e in (-2e-16, 0.0, 2e-16)]])
    assert max(ulps(decay(float(x)), math.exp(-x)) for x in xs) <= 2.0


@pytest.mark.parametrize("x", [DECAY_RANGE, 41.5, 745.0, 800.0, -1.0, -700.0, math.inf])
def test_outside_its_range_decay_is_libm_exp(x):
    assert decay(x) == math.exp(-x)


def test_nan_stays_nan():
    assert math.isnan(decay(math.nan))
