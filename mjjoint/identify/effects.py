"""The catalogue of physical effects a joint model may contain, each a real simulator term.

A model structure is a set of effect names; the minimal structure ("inertias and gear") is a
rigid gear between two inertias. Every effect switches on one term of the simulator (an
ArmSpec or JointParams field) and brings its free parameters, each with bounds, a scale
(log for positive magnitudes spanning decades) and an initial guess. Names are fixed: they
are what ``diagnose`` reports.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
from ..assets import ArmSpec
from ..assets.drive import DriveSpec, drive_joint
from ..joint import JointParams
from ..physics.boucwen import BoucWen
from ..physics.load import LoadFriction
from ..physics.ripple import TorqueRipple
from ..physics.stribeck import StaticFriction
from ..physics.transmission import Transmission
from ..physics.catalogue import MODULES
from ..physics.twosep import TwoSEP
from .effect import Effect, Param, term_values
from .generic import GENERIC_EFFECTS


Plant = ArmSpec | DriveSpec
Model = tuple[Plant, JointParams]


def _friction(model: Model) -> StaticFriction | TwoSEP:
    """The model's motor friction, or none yet: zero levels, the plant's sign regularisation."""
    if model[1].friction is not None:
        return model[1].friction
    return StaticFriction(fc=0.0, fs=0.0, sigma=0.0, v_eps=plant_v_eps(model[0]))


def plant_v_eps(nominal: Plant) -> float:
    """The motor friction's sign regularisation a plant gives it (a drive's XML, else the term's)."""
    return nominal.v_eps if isinstance(nominal, DriveSpec) else StaticFriction.v_eps


# The motor friction's sign regularisation [speed], a setting: the plant's unless a recording of
# a light motor with strong friction needs a wider one for the explicit step to stay stable
# (``initial.Estimate.v_eps``).
FRICTION_V_EPS = "coulomb_friction.v_eps"


def _coulomb(model: Model, v: dict[str, float]) -> Model:
    return _set_friction(model, fc=v["coulomb_friction.fc"], **({"v_eps": v[FRICTION_V_EPS]} if FRICTION_V_EPS in v else {}))


def _set_friction(model: Model, **changes) -> Model:
    arm, j = model
    f = _friction(model)
    if "fc" in changes and "fs" not in changes and f.fs <= f.fc:
        changes["fs"] = changes["fc"]  # Coulomb alone: break-away equals sliding level
    fields = {k: v for k, v in changes.items() if k in {x.name for x in dataclasses.fields(f)}}
    return arm, dataclasses.replace(j, friction=dataclasses.replace(f, **fields))


def _set_transmission(model: Model, **changes) -> Model:
    arm, j = model
    return arm, dataclasses.replace(j, transmission=dataclasses.replace(j.transmission, **changes))


def _dynamic(model: Model, v: dict[str, float]) -> Model:
    arm, j = model
    f = _friction(model)
    twosep = TwoSEP(fc=max(f.fc, 1e-6), fs=max(f.fs, f.fc, 1e-6), vs=f.vs, shape=f.shape,
                    sigma=f.sigma, asym=f.asym, sigma_asym=f.sigma_asym, load_gain=f.load_gain,
                    k=v["dynamic_friction.k"], b=v["dynamic_friction.b"])
    return arm, dataclasses.replace(j, friction=twosep)


# Eq. 15's Stribeck shape factor delta, a setting: 1 the exponential decay (the simulator's
# default), 2 the Gaussian one (LuGre's usual map). A fitted exponent trades off against Vs
# along a valley of the cost, so the two common shapes are screened instead.
STRIBECK_SHAPE = "stribeck_friction.shape"
STRIBECK_SHAPES = (1.0, 2.0)


def _stribeck(model: Model, v: dict[str, float]) -> Model:
    fc = _friction(model).fc
    return _set_friction(model, fs=fc * v["stribeck_friction.ratio"], vs=v["stribeck_friction.vs"],
                         shape=v.get(STRIBECK_SHAPE, StaticFriction.shape))


def _asym(model: Model, v: dict[str, float]) -> Model:
    return _set_friction(model, asym=_friction(model).fc * v["friction_asymmetry.ratio"])


