"""The simulated joint's answer at the shipped step against a 100x finer step
(``experiments.convergence``): 2 % where the physics is resolvable at 0.5 ms, first order or
better."""
from __future__ import annotations

import numpy as np
import pytest

from mjjoint import sim as sim_module
from mjjoint.experiments.convergence import SHIPPED_STEP, Case, cases, measure, measure_arm3, rel_rms

pytestmark = pytest.mark.long(1.5)

CASES = {c.name: c for c in cases()}
SLIDING = [name for name in CASES if name.startswith("free rotor") and name.endswith("1 Hz")]


# Below this difference at the shipped step the error's terms of several orders mix (an error
# whose sign turns between h and h / 4): the order is not read there.
RESOLVED = 0.005


def converges(errors: tuple[float, ...], order: float) -> bool:
    """First order at least, or already within RESOLVED at the shipped step."""
    return errors[0] < RESOLVED or (order > 0.6 and errors[-1] < errors[0])


@pytest.mark.parametrize("name", [name for name, c in CASES.items() if not c.events])
def test_every_case_converges(name):
    """Semi-implicit Euler is first order: quartering the step about quarters the difference
    from the 100x finer step (an ill-posed model, or a term stepped inconsistently, does not)."""
    c = measure(CASES[name])
    assert converges(c.torque, c.order) and converges(c.speed, c.speed_order), c


@pytest.mark.parametrize("name", SLIDING)
def test_free_rotor_at_the_shipped_step_is_the_converged_one(name):
    c = measure(CASES[name])
    assert c.speed[0] < 0.02 and c.torque[0] < 0.02, c
    assert converges(c.torque, c.order), c


def test_a_current_loops_lag_at_the_shipped_step_is_the_converged_one():
    """The lag's activation steps as backward Euler (``builder.lag_constant``): within 2 % of the
    100x finer step at first order. The exact step of the lag itself leads by half a step
    against the centred controls: 3.3 % in tau."""
    c = measure(CASES["shipped arm, linear joint without friction, 3 ms current-loop lag, 3 s down-chirp"])
    assert c.speed[0] < 0.02 and c.torque[0] < 0.02 and c.order > 0.9, c


def test_a_stopping_rotor_converges_at_first_order():
    """The impulse's error is its stop instant: above 2 % at 0.5 ms, halved with the step; within
    8 % in the friction at 0.5 ms (11 % with z1 from the start of the step that turns the rotor
    back)."""
    c = measure(CASES["free rotor, 2SEP, 2 ms impulse"])
    assert c.order > 0.9 and c.speed[1] < 0.6 * c.speed[0] and c.torque[0] < 0.08, c


@pytest.mark.parametrize("name", ["free rotor, 2SEP, sine 1.25 Fs, 2 Hz", "shipped arm, 2SEP, 3 s down-chirp",
                                  "locked output, sine 1.25 Fs, 2 Hz"])
def test_2sep_stops_and_breakaways_at_the_shipped_step_are_the_converged_ones(name):
    """Where the rotor sticks, breaks away and reverses under the 2SEP lag, the steps that hold
    such an event are substepped (``kernels.twosep_substeps``): at 0.5 ms within 2 % of the 100x
    finer step in motor speed and torque. Taken whole, each event sat on a step and moved what
    followed: 6.6 % / 10 % on the 2 Hz sine, 11 % / 11 % on the chirp, 14 % / 6 % on the locked
    output (4.2 % / 7.1 %, 4.4 % / 5.2 %, 18 % / 7.2 % with z1 taken at the end of the steps that
    reverse the rotor); docs/design.md."""
    case = CASES[name]
    ref = case.plant(SHIPPED_STEP / 100, case.joint, case.u)
    run = case.plant(SHIPPED_STEP, case.joint, case.u)
    speed, torque = rel_rms(run.qd, ref.qd), rel_rms(getattr(run, case.torque), getattr(ref, case.torque))
    assert speed < 0.02 and torque < 0.02, (speed, torque)


