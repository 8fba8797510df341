"""What ``fit`` and ``diagnose`` work on: a recording's prediction windows and a starting structure.

``load_problem`` reads the recording (or takes one already read), builds the starting structure
from effect names or a model file (its terms mapped onto effects, its values as initial values),
and gives a ``Problem``; a multi-joint recording gives ``JointProblems``, one single-joint
problem per selected joint, each from that joint's starting model (``[[joint]]`` model files:
``assets.joint_view``), loaded, given ``Inputs.arm``, by the other joints' measured motion
(``manipulator``). The command line and the Python API (``mjjoint.fit``,
``mjjoint.diagnose``) both build their problems here; ``names`` lets each name its own inputs
in the one-line ``ValueError`` messages (``gear_ratio`` or ``--gear-ratio``).
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from .assets import ArmSpec, DriveSpec
from .assets.joint_view import single_joint_models
from .assets.plant import input_range
from .assets.serial_file import SerialArmFile, read_model_file
from .identify.effects import FRICTION_V_EPS, SEED_EFFECTS, base_params, check_effects, plant_effects, plant_v_eps
from .identify.from_model import stated, structure_from_model
from .identify.initial import ARM_SLOPE_STEP, SLOPE_STEP, Estimate, estimate
from .identify.structure import Structure
from .identify.windows import Measured, Predictor, WindowDesign, stable
from .manipulator import arm_model, arm_predictor, load_note
from .modelfile import ModelFile
from .params import fitting_timestep
from .recordings import MultiRecording, Recording, read_recording, reading_notes
from .recordings.consistency import (dead_sensor_problem, gear_sides_problem, motion_problem, scale_problem,
                                     torque_sign_problem)

PLANTS = {"arm": "", "linear": "slide", "rotary": "hinge"}  # plant -> direct drive joint type ("": the arm)


@dataclass
class Problem:
    """One joint's recording as prediction windows, and the structure to start from."""

    source: str
    predictor: Predictor
    base: Structure
    notes: list[str]


@dataclass
class JointProblems:
    """A multi-joint recording: one ``Problem`` per selected joint (numbered from 1)."""

    source: str
    problems: dict[int, Problem]
    notes: list[str] = field(default_factory=list)
    arm: str | None = None  # the arm whose other joints' measured motion loads each joint (``Inputs.arm``)


@dataclass(frozen=True)
class Inputs:
    """How to read a recording and where to start; ``None`` where the recording or model gives it.

    A value per joint (``gear_ratio``, ``k_m``) is one number for every joint or a tuple of one
    per joint of a multi-joint recording. ``base``: effect names (``()``: the minimal model;
    ``None``: the seed paper's full joint) and/or ``model`` (a model file or its path: its arm,
    and its terms as effects unless ``base`` lists the effects).
    ``columns``, ``scales`` and ``allow_gaps`` apply when the recording is a path. Every plant
    starts from initial values and ranges estimated from the recording (``identify.initial``);
    a model file's values are the user's and stay.
    """

    gear_ratio: float | tuple[float, ...] | None = None
    k_m: float | tuple[float, ...] | None = None
    base: tuple[str, ...] | None = None
    model: ModelFile | SerialArmFile | str | Path | None = None
    plant: str = "arm"
    joints: tuple[int, ...] | None = None
    design: WindowDesign = WindowDesign()
    columns: Mapping[str, str] | None = None
    scales: Mapping[str, float] | None = None
    allow_gaps: bool = False
    fit_signals: tuple[str, ...] | None = None  # the signals the cost scores (q, delta, tau); None: all recorded
    # The arm (a [[joint]] model file or an MJCF of it): each joint's other joints' measured motion
    # loads it through MuJoCo's multibody dynamics (``manipulator``); None: each joint alone.
    arm: SerialArmFile | str | Path | None = None


def check_inputs(inputs: Inputs, names: Mapping[str, str] | None = None) -> None:
    """The checks of ``inputs`` that need no recording and no model file (one-line ValueError
    naming the input as ``names`` calls it): a fleet's rows are checked so before any work."""
    say = _Names(names or {})
    for key in ("gear_ratio", "k_m"):
        value = getattr(inputs, key)
        for v in value if isinstance(value, tuple) else (value,):
            if v is not None and not 0 < v < math.inf:
                raise ValueError(f"{say(key)} {v:g} must be positive and finite")
    if inputs.joints is not None and (not inputs.joints or min(inputs.joints) < 1):
        raise ValueError(f"{say('joints')}: joints are numbered from 1, got {inputs.joints!r}")
    if inputs.plant not in PLANTS:
        raise ValueError(f"{say('plant')} {inputs.plant!r} is not one of {', '.join(PLANTS)}")
    # the arm's effects; a drive's and a model file's are checked where those are known
    if inputs.base is not None and inputs.model is None and inputs.plant == "arm":
        _effects(inputs.base, say)


