"""The verdict does not claim that screens which did not converge ruled their effects out."""
from __future__ import annotations

import numpy as np

from mjjoint.diagnosis.loop import UNRESOLVED_RATIO, unresolved_screens


def test_screens_ending_above_the_model_they_extend_are_unresolved():
    ref = 0.01
    screened = {"backlash": (0.004, None), "transmission_hysteresis": (0.0102, None),
                "link_flexibility": (0.45, None), "linear_stiffness+backlash": (UNRESOLVED_RATIO * ref, None),
                "input_delay": (np.inf, None)}
    out = unresolved_screens(screened, ref)
    # worst first; a gain or a small loss (held-out noise) is no sign of a failed fit
    assert list(out) == ["input_delay", "link_flexibility", "linear_stiffness+backlash"]
    assert out["link_flexibility"] == 45.0


def test_quantisation_step_survives_printed_precision():
    """A 15-bit encoder read at ~100 rad and printed to 10 significant digits: its smallest
    change carries the step to ~1e-4 only, which a change of 1000 steps multiplies."""
    from mjjoint.diagnosis.floor import quantisation_step
    lsb = 2 * np.pi / 2 ** 15
    t = np.arange(0, 6, 1e-3)
    q = 100 * np.sin(2 * np.pi * 0.25 * t) + 0.01 * np.random.default_rng(0).normal(size=t.size)
    printed = np.array([float(f"{x:.10g}") for x in np.round(q / lsb) * lsb])
    assert abs(quantisation_step(printed) / lsb - 1) < 1e-5
