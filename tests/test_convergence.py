"""The simulated joint's answer at the shipped step against a 100x finer step
(``experiments.convergence``): 2 % where the physics is resolvable at 0.5 ms, first order."""
from __future__ import annotations

import pytest

from mjjoint.experiments.convergence import SHIPPED_STEP, Case, cases, measure, rel_rms

CASES = {c.name: c for c in cases()}
SLIDING = [name for name in CASES if name.startswith("free rotor") and "impulse" not in name]


@pytest.mark.parametrize("name", SLIDING)
def test_free_rotor_at_the_shipped_step_is_the_converged_one(name):
    c = measure(CASES[name])
    assert c.speed < 0.02 and c.torque < 0.02, c
    assert c.order > 0.6, c  # first order (semi-implicit Euler): halving h about halves the error


def test_a_stopping_rotor_converges_at_first_order():
    """The impulse's error is its stop instant: above 2 % at 0.5 ms, halved with the step."""
    c = measure(CASES["free rotor, 2SEP, 2 ms impulse"])
    assert c.order > 0.9 and c.speed_half < 0.6 * c.speed, c


def test_shipped_chirp_is_well_posed_and_converges_with_the_step():
    """Two fine steps agree; 0.1 ms is within 3 %; at 0.5 ms what is left (docs/design.md) is
    breakaway instants shifted within stick phases."""
    case: Case = CASES["shipped arm, 2SEP, 3 s down-chirp"]
    ref = case.plant(SHIPPED_STEP / 200, case.joint, case.u)
    fine = case.plant(SHIPPED_STEP / 100, case.joint, case.u)
    assert rel_rms(fine.tau, ref.tau) < 0.01 and rel_rms(fine.qd, ref.qd) < 0.01
    assert rel_rms(case.plant(SHIPPED_STEP / 5, case.joint, case.u).tau, ref.tau) < 0.03
    shipped = case.plant(SHIPPED_STEP, case.joint, case.u)
    assert rel_rms(shipped.tau, ref.tau) < 0.2 and rel_rms(shipped.qd, ref.qd) < 0.1


@pytest.mark.parametrize("name", ["shipped arm, B = 0, 3 s down-chirp", "shipped arm, static map, 3 s down-chirp"])
def test_shipped_chirp_without_the_lag(name):
    c = measure(CASES[name])
    assert c.speed < 0.01 and c.torque < 0.03, c