# Eq. 17's loop shape gamma / beta, a setting: 1 the classic loop (unloading along the elastic
# slope A), 0 beta alone (unloading stiffer, A + beta |x|). The passive range |gamma| <= beta,
# which BoucWen enforces, ends at 1: a fitted ratio would sit on its bound at the classic loop,
# so the ratio is screened at both ends of [0, 1] instead.
HYSTERESIS_SHAPE = "transmission_hysteresis.shape"
HYSTERESIS_SHAPES = (1.0, 0.0)


def _hysteresis(model: Model, v: dict[str, float]) -> Model:
    shape = v.get(HYSTERESIS_SHAPE, 1.0)  # gamma / beta; x_u = 1/(beta + gamma)
    beta = 1.0 / ((1.0 + shape) * v["transmission_hysteresis.x_u"])
    bw = BoucWen(mu=v["transmission_hysteresis.mu"], beta=beta, gamma=shape * beta)
    return _set_transmission(model, hysteresis=bw)


def _tried(setting: str, values: tuple[float, ...]):
    """``Effect.variants`` of a shape factor that is tried rather than fitted: one screen per value."""
    return lambda conds, structure: [({}, {setting: v}) for v in values]


def _read_hysteresis(model: Model) -> dict[str, float] | None:
    bw = model[1].term("hysteresis")
    if bw is None:
        return None
    return {"transmission_hysteresis.mu": bw.mu, "transmission_hysteresis.x_u": bw.x_ultimate,
            HYSTERESIS_SHAPE: bw.gamma / bw.beta if bw.beta > 0 else 1.0}


def _ripple(model: Model, v: dict[str, float]) -> Model:
    a, b = v["torque_ripple.a"], v["torque_ripple.b"]
    r = TorqueRipple(amplitude=math.hypot(a, b), harmonic=v["torque_ripple.harmonic"], phase=math.atan2(b, a))
    return model[0], dataclasses.replace(model[1], ripple=r)


def _skewed(pred: dict, v: dict[str, float], rate: float) -> dict:
    """The link angle as an encoder read ``lag`` late sees it, theta(t - lag), and the deflection
    from it (beyond a window's ends along its first or last step: ``shift_late``)."""
    theta = shift_late(pred["theta"], v["sensor_skew.lag"] * rate)
    # delta = q / N - theta: the motor side is read on time.
    return {**pred, "theta": theta, "delta": pred["delta"] + pred["theta"] - theta}


def shift_late(x: np.ndarray, samples: float) -> np.ndarray:
    """Rows of x read ``samples`` (fractional, either sign) late, linearly interpolated, and
    extrapolated beyond the ends along the first or the last step: a window's prediction ends
    where a sensor read early needs what follows, and an end held there misses by the whole
    motion over the shift."""
    n = x.shape[-1]
    at = np.arange(n) - samples
    i = np.clip(np.floor(at).astype(int), 0, n - 2)
    f = at - i
    return x[..., i] * (1.0 - f) + x[..., i + 1] * f


def _arm(model: Model, **changes) -> Model:
    return dataclasses.replace(model[0], **changes), model[1]


def _load(model: Model, v: dict[str, float]) -> Model:
    lf = LoadFriction(fc=v["load_friction.fc"], viscous=v["load_friction.viscous"])
    return model[0], dataclasses.replace(model[1], load_friction=lf)


def _ripple_variants(conds: list[dict], structure) -> list[tuple[dict, dict]]:
    """The ripple harmonic is not fitted but tried: each signal's residual proposes its own best
    k (they need not agree: the q residual is dominated by other errors), so every distinct
    proposal is screened, most-explained first, at most three; a real k (the rotor's balance
    scans real periods) at the whole harmonic nearest it."""
    ranked = sorted((c for c in conds if c["name"] == "periodic_q" and c["params"].get("k")),
                    key=lambda c: -c["score"])
    ks = list(dict.fromkeys(float(max(1, round(c["params"]["k"]))) for c in ranked))[:3] or [1.0]
    return [({}, {"torque_ripple.harmonic": k}) for k in ks]


def _play_variants(conds: list[dict], structure) -> list[tuple[dict, dict]]:
    """The catalogue's start, and the play the recording's deflection shows with the stiffness
    beyond it (``initial.engaged_gear``) where there is one: a wide play screened from a narrow
    start with the base's softened spring stalls there."""
    play = structure.start.play if structure.start is not None else {}
    return [({}, {})] + ([(dict(play), {})] if play else [])


