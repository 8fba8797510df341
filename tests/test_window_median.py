"""The windowed medians equal numpy's, window by window, bit for bit."""
import numpy as np
import pytest

from mjjoint.diagnosis import locate
from mjjoint.diagnosis.locate import _resonance
from mjjoint.diagnosis.window_median import window_medians


def _reference(x, starts, stops):
    return np.stack([np.median(x[a:b], axis=0) for a, b in zip(starts, stops)])


@pytest.mark.parametrize("seed", range(5))
def test_random_windows_in_any_order_match_numpy(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 300))
    # Rounded values give ties; windows jump back and forth and may be disjoint from the last.
    x = np.round(rng.standard_normal((n, 3)), 1)
    starts = rng.integers(0, n, 200)
    stops = starts + 1 + (rng.integers(0, n, 200) % (n - starts))
    np.testing.assert_array_equal(window_medians(x, starts, stops), _reference(x, starts, stops))


def test_a_window_holding_a_nan_has_median_nan_and_the_others_are_untouched():
    x = np.arange(10.0)
    x[4] = np.nan
    starts, stops = np.array([0, 2, 5, 0]), np.array([4, 6, 10, 10])
    np.testing.assert_array_equal(window_medians(x, starts, stops), _reference(x, starts, stops))


@pytest.mark.parametrize("starts, stops", [([0], [0]), ([-1], [2]), ([0], [11]), ([0, 1], [2])])
def test_an_empty_or_outside_window_is_refused(starts, stops):
    with pytest.raises(ValueError, match="window|length"):
        window_medians(np.zeros(10), starts, stops)


def test_the_resonance_scores_are_those_of_numpys_flank_medians(monkeypatch):
    # A coloured residual with a peak, and its permutations, at a 1-minute 1 kHz record's widths.
    rng = np.random.default_rng(0)
    t = np.arange(60_000) * 1e-3
    r = np.cumsum(rng.standard_normal(t.size)) * 1e-3 + 1e-2 * np.sin(2 * np.pi * 40 * t)
    R = np.column_stack([r] + [rng.permutation(r) for _ in range(3)])
    cond = _resonance(1e-3, np.sin(2 * np.pi * 0.5 * t))
    scores, params = cond.evaluate(R)
    monkeypatch.setattr(locate, "window_medians", _reference)
    expected, expected_params = cond.evaluate(R)
    np.testing.assert_array_equal(scores, expected)
    assert params == expected_params and abs(params["frequency_hz"] - 40) < 1
