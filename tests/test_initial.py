"""Initial values and ranges from the recording: drives decades away from the shipped ones fit
with no --scales, and the estimator recovers known parameters of noise-free recordings."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from mjjoint.assets import ArmSpec
from mjjoint.assets.drive import DriveSpec
from mjjoint.excitation import Chirp
from mjjoint.experiments.servo import LARGE, SMALL, geared_recording, servo_recording
from mjjoint.identify.effects import EFFECTS
from mjjoint.identify.initial import CATALOGUE_ORDERS, DECADES, STIFFNESS, Estimate, engaged_gear, estimate
from mjjoint.identify.structure import Structure
from mjjoint.identify.windows import Measured
from mjjoint.joint import JointParams
from mjjoint.physics.transmission import Transmission
from mjjoint.recordings import Recording, write_recording


@pytest.mark.parametrize("case", [SMALL, LARGE], ids=["small", "large"])
def test_the_estimator_recovers_a_drives_inertia_and_friction(case):
    j, fc, sigma = case.inertia, case.coulomb, case.viscous
    e = estimate(Measured.from_recording(servo_recording(case), 1.0, output=False))
    # Start values, for a fit that may move each DECADES either way: the inertia within 5 %,
    # the friction levels (which the J a term dwarfs on the large drive) within half.
    assert e.values["inertia.motor"] == pytest.approx(j, rel=0.05)
    assert e.values["coulomb_friction.fc"] == pytest.approx(fc, rel=0.5)
    assert e.values["viscous_friction.sigma"] == pytest.approx(sigma, rel=0.5)
    # Every range is centred on its estimate, so the truth lies far inside.
    s = Structure.create(("coulomb_friction", "viscous_friction"), DriveSpec(joint_type="hinge"), 1.0, start=e)
    for p in s.params:
        assert p.lo == pytest.approx(p.initial * 10 ** -DECADES) and p.hi == pytest.approx(p.initial * 10 ** DECADES)


@pytest.mark.parametrize("case", [SMALL, LARGE], ids=["small", "large"])
def test_fit_plant_rotary_recovers_motors_decades_apart_with_no_scales(case, tmp_path, capsys):
    from mjjoint.cli import main
    j, fc = case.inertia, case.coulomb
    rec = tmp_path / "servo.csv"
    write_recording(rec, servo_recording(case))
    out = tmp_path / "fit"
    assert main(["fit", str(rec), "--plant", "rotary", "--base", "coulomb_friction,viscous_friction",
                 "--window-length", "0.5", "--max-iter", "15", "--out", str(out)]) == 0
    fitted = json.loads((out / "fit.json").read_text())["structure"]["parameters"]
    # The fitted model's sign regularisation is set from the estimated Fc / J (Estimate.v_eps),
    # the truth's from the true one: 0.036 against 0.025 rad/s on the large drive, whose Fc the
    # fit then takes 8 % low (measured), the inertia within 1 %.
    assert fitted["inertia.motor"] == pytest.approx(j, rel=0.05)
    assert fitted["coulomb_friction.fc"] == pytest.approx(fc, rel=0.1)
    assert "kg m^2" in capsys.readouterr().out  # rotary units, SI


@pytest.mark.parametrize("k1", [3e3, 3e4])
def test_the_estimator_recovers_the_gear_stiffness_from_the_torque_and_the_resonance(k1):
    measured, arm = geared_recording(k1)
    e = estimate(measured, arm)
    assert e.values["linear_stiffness.k1"] == pytest.approx(k1, rel=0.05)
    assert e.values["inertia.motor"] == pytest.approx(arm.motor_inertia, rel=0.05)
    assert e.values["coulomb_friction.fc"] == pytest.approx(0.05, rel=0.05)
    assert e.values["viscous_friction.sigma"] == pytest.approx(2e-4, rel=0.25)
    # Without the torque sensor: the resonance of the input-to-deflection response.
    untorqued = dataclasses.replace(measured, tau=None)
    e = estimate(untorqued, arm)
    assert e.resonance is not None
    assert e.values["linear_stiffness.k1"] == pytest.approx(k1, rel=0.25)


def test_without_the_torque_sensor_a_heavy_links_rigid_inertia_is_split_between_the_sides():
    """A link 440x the nominal's, driven below its gear's modes, and no tau: the recording fixes
    only the sum J_m + J_l/N^2. The start keeps the sum and splits it evenly, so the side that
    carries most of it (the link) starts within a factor 2 (the nominal link, kept as it was,
    started it 440x light, on a gear 300x too soft for it); a link of the nominal's size keeps
    the nominal split."""
    n = 160.0
    slow = Chirp(amplitude=3.0, f_start=5.0)  # below the anti-resonance: the joint moves as one
    measured, arm = geared_recording(3e6, tau=False, tip_mass=500.0, chirp=slow)
    nominal = ArmSpec(segments=0, gravity=0.0)
    v = estimate(measured, nominal).values
    link = nominal.link_inertia + (v["mass.tip"] - nominal.tip_mass) * nominal.rod_length ** 2
    truth = arm.motor_inertia + arm.link_inertia / n ** 2
    assert v["inertia.motor"] + link / n ** 2 == pytest.approx(truth, rel=0.05)
    assert v["inertia.motor"] == pytest.approx(link / n ** 2)
    assert 0.45 < link / arm.link_inertia < 1.05
    # No resonance in view: the gear as stiff for this link as the nominal's for its own.
    assert v["linear_stiffness.k1"] / link == pytest.approx(STIFFNESS.initial / nominal.link_inertia)
    v = estimate(geared_recording(3e4, tau=False, chirp=slow)[0], nominal).values
    assert "mass.tip" not in v
    assert v["inertia.motor"] == pytest.approx(nominal.motor_inertia, rel=0.1)


def test_a_fit_started_off_ends_on_a_bound_and_restarts_recover_the_truth():
    """J started a thousandfold low and Fc three hundredfold high: the single fit ends with
    parameters on their bounds and says which; restarts from the recording's estimates reach
    the truth, with nothing on a bound."""
    from mjjoint.identify.fit import fit
    from mjjoint.identify.windows import Predictor, WindowDesign
    j, fc = SMALL.inertia, SMALL.coulomb
    measured = Measured.from_recording(servo_recording(SMALL, duration=3.0), 1.0, output=False)
    start = estimate(measured)
    nominal = DriveSpec(joint_type="hinge", v_eps=start.v_eps(DriveSpec.timestep, DriveSpec.v_eps))
    s = Structure.create(("coulomb_friction", "viscous_friction"), nominal, 1.0, start=start)
    lo = {p.name: p.lo for p in s.params}
    hi = {p.name: p.hi for p in s.params}
    off = s.with_values({"inertia.motor": lo["inertia.motor"], "coulomb_friction.fc": hi["coulomb_friction.fc"],
                         "viscous_friction.sigma": hi["viscous_friction.sigma"]})
    pred = Predictor(measured, WindowDesign(length=0.25))
    single = fit(pred, off, max_iter=10)
    assert single.on_bound and single.as_dict()["on_bound"] == list(single.on_bound)
    assert all(f"{n} = " in w and "bound" in w for n, w in zip(single.on_bound, single.warnings))
    best = fit(pred, off, max_iter=10, restarts=2)
    assert best.starts == 3 and best.on_bound == ()
    assert best.structure.values["inertia.motor"] == pytest.approx(j, rel=0.05)
    assert best.structure.values["coulomb_friction.fc"] == pytest.approx(fc, rel=0.05)


def test_a_refit_on_a_bound_far_from_its_floor_is_fitted_again_from_the_recordings_start():
    """The diagnosis's refit after an addition (``loop.restarted``): a fit left on its bounds far
    above the noise floor is fitted again from the recording's estimates and the lower training
    cost kept; a fit near its floor with nothing on a bound is returned as it is."""
    from mjjoint.diagnosis.clock import Phases
    from mjjoint.diagnosis.floor import noise_floor
    from mjjoint.diagnosis.loop import FAR_FROM_FLOOR, DiagnoseOptions, restarted
    from mjjoint.identify.fit import fit
    from mjjoint.identify.windows import Predictor, WindowDesign
    measured = Measured.from_recording(servo_recording(SMALL, duration=3.0), 1.0, output=False)
    start = estimate(measured)
    nominal = DriveSpec(joint_type="hinge", v_eps=start.v_eps(DriveSpec.timestep, DriveSpec.v_eps))
    s = Structure.create(("coulomb_friction", "viscous_friction"), nominal, 1.0, start=start)
    bounds = {p.name: (p.lo, p.hi) for p in s.params}
    off = s.with_values({"inertia.motor": bounds["inertia.motor"][0], "coulomb_friction.fc": bounds["coulomb_friction.fc"][1],
                         "viscous_friction.sigma": bounds["viscous_friction.sigma"][1]})
    pred = Predictor(measured, WindowDesign(length=0.25))
    floor = noise_floor(pred, s)
    options = DiagnoseOptions(fit_iter=10)
    said = []
    phases = Phases(lambda: pred.rollouts)
    stuck = fit(pred, off, max_iter=10)
    assert stuck.on_bound and floor.worst(stuck.nrmse_test) > FAR_FROM_FLOOR
    again = restarted(pred, stuck, floor, options, said.append, None, phases)
    assert again.on_bound == () and again.cost_train < stuck.cost_train
    assert again.structure.values["inertia.motor"] == pytest.approx(SMALL.inertia, rel=0.05)
    assert "refitted from the recording's start" in said[0] and said[0].endswith(": kept")
    good = fit(pred, s, max_iter=10)
    assert good.on_bound == ()
    assert restarted(pred, good, floor, options, said.append, None, phases) is good and len(said) == 1


def test_the_lab_arms_recordings_keep_the_catalogues_orders():
    """Chirp, multisine and the closed-loop lab program all round to the catalogue's decade:
    on the arm the catalogue is scaled by exactly 1, and a drive 5 decades away is not."""
    from types import SimpleNamespace

    import mjjoint
    from mjjoint.benchmark.cases import NOMINAL
    from mjjoint.rehearse import record
    recs = [mjjoint.simulate(ex.sample(1000, 5)) for ex in (mjjoint.Chirp(), mjjoint.Multisine())]
    recs.append(SimpleNamespace(**record(NOMINAL, JointParams())))
    for rec in recs:
        assert estimate(Measured.from_recording(rec, 160.0)).scales == {"force": 1.0, "speed": 1.0, "position": 1.0}
    large = estimate(Measured.from_recording(servo_recording(LARGE), 1.0, output=False))
    assert large.scales["force"] >= 1e3


def test_the_play_and_the_spring_beyond_it_are_read_from_the_engaged_teeth():
    """delta = T/k + (b/2) sgn(T) - (D/k) delta' wherever the teeth touch: a deflection swept
    through a dead zone of width b gives b and k back; a gear without play gives no start."""
    t = np.arange(0.0, 2.0, 1e-3)
    delta = 2e-3 * np.sin(2 * np.pi * 3 * t) + 1e-7 * np.random.default_rng(0).standard_normal(t.size)
    k, d = 5e3, 2.0
    for b in (0.0, 1e-3):
        de = np.sign(delta) * np.maximum(np.abs(delta) - b / 2, 0.0)
        torque = k * de + d * np.gradient(de, t)
        play = engaged_gear(delta, np.gradient(delta, t), torque)
        if b == 0.0:
            assert play == {}
        else:
            assert play["backlash.width"] == pytest.approx(b, rel=0.02)
            assert play["linear_stiffness.k1"] == pytest.approx(k, rel=0.02)


def test_a_simulated_play_wider_than_the_catalogues_start_is_offered_to_the_backlash_screen():
    from mjjoint.physics.friction import StaticFriction
    from mjjoint.sim import simulate
    arm = ArmSpec(segments=0, gravity=0.0)
    for width in (0.0, 6e-4):
        joint = JointParams(friction=StaticFriction(fc=0.05, fs=0.05, sigma=2e-4), load_friction=None,
                            transmission=Transmission(gear_ratio=160.0, k1=5e3, k3=0.0, damping=1.0,
                                                      hysteresis=None, backlash=width))
        trace = simulate(Chirp(f_start=30.0).sample(1000, 5), arm=arm, joint=joint)
        measured = Measured.from_recording(Recording(t=trace.t, u=trace.u, q=trace.q, theta=trace.theta,
                                                     tau=trace.tau), 160.0)
        structure = Structure.create(("linear_stiffness",), arm, 160.0, start=estimate(measured, arm))
        starts = [values for values, _ in EFFECTS["backlash"].variants([], structure)]
        if width == 0.0:
            assert starts == [{}]
        else:
            assert starts[0] == {} and starts[1]["backlash.width"] == pytest.approx(width, rel=0.2)
            assert starts[1]["linear_stiffness.k1"] == pytest.approx(5e3, rel=0.2)


@pytest.mark.parametrize("g", [24.6, 1194.0], ids=["inside", "outside"])
def test_every_range_started_from_a_recording_is_one_the_model_accepts(g):
    """A link regression that reads gravity at 24.6 m/s^2 starts g there but keeps its range
    (DECADES either side would reach 2.5e4, which the arm refuses: a fit stepping there ends in
    an error, not a cost); one that reads 1194 is no estimate of g at all. Every other parameter
    at either end of its range builds a model too."""
    effects = ("coulomb_friction", "viscous_friction", "gravity", "load_friction", "linear_stiffness")
    base = Structure.create(effects, ArmSpec(), 160.0)
    start = Estimate(CATALOGUE_ORDERS["force"], CATALOGUE_ORDERS["speed"],
                     values={"gravity.g": g, "mass.tip": 3.5, "load_friction.viscous": 11.0})
    started = base.started(start)
    param = next(p for p in started.params if p.name == "gravity.g")
    catalogue = EFFECTS["gravity"].params[0]
    assert (param.lo, param.hi) == (catalogue.lo, catalogue.hi)
    assert param.initial == (g if catalogue.lo <= g <= catalogue.hi else catalogue.initial)
    for p in started.params:
        for end in (p.lo, p.hi):
            started.with_values({p.name: end}).model_params()


def test_a_start_too_stiff_for_the_step_is_set_back_to_the_nominal():
    """A second of the shipped arm's down-chirp without the gear torque sits above the gear's
    resonance, where the rotor moves alone: the rigid regression reads a rotor inertia a hundred
    times below the shipped one, too light for the fitting step, and a fit from there scored
    nothing but refused predictions (every NRMSE n/a). The problem's start sets that value back."""
    from mjjoint.api.problem import joint_problems
    from mjjoint.identify.windows import WindowDesign, stable
    from mjjoint.sim import Simulator
    tr = Simulator().run(Chirp().sample(1000.0, 1.0))
    rec = Recording(t=tr.t, u=tr.u, q=tr.q, theta=tr.theta)  # no torque sensor
    design = dataclasses.replace(WindowDesign(), length=0.05)
    problem = joint_problems(rec, dict(gear_ratio=160.0, base=(), design=design))[None]
    assert problem.base.start.values["inertia.motor"] < 1e-2 * ArmSpec().motor_inertia  # the misread
    assert stable(problem.base) and problem.base.values["inertia.motor"] == pytest.approx(ArmSpec().motor_inertia)


def test_a_recording_too_short_to_filter_is_refused_in_words():
    """Twelve samples reached scipy's "padlen" message; a recording read at the wrong time unit,
    its Savitzky-Golay window's."""
    t = np.arange(12) / 1000.0
    rec = Recording(t=t, u=np.sin(t), q=np.sin(40 * t), theta=np.sin(40 * t) / 160.0)
    with pytest.raises(ValueError, match="12 samples are too few to estimate the joint from"):
        estimate(Measured.from_recording(rec, 160.0))
    t = np.arange(1000) * 1e-6  # a millisecond clock read as seconds, scaled once more
    with pytest.raises(ValueError, match="1000 samples at 1e\\+06 Hz are fewer than the derivative's window"):
        Measured.from_recording(Recording(t=t, u=np.sin(t), q=np.sin(t), theta=np.sin(t) / 160.0), 160.0)