def _at_located_lag(param: str, cap: float):
    """``Effect.variants`` of an input's time constant: started at the lag the residual's
    cross-correlation locates (at most ``cap``, inside the bound)."""
    def variants(conds: list[dict], structure) -> list[tuple[dict, dict]]:
        lags = [c["params"].get("lag_ms") for c in conds if c["name"] == "lag" and c["significant"]]
        if lags and lags[0] > 0:
            return [({param: min(lags[0] * 1e-3, cap)}, {})]
        return [({}, {})]
    return variants


# [N m/rad] 2SEP's attraction gain B, the catalogue's start (TwoSEP's default).
LAG_GAIN = TwoSEP().b
# [1/rad] a soft contact's pre-sliding stiffness: 95 % of Fc within 0.1 rad at the motor, a
# bristle's (LuGre's z0 of 0.01-0.03 rad) where the catalogue's start is a gear's teeth (3 mrad).
SOFT_PRESLIDING = 30.0


def _lag_variants(conds: list[dict], structure) -> list[tuple[dict, dict]]:
    """From the catalogue's lag gain and from a tenth of it: the lag winds up over each dwell and
    holds the next breakaway until it decays, so a gain far above the truth's starts in another
    breakaway's valley of the cost. And from a soft contact's pre-sliding (SOFT_PRESLIDING) with
    a fifth of the gain: its valley lies decades below the catalogue's K, beyond a restart's
    spread."""
    return [({}, {}), ({"dynamic_friction.b": LAG_GAIN / 10}, {}),
            ({"dynamic_friction.k": SOFT_PRESLIDING, "dynamic_friction.b": LAG_GAIN / 5}, {})]


# The rod's damping as Rayleigh's stiffness-proportional coefficient beta = c / k of its hinges
# [s]: a mode of frequency w is damped at the ratio beta w / 2 whatever the stiffness, so the
# two parameters do not trade off. The catalogue's value is the shipped rod's.
ROD_BETA = ArmSpec.segment_damping / ArmSpec().hinge_stiffness


def _flexibility(model: Model, v: dict[str, float]) -> Model:
    arm = dataclasses.replace(model[0], segments=4, rod_ei=v["link_flexibility.ei"])
    return dataclasses.replace(arm, segment_damping=v["link_flexibility.beta"] * arm.hinge_stiffness), model[1]


def _read_flexibility(model: Model) -> dict[str, float] | None:
    arm = model[0]
    if not getattr(arm, "segments", 0):
        return None
    return {"link_flexibility.ei": arm.rod_ei, "link_flexibility.beta": arm.segment_damping / arm.hinge_stiffness}


# Rayleigh's share of a uniform cantilever's mass that moves with its tip in the first mode (33/140).
RAYLEIGH_ROD_SHARE = 33.0 / 140.0


def _rod_mass(structure) -> float:
    """The mass [kg] at the tip of the rod's first mode with the hub held, a cantilever of
    stiffness 3 EI / L^3: its tip mass and Rayleigh's share of the rod's."""
    return structure.values.get("mass.tip", structure.nominal.tip_mass) + RAYLEIGH_ROD_SHARE * structure.nominal.rod_mass


def _rod_mode_hz(structure) -> float:
    """The rod's first mode [Hz] with the hub held (``_rod_mass``)."""
    k = 3 * structure.values["link_flexibility.ei"] / structure.nominal.rod_length ** 3
    return math.sqrt(k / _rod_mass(structure)) / (2 * math.pi)


def _flexibility_variants(conds: list[dict], structure) -> list[tuple[dict, dict]]:
    """Started where the rod's first mode with the hub held (``_rod_mass``) lies at the resonance
    the residual locates; from the catalogue's EI where none is located."""
    freqs = [c["params"]["frequency_hz"] for c in conds if c["name"] == "resonance" and c["significant"]]
    if not freqs:
        return [({}, {})]
    ei = _rod_mass(structure) * (2 * math.pi * freqs[0]) ** 2 * structure.nominal.rod_length ** 3 / 3
    return [({"link_flexibility.ei": ei}, {})]