@pytest.mark.parametrize("name", [name for name, c in CASES.items() if c.events])
def test_stick_slip_cases_are_well_posed_and_converge(name):
    """Where sticking and breakaway instants dominate, the model still has one answer (two fine
    steps agree) and the step approaches it: a fifth of the step, well under half the
    difference. What is left at 0.5 ms is in docs/design.md."""
    case: Case = CASES[name]
    ref = case.plant(SHIPPED_STEP / 200, case.joint, case.u)
    fine = case.plant(SHIPPED_STEP / 100, case.joint, case.u)
    assert rel_rms(fine.tau, ref.tau) < 0.01 and rel_rms(fine.qd, ref.qd) < 0.01
    coarse, finer = (case.plant(h, case.joint, case.u) for h in (SHIPPED_STEP, SHIPPED_STEP / 5))
    assert rel_rms(finer.tau, ref.tau) < 0.4 * rel_rms(coarse.tau, ref.tau)
    assert rel_rms(finer.qd, ref.qd) < 0.4 * rel_rms(coarse.qd, ref.qd)


@pytest.mark.parametrize("name", ["shipped arm, B = 0, regularised bearing, 3 s down-chirp",
                                  "shipped arm, static map, regularised bearing, 3 s down-chirp",
                                  "shipped arm, linear joint without friction, 3 s down-chirp"])
def test_shipped_chirp_without_the_lag_nor_sticking(name):
    """Without the 2SEP lag and without the bearing's stick events, the shipped chirp at 0.5 ms
    is within 2 % of the converged one (the linear joint's own: 0.5 %, the input held centred
    on the steps, ``sim.held_controls``); docs/design.md."""
    c = measure(CASES[name])
    assert c.speed[0] < 0.01 and c.torque[0] < 0.02, c


@pytest.mark.parametrize("name", ["shipped arm, B = 0, 3 s down-chirp", "shipped arm, static map, 3 s down-chirp"])
def test_the_sticking_bearing_adds_events_that_converge(name):
    """The sticking bearing's stops and breakaways, each a step early or late, add to the chirp's
    difference but not to its order: halving the step halves it; within 2 % at 0.5 ms."""
    c = measure(CASES[name])
    assert c.speed[0] < 0.01 and c.torque[0] < 0.02 and c.order > 0.9 and c.torque[1] < 0.6 * c.torque[0], c


def test_a_plainly_held_input_is_half_a_step_early():
    """Held plainly over each sample's steps, the input acts half a step early: a first-order
    error that dominated the linear joint's chirp (3.4 % in tau at 0.5 ms); centred on the
    steps (``sim.held_controls``) it is second order."""
    case = CASES["shipped arm, linear joint without friction, 3 s down-chirp"]
    ref = case.plant(SHIPPED_STEP / 100, case.joint, case.u)
    centred = rel_rms(case.plant(SHIPPED_STEP, case.joint, case.u).tau, ref.tau)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(sim_module, "held_controls", lambda c, substeps, before=0.0: np.repeat(np.asarray(c, float), substeps, axis=0))
        plain = rel_rms(case.plant(SHIPPED_STEP, case.joint, case.u).tau, ref.tau)
    assert plain > 0.02 and centred < 0.25 * plain, (plain, centred)


def test_the_three_joint_arm_at_twice_the_seed_motors_speed_is_the_converged_one():
    """Every motor of the shipped 3-joint arm under the chapter's down-chirp at half its current
    limit (600 rad/s at the motors, the shoulder's gear to 2.6x its rated deflection): each
    joint's motor speed and gear torque at 0.5 ms within 2 % of the 100x finer step's, first
    order (halved with the step). At the full current limit, through the arm's 12 Hz mode, the
    gears pass 3.7x their rated deflection and the hardening beyond the stable explicit
    stiffness is taken implicitly: the elbow's torque then differs by 7.7 % (docs/design.md)."""
    for j, c in enumerate(measure_arm3(), start=1):
        assert c.speed[0] < 0.02 and c.torque[0] < 0.02, (j, c)
        assert c.speed[1] < 0.6 * c.speed[0] and c.torque[1] < 0.6 * c.torque[0], (j, c)
