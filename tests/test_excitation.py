"""Excitation signals: levels, timing, areas, sweep frequencies, spectra, file replay."""
from __future__ import annotations

import numpy as np
import pytest

from mjjoint.excitation import EXCITATIONS, Chirp, FromFile, Impulse, Multisine, Step


@pytest.mark.parametrize("t0", [0.25, 0.2, 1.1])
def test_step_level_and_timing(t0):
    u = Step(amplitude=0.07, t0=t0).sample(1000, 2.0)
    k0 = round(t0 * 1000)
    assert len(u) == 2000
    assert np.all(u[:k0] == 0) and np.all(u[k0:] == 0.07)


def test_step_between_samples_keeps_the_applied_torque_integral():
    # t0 = 0.2505 s lies mid-sample: the held input must still integrate to A (T - t0).
    u = Step(amplitude=0.1, t0=0.2505).sample(1000, 1.0)
    assert u.sum() / 1000 == pytest.approx(0.1 * (1.0 - 0.2505), rel=1e-12)
    assert np.all(u[:250] == 0) and np.all(u[251:] == 0.1)


@pytest.mark.parametrize("rate, t0, width", [(1000, 0.1, 1.5e-3), (2000, 0.1, 1.5e-3), (1000, 0.0123, 7e-4),
                                              (500, 0.05, 1e-2)])
def test_impulse_area_and_support(rate, t0, width):
    amp = 1.25
    u = Impulse(amplitude=amp, t0=t0, width=width).sample(rate, 0.5)
    assert u.sum() / rate == pytest.approx(amp * width, rel=1e-12)
    t = np.arange(len(u)) / rate
    on = t[u != 0]
    assert on.min() >= t0 - 1 / rate and on.max() < t0 + width
    assert u.max() <= amp


def test_default_impulse_is_the_chapters_5_amperes_for_1_5_ms():
    k_m = 0.25  # N m/A, the shipped motor's torque constant
    imp = Impulse()
    assert imp.amplitude == pytest.approx(5 * k_m) and imp.width == pytest.approx(1.5e-3)


def _end_frequencies(u: np.ndarray, rate: float, log: bool) -> tuple[float, float]:
    """Instantaneous frequency at t = 0 and t = T from zero crossings.

    A half period between two crossings holds half a cycle, so 1/(2 dt) is the mean frequency
    over it; the two outermost estimates are extrapolated to the record ends, linearly in f
    for a linear sweep and in log f for a geometric one.
    """
    t = np.arange(len(u)) / rate
    s = np.flatnonzero(np.sign(u[:-1]) * np.sign(u[1:]) < 0)
    tz = t[s] - u[s] * (t[s + 1] - t[s]) / (u[s + 1] - u[s])
    mid, f = 0.5 * (tz[1:] + tz[:-1]), 0.5 / np.diff(tz)
    g = np.log(f) if log else f
    T = len(u) / rate
    g0 = g[0] + (g[1] - g[0]) * (0 - mid[0]) / (mid[1] - mid[0])
    g1 = g[-1] + (g[-1] - g[-2]) * (T - mid[-1]) / (mid[-1] - mid[-2])
    return (float(np.exp(g0)), float(np.exp(g1))) if log else (g0, g1)


@pytest.mark.parametrize("f_start, f_end, sweep", [(30, 1, "linear"), (1, 30, "linear"), (30, 1, "log"),
                                                   (2, 50, "log")])
def test_chirp_instantaneous_frequency_at_both_ends(f_start, f_end, sweep):
    chirp = Chirp(amplitude=0.2, f_start=f_start, f_end=f_end, sweep=sweep)
    u = chirp.sample(1000, 5.0)
    f0, f1 = _end_frequencies(u, 1000, sweep == "log")
    assert f0 == pytest.approx(f_start, rel=0.05)
    assert f1 == pytest.approx(f_end, rel=0.05)
    assert np.abs(u).max() == pytest.approx(0.2, rel=1e-3)


def test_default_chirp_is_the_chapters_30_to_1_hz_down_chirp():
    f0, f1 = _end_frequencies(Chirp().sample(1000, 5.0), 1000, log=False)
    assert f0 == pytest.approx(30, rel=0.05) and f1 == pytest.approx(1, rel=0.05)


def test_chirp_above_nyquist_is_rejected():
    with pytest.raises(ValueError, match="f_start=600"):
        Chirp(f_start=600).sample(1000, 1.0)