def load_problem(recording: Recording | MultiRecording | str | Path | Sequence[Recording | str | Path],
                 inputs: Inputs = Inputs(), names: Mapping[str, str] | None = None) -> Problem | JointProblems:
    """The problem of ``recording`` under ``inputs``.

    Args:
        recording: a ``Recording`` (arrays of shape (n,)), a ``MultiRecording``, or the path of
            a recording file (read with ``inputs.columns``, ``scales``, ``allow_gaps``); or a
            list of single-joint recordings or paths, stacked as separate segments (no window
            spans two: ``Measured.stack``).
        inputs: how to read it and where to start (``Inputs``).
        names: how the caller names each input in messages (``{"gear_ratio": "--gear-ratio"}``);
            unnamed inputs keep their Python names.

    Returns:
        A ``Problem``, or ``JointProblems`` for a multi-joint recording (or inputs only such a
        recording takes: ``joints``, a tuple per joint, a ``[[joint]]`` model file).

    Raises:
        ValueError: in one line naming the input, for anything that does not fit.
    """
    say = _Names(names or {})
    check_inputs(inputs, names)
    if inputs.plant != "arm":
        return _drive_problem(recording, inputs, say)
    model = read_model_file(inputs.model) if isinstance(inputs.model, (str, Path)) else inputs.model
    if model is None and inputs.base is None and inputs.arm is not None:
        model = _arm_file(inputs.arm)  # a [[joint]] arm file is also where each joint starts
    if _several_joints(inputs, model):
        return _joint_problems(recording, inputs, model, say)
    notes: list[str] = []
    keep: tuple[str, ...] = ()
    if model is not None:
        base, notes, keep = _from_model(model, inputs.gear_ratio, say, inputs.base)
    else:
        if inputs.gear_ratio is None:
            raise ValueError(f"{say('gear_ratio')} N is required (or a {say('model')} file that gives it)")
        base = Structure.create(_effects(inputs.base, say), ArmSpec(), inputs.gear_ratio)
    recs = [_read(r, inputs, base.gear_ratio, inputs.k_m) for r in _each(recording)]
    if len(recs) == 1 and not isinstance(recs[0], Recording):
        return _joint_problems(recording, inputs, model, say, recs[0])
    measured = _stacked(recording, recs, base.gear_ratio, notes)
    measured, start, more = _aligned(measured, base.nominal)
    notes += more
    predictor = make_predictor(measured, inputs, say)
    return Problem(_source(recording), predictor, _started(base, measured, start, keep), notes)


def _aligned(measured: Measured, nominal) -> tuple[Measured, Estimate, list[str]]:
    """The recording's estimate (``identify.initial``), and the recording with its link encoder
    counted from the motor's zero where the two differ (``initial.encoder_offset``), with a note."""
    start = estimate(measured, nominal)
    offset = start.theta_offset
    if not offset:
        return measured, start, []
    note = (f"the link encoder counts from another zero than the motor's: the deflection q/N - theta reads "
            f"{offset:.4g} rad at zero gear torque, more than any torque recorded explains; theta taken {offset:+.4g} rad")
    return dataclasses.replace(measured, theta=measured.theta + offset), start, [note]


def _started(base: Structure, measured: Measured, start: Estimate, keep: tuple[str, ...]) -> Structure:
    """``base`` with ranges and initial values from the recording (``start``: its ``identify.initial``
    estimate); the values named in ``keep`` (a model file's) are the user's and stay."""
    stepped = base.at_timestep(fitting_timestep(measured.rate, base.nominal.timestep))
    started = regularised(stepped.started(start, keep=keep), start)
    try:
        started.model_params()
    except ValueError as err:  # a fit from there would score nothing but unstable predictions
        raise ValueError(f"the model started from the recording's estimates is one the simulator refuses: {err}") from None
    return _stable_start(started, stepped, keep)