def _friction_read(values, present=lambda f: True, coulomb: bool = True):
    """``Effect.read`` of a motor friction effect: ``values(f)`` of the model's friction where it
    is ``present`` and, with ``coulomb``, has a Coulomb level (the effects that refine it need one)."""
    def read(model: Model):
        f = model[1].friction
        return values(f) if f is not None and (f.fc > 0 or not coulomb) and present(f) else None
    return read


def _when(value, read):
    """``read(value)`` where ``value`` is not None, else None."""
    return None if value is None else read(value)


def _read_ripple(r: TorqueRipple) -> dict[str, float]:
    return {"torque_ripple.a": r.amplitude * math.cos(r.phase), "torque_ripple.b": r.amplitude * math.sin(r.phase),
            "torque_ripple.harmonic": r.harmonic}


def _arm_value(model: Model, name: str, key: str):
    v = getattr(model[0], name, 0.0)
    return {key: v} if v else None


MOTOR_SIGN = ("coulomb", "reversal")
EFFECTS: dict[str, Effect] = {e.name: e for e in (
    Effect("coulomb_friction", "constant motor friction opposing motion, Fc sgn(w)",
           (Param("coulomb_friction.fc", 0.05, 1e-4, 5.0, unit="N m", dim="force"),),
           _coulomb, evidence=MOTOR_SIGN, plot="motor_velocity", direct_drive=True, term="friction",
           read=_friction_read(lambda f: {"coulomb_friction.fc": f.fc})),
    Effect("viscous_friction", "motor friction proportional to speed, sigma w",
           (Param("viscous_friction.sigma", 1e-4, 1e-7, 1e-1, unit="N m s/rad", dim="force/speed"),),
           lambda m, v: _set_friction(m, sigma=v["viscous_friction.sigma"]),
           evidence=("viscous",), plot="motor_velocity", direct_drive=True, term="friction",
           read=_friction_read(lambda f: {"viscous_friction.sigma": f.sigma}, lambda f: f.sigma > 0, coulomb=False)),
    Effect("stribeck_friction", "break-away above the Coulomb level at low speed (Eq. 15)",
           (Param("stribeck_friction.ratio", 1.5, 1.0, 5.0, log=False),
            Param("stribeck_friction.vs", 0.5, 1e-3, 100.0, unit="rad/s", dim="speed")),
           _stribeck, requires=("coulomb_friction",), variants=_tried(STRIBECK_SHAPE, STRIBECK_SHAPES),
           evidence=("stribeck", "reversal"), acts_under="reversal", plot="motor_velocity", direct_drive=True,
           term="friction",
           read=_friction_read(lambda f: {"stribeck_friction.ratio": f.fs / f.fc, "stribeck_friction.vs": f.vs,
                                          STRIBECK_SHAPE: f.shape},
                               lambda f: f.fs > f.fc)),
    Effect("dynamic_friction", "2SEP pre-sliding hysteresis and frictional lag (Eqs. 11-14)",
           (Param("dynamic_friction.k", 1000.0, 10.0, 1e5, unit="1/rad", dim="1/position"),
            Param("dynamic_friction.b", LAG_GAIN, 0.1, 1e4, unit="N m/rad", dim="force/position")),
           _dynamic, requires=("coulomb_friction",), variants=_lag_variants,
           # its pre-sliding spring holds the rotor at rest as dry friction does
           evidence=("reversal", "hysteresis", "lag", "rotor_holds"), acts_under="reversal", plot="motor_velocity",
           direct_drive=True, term="friction",
           read=_friction_read(lambda f: {"dynamic_friction.k": f.k, "dynamic_friction.b": f.b},
                               lambda f: isinstance(f, TwoSEP))),
    Effect("friction_asymmetry", "direction-dependent friction level",
           (Param("friction_asymmetry.ratio", 0.0, -0.9, 0.9, log=False),),
           _asym, requires=("coulomb_friction",),
           evidence=("coulomb",), plot="motor_velocity", direct_drive=True, term="friction",
           read=_friction_read(lambda f: {"friction_asymmetry.ratio": f.asym / f.fc}, lambda f: f.asym != 0)),
    Effect("viscous_asymmetry", "direction-dependent viscous slope, sigma (1 + r sgn w) w",
           (Param("viscous_asymmetry.ratio", 0.0, -0.9, 0.9, log=False),),
           lambda m, v: _set_friction(m, sigma_asym=v["viscous_asymmetry.ratio"]), requires=("viscous_friction",),
           evidence=("viscous",), plot="motor_velocity", direct_drive=True, term="friction",
           read=_friction_read(lambda f: {"viscous_asymmetry.ratio": f.sigma_asym},
                               lambda f: f.sigma > 0 and f.sigma_asym != 0, coulomb=False)),
    Effect("load_dependent_friction", "friction levels growing with the torque the gear transmits, "
           "(Fc + g |T| / N) sgn(w)",
           (Param("load_dependent_friction.gain", 0.05, 0.0, 0.9, log=False),),
           lambda m, v: _set_friction(m, load_gain=v["load_dependent_friction.gain"]),
           requires=("coulomb_friction",),
           evidence=("coulomb", "sin_theta"), plot="motor_velocity", term="friction",
           read=_friction_read(lambda f: {"load_dependent_friction.gain": f.load_gain},
                               lambda f: getattr(f, "load_gain", 0.0) > 0)),
    # No parameter: the exact sign is a form of the Coulomb term. Screened on request or where the
    # base creeps through the recording's rests (diagnosis.rests), not on every recording: with no
    # parameter it wins every tie with 2SEP by parsimony, where 2SEP refitted can predict far
    # better (docs/diagnosis.md, "Model structures").
    Effect("sticking_friction", "dry motor friction that holds the rotor at rest up to its break-away "
           "level: sgn(w) exact, where the base's is regularised over v_eps and the rotor creeps",
           (), lambda m, v: _set_friction(m, v_eps=0.0), requires=("coulomb_friction",),
           excludes=("dynamic_friction",), evidence=(*MOTOR_SIGN, "rotor_holds"), plot="motor_velocity",
           # a base whose rotor creeps through the rests slows it with the link's drag, the gear's
           # damper and the gravity that loads it: a screen holding those misses the hold
           stand_ins=("load_friction", "transmission_damping", "gravity"), direct_drive=True,
           term="friction", on_request=True,
           read=_friction_read(lambda f: {FRICTION_V_EPS: 0.0},
                               lambda f: isinstance(f, StaticFriction) and f.v_eps == 0.0)),
    Effect("load_friction", "output bearing friction Fc sgn(theta') + d_f theta'",
           (Param("load_friction.fc", 0.1, 1e-4, 50.0, unit="N m"),
            # a bearing of negligible viscous drag still holds its Coulomb level
            Param("load_friction.viscous", 0.01, 1e-5, 10.0, unit="N m s/rad", lo_physical=True)),
           _load, site="link", evidence=("coulomb", "viscous", "reversal"), plot="link_velocity",
           term="load_friction",
           read=lambda m: _when(m[1].load_friction, lambda lf: {"load_friction.fc": lf.fc,
                                                                 "load_friction.viscous": lf.viscous})),
    Effect("gravity", "gravity torque of the link, l g sin(theta) (Eq. 9)",
           (Param("gravity.g", 9.81, 0.1, 50.0, unit="m/s^2", scale_free=True),),
           lambda m, v: _arm(m, gravity=v["gravity.g"]), site="link",
           evidence=("sin_theta", "cos_theta"), plot="sin_theta",
           read=lambda m: _arm_value(m, "gravity", "gravity.g")),
    Effect("linear_stiffness", "elastic gear: torsional spring K delta (Eq. 3)",
           (Param("linear_stiffness.k1", 1e4, 1e2, 1e7, unit="N m/rad"),),
           lambda m, v: _set_transmission(m, k1=v["linear_stiffness.k1"], damping=0.0), site="gear",
           evidence=("delta", "resonance"), plot="loops",
           term="transmission", read=term_values("transmission", {"linear_stiffness.k1": "k1"})),
    Effect("nonlinear_stiffness", "hardening gear stiffness, k3 delta^3 (Eq. 16)",
           (Param("nonlinear_stiffness.k3", 1e8, 1e4, 1e13, unit="N m/rad^3"),),
           lambda m, v: _set_transmission(m, k3=v["nonlinear_stiffness.k3"]),
           requires=("linear_stiffness",), site="gear", evidence=("delta",), plot="loops",
           term="transmission", read=term_values("transmission", {"nonlinear_stiffness.k3": "k3"})),
    Effect("transmission_hysteresis", "Bouc-Wen hysteretic (elasto-plastic) gear stiffness (Eqs. 16-17)",
           (Param("transmission_hysteresis.mu", 0.6, 0.02, 0.98, log=False),
            Param("transmission_hysteresis.x_u", 2e-3, 1e-6, 0.1, unit="rad")),
           _hysteresis, requires=("linear_stiffness",), site="gear",
           evidence=("hysteresis", "small_delta"), plot="loops", term="hysteresis",
           variants=_tried(HYSTERESIS_SHAPE, HYSTERESIS_SHAPES), read=_read_hysteresis),
    Effect("transmission_damping", "viscous damping in the gear, D delta' (Eq. 18)",
           (Param("transmission_damping.d", 1.0, 1e-3, 1e3, unit="N m s/rad"),),
           lambda m, v: _set_transmission(m, damping=v["transmission_damping.d"]),
           requires=("linear_stiffness",), site="gear", evidence=("resonance",), plot="loops",
           term="transmission", read=term_values("transmission", {"transmission_damping.d": "damping"})),
    # While the teeth are apart the link moves under its bearing and gravity alone: a fit whose gear
    # never opens bends those to the play's absence, and a screen holding them misses the play.
    Effect("backlash", "play in the gear: dead zone of the deflection (Fig. 3 (a))",
           (Param("backlash.width", 1e-4, 1e-7, 1e-2, unit="rad"),),
           lambda m, v: _set_transmission(m, backlash=v["backlash.width"]),
           requires=("linear_stiffness",), site="gear", evidence=("small_delta", "reversal"), plot="loops",
           variants=_play_variants, term="transmission", stand_ins=("load_friction", "gravity"),
           read=term_values("transmission", {"backlash.width": "backlash"})),
    Effect("torque_ripple", "position-periodic motor torque (cogging / eccentricity)",
           (Param("torque_ripple.a", 0.0, -2.0, 2.0, log=False, unit="N m", dim="force"),
            Param("torque_ripple.b", 0.0, -2.0, 2.0, log=False, unit="N m", dim="force")),
           _ripple, evidence=("periodic_q",), plot="motor_revolution", variants=_ripple_variants,
           term="ripple", read=lambda m: _when(m[1].ripple, _read_ripple)),
    # A rod's own damping is as unknown as its stiffness: fixed, it leaves a mode's decay to be
    # taken up by whatever other dissipation a candidate brings.
    Effect("link_flexibility", "bending of the link rod (distributed mass-spring, Fig. 5 (b))",
           (Param("link_flexibility.ei", 500.0, 1.0, 1e6, unit="N m^2"),
            Param("link_flexibility.beta", ROD_BETA, 1e-7, 1e-2, unit="s", lo_physical=True)),
           _flexibility, site="link",
           evidence=("resonance",), plot="spectrum", stand_ins=("linear_stiffness", "transmission_damping"),
           variants=_flexibility_variants, read=_read_flexibility, step_resolved=False, mode_hz=_rod_mode_hz),
    Effect("input_delay", "dead time between commanded and applied motor torque",
           (Param("input_delay.delay", 1e-3, 0.0, 0.01, log=False, unit="s"),),
           lambda m, v: _arm(m, input_delay=v["input_delay.delay"]),
           evidence=("lag",), plot="time_shift", direct_drive=True,
           variants=_at_located_lag("input_delay.delay", 0.009),
           read=lambda m: _arm_value(m, "input_delay", "input_delay.delay")),
    # A dead time and a first-order lag of the same time shift differ in how they round the
    # input's fast changes: a current loop's lag taken as a delay leaves a residual that other
    # terms (a direction-dependent friction) take up.
    Effect("input_lag", "first-order lag of the applied motor torque behind its command "
           "(a current loop's bandwidth), tau du/dt = u_cmd - u",
           # Linear from (almost) no lag, as the delay: a screen with no lag to find descends to
           # the base model there, where on a log scale its gradient vanishes on the way.
           (Param("input_lag.tau", 1e-3, 1e-6, 0.05, log=False, unit="s"),),
           lambda m, v: _arm(m, input_lag=v["input_lag.tau"]),
           evidence=("lag",), plot="time_shift", direct_drive=True,
           variants=_at_located_lag("input_lag.tau", 0.045),
           read=lambda m: _arm_value(m, "input_lag", "input_lag.tau")),
    Effect("input_offset", "constant bias of the applied motor torque (amplifier or sensor offset)",
           (Param("input_offset.offset", 0.0, -1.0, 1.0, log=False, unit="N m", dim="force"),),
           lambda m, v: _arm(m, input_offset=v["input_offset.offset"]),
           # a constant force reads as one sign of friction half the time, and is seen against velocity
           evidence=("coulomb",), plot="motor_velocity", direct_drive=True,
           read=lambda m: _arm_value(m, "input_offset", "input_offset.offset")),
    # A late link encoder reads as a lagging gear: a base fit without the skew bends the gear's
    # stiffness and damping toward it, and a screen holding them misses the skew.
    Effect("sensor_skew", "the link encoder read late against the motor encoder and input (time skew)",
           (Param("sensor_skew.lag", 0.0, -0.01, 0.01, log=False, unit="s"),),
           lambda m, v: m, site="sensor", measure=_skewed, senses=("theta", "delta"), plot="time_shift",
           stand_ins=("linear_stiffness", "transmission_damping")),
    Effect("torque_skew", "the torque sensor read late (its filter's lag or a timing skew)",
           (Param("torque_skew.lag", 0.0, -0.01, 0.01, log=False, unit="s"),),
           lambda m, v: m, site="sensor", senses=("tau",), evidence=("lag", "energy_returned"), plot="time_shift",
           measure=lambda p, v, rate: {**p, "tau": shift_late(p["tau"], v["torque_skew.lag"] * rate)},
           on_request=True),
    # Gain before offset (effects apply in catalogue order): tau_measured = gain tau + offset.
    Effect("torque_gain", "gain error of the torque sensor (measured tau only)",
           (Param("torque_gain.gain", 1.0, 0.2, 5.0, unit=""),),
           lambda m, v: m, site="sensor", measure=lambda p, v, rate: {**p, "tau": p["tau"] * v["torque_gain.gain"]},
           senses=("tau",), plot="measured_torque", on_request=True),
    Effect("torque_offset", "constant bias of the torque sensor (measured tau only)",
           (Param("torque_offset.offset", 0.0, -100.0, 100.0, log=False, unit="N m"),),
           lambda m, v: m, site="sensor",
           measure=lambda p, v, rate: {**p, "tau": p["tau"] + v["torque_offset.offset"]}, senses=("tau",),
           plot="measured_torque", on_request=True),
    # The open vocabulary (identify.generic), then the user terms' effects (physics.catalogue).
    *GENERIC_EFFECTS,
    *(e for module in MODULES for e in getattr(module, "EFFECTS", ())),
)}