@pytest.mark.parametrize("seed", [0, 7])
def test_multisine_spectrum_lies_in_the_band(seed):
    ms = Multisine(amplitude=0.3, f_min=2.0, f_max=20.0, n=12, seed=seed)
    rate, T = 1000, 4.0
    u = ms.sample(rate, T)
    spec = np.abs(np.fft.rfft(u))
    freqs = np.fft.rfftfreq(len(u), 1 / rate)
    lines = freqs[spec > 1e-6 * spec.max()]
    assert len(lines) == 12
    assert lines.min() >= 2.0 and lines.max() <= 20.0
    power = spec ** 2
    in_band = power[(freqs >= 2.0) & (freqs <= 20.0)].sum()
    assert in_band / power.sum() > 1 - 1e-12
    assert np.abs(u).max() == pytest.approx(0.3, rel=1e-12)  # crest factor normalised to the peak


def test_multisine_phases_follow_the_seed():
    a, b, c = (Multisine(seed=s).sample(1000, 2.0) for s in (1, 1, 2))
    assert np.array_equal(a, b) and not np.allclose(a, c)


def test_multisine_with_more_lines_than_the_band_holds_is_rejected():
    with pytest.raises(ValueError, match="n=100"):
        Multisine(f_min=1, f_max=10, n=100).sample(1000, 2.0)  # 19 whole-period lines fit


@pytest.mark.parametrize("make, key", [
    (lambda: Impulse(width=-1e-3), "width=-0.001"),
    (lambda: Step(t0=-1), "t0=-1"),
    (lambda: Chirp(f_end=0), "f_end=0"),
    (lambda: Chirp(sweep="cubic"), "sweep='cubic'"),
    (lambda: Multisine(n=2.5), "n=2.5"),
    (lambda: Multisine(f_min=10, f_max=5), "f_max=5"),
    (lambda: Step(amplitude=float("nan")), "amplitude=nan"),
])
def test_bad_parameters_name_the_value(make, key):
    with pytest.raises(ValueError, match=key.replace(".", r"\.").replace("(", r"\(")) as info:
        make()
    assert "\n" not in str(info.value)


def test_bad_sampling_is_rejected():
    with pytest.raises(ValueError, match="rate=0"):
        Step().sample(0, 1.0)
    with pytest.raises(ValueError, match="duration=-1"):
        Step().sample(1000, -1.0)
    # an input that starts after the run would leave it at rest throughout, silently
    with pytest.raises(ValueError, match=r"t0=10 s is not before the run's end \(0.1 s\)"):
        Step(t0=10.0).sample(1000, 0.1)
    with pytest.raises(ValueError, match="t0=0.9 s"):
        Impulse(t0=0.9).sample(1000, 0.5)


def test_registry_defaults_build_and_sample():
    assert set(EXCITATIONS) == {"step", "impulse", "chirp", "multisine", "file"}
    for name, cls in EXCITATIONS.items():
        if cls is not FromFile:
            u = cls().sample(1000, 1.0)
            assert u.shape == (1000,) and np.all(np.isfinite(u)), name


def test_from_file_is_a_zero_order_hold_of_the_file(tmp_path):
    path = tmp_path / "u.csv"
    t = 10.0 + np.arange(50) / 100  # 100 Hz, starting at 10 s: time is relative to the first row
    u = np.sin(t)
    np.savetxt(path, np.column_stack([t, u, 2 * u]), delimiter=",", header="t,u,v", comments="")
    ex = FromFile(path)
    assert ex.duration == pytest.approx(0.5)
    held = ex.sample(1000, 0.5)
    assert len(held) == 500
    assert np.array_equal(held, np.repeat(u, 10))
    assert np.array_equal(FromFile(path, column="v").sample(1000, 0.5), np.repeat(2 * u, 10))


@pytest.mark.parametrize("text, match", [
    ("t,x\n0,1\n0.1,2\n", "'u'"),
    ("t,u\n0,1\n0,2\n", "line 3"),
    ("t,u\n0,1\n0.1,nan\n", "line 3"),
    ("t,u\n0,1\n0.1,abc\n", "abc"),
    ("0,1\n0.1,2\n", "header"),
    ("", "empty"),
    # t in milliseconds would replay the input a thousand times slower
    ("t,u\n" + "".join(f"{k},{k % 7}\n" for k in range(1000)), r"t looks like milliseconds.*\(write t in seconds\)"),
])
def test_from_file_bad_files_fail_in_one_line(tmp_path, text, match):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=match) as info:
        FromFile(path)
    assert "\n" not in str(info.value)


def test_from_file_shorter_than_the_request_is_rejected(tmp_path):
    path = tmp_path / "short.csv"
    path.write_text("t,u\n0,1\n0.1,2\n")
    with pytest.raises(ValueError, match="duration=1"):
        FromFile(path).sample(1000, 1.0)
    with pytest.raises(ValueError, match="no such file"):
        FromFile(tmp_path / "missing.csv")