def _stable_start(started: Structure, nominal: Structure, keep: tuple[str, ...]) -> Structure:
    """``started``, or where its values are too stiff for its step (a regression misled by an
    excitation it cannot read: a rotor inertia a decade below what moves), ``started`` with the
    first of the recording's values that does so set back to the ``nominal`` one: a fit from an
    unstable start scores nothing but refused predictions, and cannot move from there. The
    user's values (``keep``) stay; a start no single value makes unstable is left to the fit."""
    if stable(started):
        return started
    for name, value in started.values.items():
        if name not in keep and value != nominal.values.get(name, value):
            trial = started.with_values({name: nominal.values[name]})
            if stable(trial):
                return trial
    return started


def make_predictor(measured: Measured, inputs: Inputs, say=str) -> Predictor:
    """The windowed predictor scoring ``inputs.fit_signals``, each one recorded (``say``: an
    input's name in messages)."""
    signals = inputs.fit_signals
    missing = [s for s in signals or () if getattr(measured, s) is None]
    if missing:
        raise ValueError(f"{say('fit_signals')}: the recording has no {missing[0]} (for this plant)")
    if "delta" in (signals or ()) and not measured.link_encoder:
        raise ValueError(f"{say('fit_signals')}: theta is q/N, one encoder's angle, so the deflection is not "
                         "measured: score q alone")
    return Predictor(measured, inputs.design, fit_signals=signals)


def drive_structure(effects, joint_type: str, measured: Measured) -> Structure:
    """A direct drive's starting structure, its size from the recording (``identify.initial``),
    not from the shipped (EMPS) DriveSpec."""
    start = estimate(measured)
    # The recorded force is what was applied: the amplifier's limit must not clip it.
    limit = input_range(measured.u, DriveSpec.k_m, DriveSpec.ctrl_limit)
    h = fitting_timestep(measured.rate, DriveSpec.timestep)
    nominal = DriveSpec(joint_type=joint_type, ctrl_limit=limit, timestep=h)
    return regularised(Structure.create(effects, nominal, 1.0, start=start), start)


def regularised(structure: Structure, start: Estimate) -> Structure:
    """``structure`` with the motor friction's sign regularisation the recording's estimate needs
    for a stable explicit step (``Estimate.v_eps``) where the plant's is too narrow; one the
    structure already sets (a model file's) stays."""
    default = plant_v_eps(structure.nominal)
    arm = isinstance(structure.nominal, ArmSpec)
    v_eps = start.v_eps(structure.nominal.timestep, default, ARM_SLOPE_STEP if arm else SLOPE_STEP)
    if FRICTION_V_EPS in structure.settings or v_eps == default:
        return structure
    return dataclasses.replace(structure, settings={**structure.settings, FRICTION_V_EPS: v_eps})


def _each(recording) -> list:
    """The recordings given: one, or each of a list."""
    return list(recording) if isinstance(recording, (list, tuple)) else [recording]


def _stacked(recording, recs: list, gear_ratio: float, notes: list[str], output: bool = True) -> Measured:
    """The recordings on one time line, each its own segment (``Measured.stack``); what
    reading did to them (rows dropped, resampling) reported in ``notes``."""
    several = len(recs) > 1
    for given, rec in zip(_each(recording), recs):
        if not isinstance(rec, Recording):
            raise ValueError(f"{_source(given)}: holds several joints; only single-joint recordings are stacked "
                             "(give a multi-joint recording alone)")
        notes += [f"{_source(given)}: " * several + note for note in reading_notes(rec.meta)]
    parts = [Measured.from_recording(rec, gear_ratio, output=output) for rec in recs]
    for given, part in zip(_each(recording), parts):
        _check_conventions(part, _source(given))
    return parts[0] if not several else Measured.stack(parts)


def _check_conventions(measured: Measured, source: str) -> None:
    """Refuse, in one line, a recording whose motor does not move, whose sensor recorded nothing,
    or whose angles or torques are not read as the model takes them (``recordings.consistency``)."""
    m = measured
    problem = scale_problem("q", m.q) or scale_problem("u", m.u) or motion_problem(m.q)
    if problem is None and m.theta is not None:
        problem = dead_sensor_problem("theta", m.theta) or gear_sides_problem(m.q, m.theta, m.gear_ratio)
    if problem is None and m.tau is not None:
        problem = dead_sensor_problem("tau", m.tau) or torque_sign_problem(m.u, m.q, m.theta, m.tau, m.gear_ratio,
                                                                           m.rate)
    elif problem is None and m.theta is None:  # a direct drive: u alone works on the rotor
        problem = torque_sign_problem(m.u, m.q, None, None, 1.0, m.rate)
    if problem is not None:
        raise ValueError(f"{source}: {problem}")


