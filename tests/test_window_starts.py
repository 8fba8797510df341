"""Window starts kept off input steps (identify/windows.py, ``JUMP_SHARE``).

A window starts from the measured state, its velocity a centred Savitzky-Golay derivative. A
step of the input inside that stencil kinks the angle there, and the biased start velocity
drifts through the whole window: even the true model then misses it.
"""
from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mjjoint.assets.drive import DriveSpec
from mjjoint.identify import windows
from mjjoint.identify.fit import window_costs
from mjjoint.identify.structure import Structure
from mjjoint.identify.windows import Measured, Predictor, WindowDesign, window_starts
from mjjoint.recordings import Recording
from mjjoint.sim import step_held

from test_drive import FRICTION, TRUTH, drive_model

RATE = 1000.0
HALF, WARMUP = 3, 20  # samples: the 7 ms stencil's half width and the 20 ms warmup at 1 kHz


def _chirp(n: int) -> np.ndarray:
    t = np.arange(n) / RATE
    return np.sin(2 * np.pi * (30.0 - 29.0 * t / t[-1] / 2) * t)  # 30 Hz down to 1 Hz


def test_a_smooth_input_leaves_the_grid_alone():
    starts = window_starts(10000, 250, _chirp(10000), HALF, WARMUP)
    assert np.array_equal(starts, np.arange(0, 9750, 250))


def test_the_first_window_waits_for_a_centred_stencil_clear_of_the_loops_first_kicks():
    """A recording that starts with the controller's kicks (u jumping on its first samples):
    the first start's whole centred stencil holds none of them, within the warmup; the grid
    stays. A smooth start keeps the first sample (above)."""
    u = 0.3 * _chirp(10000)
    u[:4] += [0.0, -1.0, 2.0, -1.5]
    starts = window_starts(10000, 250, u, HALF, WARMUP)
    assert 4 <= starts[0] - HALF and starts[0] <= WARMUP
    assert np.array_equal(starts[1:], np.arange(250, 9750, 250))


@pytest.mark.parametrize("seed", range(4))
def test_starts_stay_off_steps_and_the_windows_still_tile_the_recording(seed):
    rng = np.random.default_rng(seed)
    u = 0.3 * _chirp(10000)
    steps = sorted(rng.choice(np.arange(100, 9900), 12, replace=False).tolist() + [1000, 2000])
    for k, s in enumerate(steps):
        u[s:] += (-1) ** k * rng.uniform(0.5, 1.5)
    starts = window_starts(10000, 250, u, HALF, WARMUP)
    gaps = np.diff(starts)
    # Each window starts where the last ended or at most a warmup earlier: no gap, no shared
    # cost sample.
    assert np.all((gaps >= 250 - WARMUP) & (gaps <= 250)) and starts[0] == 0 and starts[-1] + 500 >= 10000
    for s in starts:  # no step strictly inside any start's stencil s - HALF .. s + HALF
        assert not any(s - HALF < j < s + HALF for j in steps), (s, steps)
    if starts[4] != 1000:  # the first step on the grid, unless an earlier move shifted the grid
        assert 1000 - starts[3] > 250 or starts[4] == 1000 - WARMUP


def test_owned_samples_tile_the_recording_once():
    n = 9000
    t = np.arange(n) / RATE
    u = np.where(t >= 2.0, 1.0, 0.0) + np.where(t >= 5.23, -2.0, 0.0)  # both on the (moving) grid
    q = np.cumsum(np.cumsum(u)) * 1e-6
    rec = Recording(t=t, u=u, q=q, theta=q)
    p = Predictor(Measured.from_recording(rec, 1.0, output=False), WindowDesign(length=0.25))
    assert (np.diff(p.starts) < 250).sum() == 2  # the two steps' windows overlap their predecessors
    tt = p.m.t[p.samples[p.owned]]
    assert tt[0] == t[0] and np.all(np.abs(np.diff(tt) - 1 / RATE) < 1e-9)
    assert len(tt) == len(p.starts) * p.nwin_samples - (p.starts[:-1] + 250 - p.starts[1:]).sum()


