"""e^-x without a libm call, for the kernels that run every simulation step.

The friction kernels take two to four exponentials a step (pre-sliding, the lag's relaxation,
the Stribeck curve), each a decay e^-x with x >= 0 that matters only while x < 40 (past that it
is below the last bit of what it multiplies). libm's exp reached through numba costs a call,
glibc's compatibility wrapper and its error handling: about 60 instructions, a third of the
plugin's physics budget (docs/benchmark.md, "Per-step cost"). Here: x = (k/64) ln2 + r
(Cody-Waite, |r| <= ln2/128), e^-r by its Taylor series to r^5 and 2^-(k/64) from two tables,
inlined into the kernel that calls it; within 2 ulp of libm (tests/test_decay.py). Outside [0, 40)
(and for NaN) it is libm's exp.
"""
from __future__ import annotations

import math

import numpy as np

from .jit import inline_kernel

_N = 64  # table points per octave
_LN2_N_HI = 6.93147180369123816490e-01 / _N  # ln 2 / N's leading bits: k * _LN2_N_HI is exact for k < 2^21
_LN2_N_LO = 1.90821492927058770002e-10 / _N
_N_INV_LN2 = _N / math.log(2.0)
DECAY_RANGE = 40.0
# 2^-(j/N) for j < N, and 2^-m for the whole octaves m the range spans
_FRACTIONS = np.array([2.0 ** (-j / _N) for j in range(_N)])
_OCTAVES = np.array([2.0 ** -m for m in range(int(DECAY_RANGE / math.log(2.0)) + 2)])
# 1/i! for i = 2..5: e^-r to r^5, |r| <= ln2 / (2N), truncation below 4e-17 relative
_C2, _C3, _C4, _C5 = (1.0 / math.factorial(i) for i in range(2, 6))


@inline_kernel
def decay(x: float) -> float:
    """e^-x (module doc)."""
    if not 0.0 <= x < DECAY_RANGE:
        return math.exp(-x)
    k = int(x * _N_INV_LN2 + 0.5)
    s = k * _LN2_N_HI - x + k * _LN2_N_LO  # -r
    p = 1.0 + s * (1.0 + s * (_C2 + s * (_C3 + s * (_C4 + s * _C5))))
    return p * _FRACTIONS[k % _N] * _OCTAVES[k // _N]