class _Names:
    """An input's name in messages: as the caller spells it, else its Python name."""

    def __init__(self, names: Mapping[str, str]):
        self.names = names

    def __call__(self, key: str) -> str:
        return self.names.get(key, key)


def _source(recording) -> str:
    if isinstance(recording, (list, tuple)):
        return ", ".join(_source(r) for r in recording)
    return str(recording) if isinstance(recording, (str, Path)) else "the recording"


def _read(recording, inputs: Inputs, gear_ratio: float | None, k_m: float | None) -> Recording | MultiRecording:
    """The recording as given, or read from its path with the column map and scales."""
    if isinstance(recording, (Recording, MultiRecording)):
        if k_m is None:
            return recording
        if isinstance(recording, Recording):
            return recording.with_columns(u=recording.u * k_m)
        return MultiRecording(tuple(r.with_columns(u=r.u * k_m) for r in recording.joints), recording.meta)
    return read_recording(recording, columns=inputs.columns, scales=inputs.scales, gear_ratio=gear_ratio,
                          k_m=k_m, allow_gaps=inputs.allow_gaps)


def _effects(base: tuple[str, ...] | None, say, known: tuple[str, ...] | None = None) -> tuple[str, ...]:
    """The starting effects (``None``: the seed paper's full joint), prerequisites checked."""
    if base is None:
        return SEED_EFFECTS
    try:
        return check_effects(base, *(() if known is None else (known,)))
    except ValueError as exc:
        raise ValueError(f"{say('base')}: {exc}") from None


def _from_model(model: ModelFile, gear_ratio: float | None, say, base: tuple[str, ...] | None = None
                ) -> tuple[Structure, list[str], tuple[str, ...]]:
    """The model file's structure, notes on it, and the names of the values that are the user's
    (``base``: only its effects, only the values the file states for them, and the arm's inertias)."""
    effects = None if base is None else _effects(base, say)
    structure, notes = structure_from_model(model, gear_ratio, effects=effects, model_name=say("model"),
                                            gear_name=say("gear_ratio"))
    if effects is None:
        return structure, notes, tuple(structure.values)
    return structure, notes, (*stated(model, effects)[1], *(p.name for p in base_params(structure.nominal)))


def _drive_problem(recording, inputs: Inputs, say) -> Problem:
    """A direct drive (plant linear or rotary): its inertia, then the effects listed."""
    if inputs.model is not None or inputs.arm is not None:
        given = say("model") if inputs.model is not None else say("arm")
        raise ValueError(f"{say('plant')} {inputs.plant}: a direct drive starts from {say('base')}; "
                         f"{given} does not apply")
    effects = () if inputs.base is None else _effects(inputs.base, say, plant_effects(DriveSpec()))
    recs = [_read(r, inputs, 1.0, inputs.k_m) for r in _each(recording)]
    if not all(isinstance(rec, Recording) for rec in recs):
        raise ValueError(f"{say('plant')} {inputs.plant} takes single-joint recordings")
    if any(rec.tau is not None for rec in recs):
        raise ValueError(f"{say('plant')} {inputs.plant}: a direct drive has no gear, so no transmission torque: "
                         "leave the tau column out")
    notes: list[str] = []
    measured = _stacked(recording, recs, 1.0, notes, output=False)
    base = drive_structure(effects, PLANTS[inputs.plant], measured)
    return Problem(_source(recording), make_predictor(measured, inputs, say), base, notes)


# ---- multi-joint recordings ----------------------------------------------------------------

def _several_joints(inputs: Inputs, model) -> bool:
    """Whether the inputs alone say the recording has several joints."""
    return (inputs.joints is not None or isinstance(model, SerialArmFile) or inputs.arm is not None
            or isinstance(inputs.gear_ratio, tuple) or isinstance(inputs.k_m, tuple))


def _one_per_joint(key: str, value, n: int, say) -> list:
    """One value per joint from an input given once for all joints or as a tuple of n."""
    if not isinstance(value, tuple):
        return [value] * n
    if len(value) != n:
        raise ValueError(f"{say(key)} gives {len(value)} values; the recording holds {n} joints "
                         "(give one value for all, or one per joint)")
    return list(value)