def _stepped_drive_recording() -> Recording:
    """The EMPS-like drive under a force that steps on every 0.5 s window boundary."""
    model = drive_model()
    d = mujoco.MjData(model)
    rng = np.random.default_rng(1)
    h = model.opt.timestep
    n = int(round(12.0 / h))
    t = h * np.arange(n)
    levels = rng.uniform(-60.0, 60.0, size=25)
    u = levels[(t / 0.5).astype(int)] + rng.normal(0.0, 0.5, n)
    q = np.empty(n)
    for i in range(n):
        q[i] = np.round(d.qpos[0] / 1e-6) * 1e-6
        step_held(model, d, 0, u[i] / TRUTH.k_m, u[i - 1] / TRUTH.k_m if i else 0.0, 1)
    return Recording(t=t, u=u, q=q, theta=q)


def test_the_true_model_predicts_step_windows_once_their_starts_are_moved(monkeypatch):
    rec = _stepped_drive_recording()
    truth = Structure.create(("coulomb_friction", "viscous_friction", "input_offset"), DriveSpec(), 1.0).with_values(
        {"inertia.motor": TRUTH.mass, "coulomb_friction.fc": FRICTION.fc, "viscous_friction.sigma": FRICTION.sigma,
         "input_offset.offset": TRUTH.input_offset})
    measured = Measured.from_recording(rec, 1.0, output=False)
    moved = Predictor(measured, WindowDesign(length=0.5))
    monkeypatch.setattr(windows, "JUMP_SHARE", np.inf)  # every start on the grid, on a step
    grid = Predictor(measured, WindowDesign(length=0.5))
    assert np.all(grid.starts % 500 == 0) and moved.starts[1] == 500 - 20
    on_grid = window_costs(grid, truth, np.arange(len(grid.starts)))
    off_steps = window_costs(moved, truth, np.arange(len(moved.starts)))
    # Every grid window starts on a step here: the typical one is missed 16x less once moved
    # (measured), the mean 2.7x less (the rest: windows whose motion sticks and slips).
    assert np.median(off_steps) < 0.1 * np.median(on_grid)
    assert np.mean(off_steps) < 0.5 * np.mean(on_grid)


def test_stacked_logs_are_tiled_afresh_from_each_join():
    u = 0.3 * _chirp(10000)
    u[3000:] += 1.0  # a step at a join is no reason to move back across it
    u[4000:] -= 1.0  # ... one inside a log moves its window, not past the join before it
    joins = (3000, 6000)
    starts = window_starts(10000, 250, u, HALF, WARMUP, joins)
    for j in joins:
        assert j in starts
        assert not np.any((starts < j) & (starts + 250 > j))  # no window crosses a join
    assert 4000 - WARMUP in starts and np.all(starts[(starts > 4000) & (starts < 6000)] % 250 == 230)


def test_a_loop_that_kicks_at_the_start_leaves_the_fit_of_a_linear_joint_unbiased(tmp_path):
    """The independent plant's linear joint (no Coulomb friction, no gravity, ideal sensors)
    under its PD loop, whose first samples kick the resting motor: the base fit recovers the
    gear's stiffness and damping and predicts the held-out deflection far below 1 %. With the
    first window at the recording's first sample (a one-sided stencil: 1.6 rad/s for a motor at
    rest) the damping came out 3.4 % high and delta's NRMSE at 0.016."""
    import dataclasses

    from mjjoint.api.problem import joint_problems
    from mjjoint.benchmark.independent import LuGre, Sensors, record, write_csv
    from mjjoint.benchmark.independent.cases import BASE, make_case
    from mjjoint.identify.fit import fit

    case = make_case("control", 0)
    p = case.plant
    linear = dataclasses.replace(p, gravity_moment=0.0, load_coulomb=0.0,
                                 friction=LuGre(fc=1e-4, fs=1e-4, vs=1.0, sigma2=p.friction.sigma2))
    path = write_csv(tmp_path / "linear.csv", record(linear, case.excitation, Sensors(30, 30, 0.0), 0))
    (problem,) = joint_problems(path, dict(gear_ratio=linear.gear_ratio, base=list(BASE))).values()
    result = fit(problem.predictor, problem.base, max_iter=30, restarts=1)
    v = result.structure.values
    assert v["linear_stiffness.k1"] == pytest.approx(linear.stiffness, rel=0.01)
    assert v["transmission_damping.d"] == pytest.approx(linear.damping, rel=0.02)
    assert result.nrmse_test["delta"] < 0.01