# The effects screened only when asked (``Effect.on_request``): among them the torque sensor's,
# whose gain, offset or lag can stand in for any physics that moves tau (its lag for a current
# loop's), unless the recording shows a sign of one no physics gives (``Effect.evidence``: the
# gear law giving energy back, ``diagnosis.gear_law.law_energy``). The sensors' others are
# screened where the fit scores a signal they change (``Effect.senses``,
# ``diagnosis.loop.candidates_for``).
ON_REQUEST = tuple(e.name for e in EFFECTS.values() if e.on_request)
# The generic forms: screened only where no catalogued effect explains a located residual.
GENERIC = tuple(e.name for e in EFFECTS.values() if e.generic)

# The effects a direct drive can have: no gear, no output side, no gravity on a level axis.
# Torque ripple is not one: its harmonics are per motor revolution, which a linear axis
# measured in metres does not define.
DRIVE_EFFECTS = tuple(e.name for e in EFFECTS.values() if e.direct_drive)

# Parameters of the minimal structure: inertias (the gear ratio is given, not fitted); a direct
# drive has only the one, the motor joint's (kg on a slide). The link's inertia is fitted as the
# plant says (``ArmSpec.link_parameter``): as its tip mass where it has one (payloads are what
# is uncertain, and a hub term could only ADD to the nominal link: a payload 10 % lighter than
# nominal left a concealed-case fit with the hub on its bound, g 8 % low and the stiffness 7 %
# high to match the resonance), else as hub inertia. Not both: with gravity fitted, hub, tip
# mass and g would have a direction of exactly equal inertia and gravity torque.
BASE_PARAMS = (
    Param("inertia.motor", 5e-5, 1e-7, 1e-1, unit="kg m^2", dim="inertia"),
    Param("inertia.link", 2e-3, 1e-5, 1e2, unit="kg m^2"),
    Param("mass.tip", 1.0, 1e-3, 1e3, unit="kg"),
)