def _joint_problems(recording, inputs: Inputs, model, say, rec: Recording | MultiRecording | None = None
                    ) -> JointProblems:
    """The selected joints' single-joint problems (one-line errors naming the joint); ``rec``: the
    recording when already read."""
    source = _source(recording)
    if len(_each(recording)) > 1:
        raise ValueError("several recordings are stacked only when each holds one joint; "
                         f"{say('joints')}, lists of values and [[joint]] model files take one multi-joint recording")
    if rec is None:
        rec = _read(recording, inputs, None, None if isinstance(inputs.k_m, tuple) else inputs.k_m)
    if isinstance(rec, MultiRecording) and isinstance(inputs.k_m, tuple):
        ks = _one_per_joint("k_m", inputs.k_m, rec.n_joints, say)
        rec = MultiRecording(tuple(r.with_columns(u=r.u * k) for r, k in zip(rec.joints, ks)), rec.meta)
    if not isinstance(rec, MultiRecording):
        raise ValueError(f"{source}: holds one joint (columns t,u,q,theta); {say('joints')}, lists of values "
                         "and [[joint]] model files are for multi-joint recordings (columns u1,q1,theta1,...)")
    n = rec.n_joints
    joints = inputs.joints or tuple(range(1, n + 1))
    if max(joints) > n:
        raise ValueError(f"{say('joints')} {max(joints)}: {source} holds {n} joints (1-{n})")
    arm = None if inputs.arm is None else arm_model(inputs.arm, n, say("arm"))
    bases, keeps, notes = _starting_models(inputs, model, n, say)
    problems = {}
    for j in joints:
        base = bases[j - 1]
        try:
            measured = Measured.from_recording(rec.joint(j), base.gear_ratio)
            _check_conventions(measured, "the recording")
            measured, start, more = _aligned(measured, base.nominal)
            notes += [(j, m) for m in more]
            predictor = make_predictor(measured, inputs, say)
            started = _started(base, measured, start, keeps[j - 1])
            if arm is not None:
                predictor = arm_predictor(measured, started, _arm_file(inputs.arm), arm, rec, j, inputs.design,
                                          inputs.fit_signals, _arm_name(inputs.arm))
                notes.append((j, load_note(predictor)))
        except ValueError as exc:
            raise ValueError(f"joint {j}: {exc}") from None
        problems[j] = Problem(f"{source} joint {j}", predictor, started, [])
    return JointProblems(source, problems, [f"joint {j}: {m}" for j, m in notes if j in joints],
                         None if arm is None else _arm_name(inputs.arm))


def _arm_name(arm) -> str:
    """The arm as messages name it: its path, or "the arm model" when given as an object."""
    return str(arm) if isinstance(arm, (str, Path)) else "the arm model"


def _arm_file(arm) -> SerialArmFile | None:
    """The arm's [[joint]] model file, read, or None (an MJCF; errors are ``arm_model``'s)."""
    if isinstance(arm, SerialArmFile):
        return arm
    path = Path(arm)
    if path.suffix.lower() not in (".toml", ".yaml", ".yml") or not path.is_file():
        return None
    found = read_model_file(path)
    return found if isinstance(found, SerialArmFile) else None


def _starting_models(inputs: Inputs, model, n: int, say
                     ) -> tuple[list[Structure], list[tuple[str, ...]], list[tuple[int, str]]]:
    """Each joint's starting structure, the names of its values that are the user's, and
    (joint, note) pairs on what a model file could not hold."""
    gears = _one_per_joint("gear_ratio", inputs.gear_ratio, n, say)
    if model is None:
        if any(g is None for g in gears):
            raise ValueError(f"{say('gear_ratio')} N[,M...] is required (or a {say('model')} file that gives it)")
        effects = _effects(inputs.base, say)
        return [Structure.create(effects, ArmSpec(), g) for g in gears], [()] * n, []
    if isinstance(model, SerialArmFile):
        if len(model.joints) != n:
            raise ValueError(f"{say('model')} describes {len(model.joints)} joints; the recording holds {n}")
        views = single_joint_models(model)
    else:
        views = [(model, [])] * n  # one single-joint model for every joint
    bases, keeps, notes = [], [], []
    for j, ((single, view_notes), gear) in enumerate(zip(views, gears), start=1):
        try:
            base, more, keep = _from_model(single, gear, say, inputs.base)
        except ValueError as exc:
            raise ValueError(f"joint {j}: {exc}") from None
        bases.append(base)
        keeps.append(keep)
        notes += [(j, m) for m in view_notes + more]
    return bases, keeps, notes