def base_params(nominal: Plant) -> tuple[Param, ...]:
    if isinstance(nominal, DriveSpec):
        return BASE_PARAMS[:1]
    return BASE_PARAMS[:1] + tuple(p for p in BASE_PARAMS[1:] if p.name == nominal.link_parameter)


def plant_effects(nominal: Plant) -> tuple[str, ...]:
    """Every effect the plant can have."""
    return DRIVE_EFFECTS if isinstance(nominal, DriveSpec) else tuple(EFFECTS)

SEED_EFFECTS = ("coulomb_friction", "viscous_friction", "stribeck_friction", "dynamic_friction",
                "load_friction", "gravity", "linear_stiffness", "nonlinear_stiffness",
                "transmission_hysteresis", "transmission_damping")


def rigid_gear(arm: ArmSpec, gear_ratio: float) -> Transmission:
    """A gear as stiff as the timestep allows, critically damped: the rigid joint of Eq. (2).

    The plugin's torques are explicit, so the stiffest stable spring on the reduced inertia
    J of the two sides has sqrt(k/J) h = 0.5, and D = J/h damps it critically while D h/J = 1
    stays inside the explicit-damping limit of 2. The deflection left is ~1e-4 of a real
    gear's, and T = k delta + D delta' is the torque the rigid gear transmits. Behind the gear
    of a flexible rod is the hub alone: the segments decouple at these frequencies.
    """
    link = arm.hub_inertia if arm.segments else arm.link_inertia
    j_red = 1.0 / (1.0 / link + 1.0 / (arm.motor_inertia * gear_ratio ** 2))
    h = arm.timestep
    return Transmission(gear_ratio=gear_ratio, k1=j_red * (0.5 / h) ** 2, k3=0.0, damping=j_red / h,
                        hysteresis=None)


def minimal_model(nominal: Plant, gear_ratio: float) -> Model:
    """Rigid gear, two inertias, nothing else: the start of ``--base minimal``.

    A direct drive's minimal model is its one inertia under the input, nothing else.
    """
    if isinstance(nominal, DriveSpec):
        drive = dataclasses.replace(nominal, input_delay=0.0, input_lag=0.0, input_offset=0.0)
        return drive, drive_joint(JointParams(friction=None, ripple=None))
    arm = dataclasses.replace(nominal, segments=0, gravity=0.0, input_delay=0.0, input_lag=0.0, input_offset=0.0)
    joint = JointParams(friction=None, load_friction=None, ripple=None,
                        transmission=rigid_gear(arm, gear_ratio))
    return arm, joint


def incompatible(a: str, b: str) -> bool:
    """Whether effects ``a`` and ``b`` cannot be in one model (either's ``Effect.excludes``)."""
    return b in EFFECTS[a].excludes or a in EFFECTS[b].excludes


def check_effects(names, known: tuple[str, ...] = tuple(EFFECTS)) -> tuple[str, ...]:
    """Validate and order effect names (requirements first); unknown names fail in one line."""
    names = list(dict.fromkeys(names))
    unknown = [n for n in names if n not in known]
    if unknown:
        raise ValueError(f"unknown effect {unknown[0]!r} (known: {', '.join(known)})")
    for n in names:
        missing = [r for r in EFFECTS[n].requires if r not in names]
        if missing:
            raise ValueError(f"effect {n!r} needs {missing[0]!r} in the model as well")
        clash = [r for r in names if incompatible(n, r)]
        if clash:
            raise ValueError(f"effect {n!r} cannot be in one model with {clash[0]!r}")
    order = list(EFFECTS)
    return tuple(sorted(names, key=order.index))
