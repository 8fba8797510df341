"""Run one concealed case blind and score the result against the hidden truth."""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..diagnosis.loop import DiagnoseOptions, diagnose
from ..identify.effects import EFFECTS
from ..identify.fit import evaluate
from ..identify.structure import Structure
from ..identify.windows import Measured, Predictor, WindowDesign
from ..recordings import Recording, read_recording, write_recording
from .cases import CONCEALED, GEAR_RATIO, NOMINAL, Case, make_case
from ..rehearse import LabProgram, record
from ..rehearse.sensors import Sensors, quantise


@dataclass
class Score:
    case: str
    seed: int
    named: bool              # the hidden effect, or a rival the tool reported indistinguishable from it
    false_additions: list[str]
    signal: str
    nrmse_before: float
    nrmse_after: float
    parameter: str | None
    truth: float | None
    fitted: float | None
    rollouts: float
    seconds: float
    # The hidden truth's own held-out NRMSE of `signal` on the same windows: what a perfect
    # diagnosis would reach (sensor noise and window-start estimates set this floor).
    nrmse_truth: float | None = None

    @property
    def reduction(self) -> float:
        return 1.0 - self.nrmse_after / self.nrmse_before if self.nrmse_before > 0 else 0.0

    @property
    def parameter_error(self) -> float | None:
        if self.truth is None or self.fitted is None:
            return None
        return abs(self.fitted - self.truth) / abs(self.truth)

    @property
    def passed(self) -> bool:
        if self.case == "none":
            return not self.false_additions
        err = self.parameter_error
        return (self.named and not self.false_additions and self.reduction >= 0.5
                and err is not None and err <= 0.2)


def write_case_recording(case: Case, folder: Path, duration: float, timestep: float | None = None) -> Path:
    """Simulate the truth in closed loop and write ONLY the recording CSV the tool will see;
    ``timestep``: the truth's step [s] where not its model's own (a finer one stands for physics
    that has none)."""
    arm, joint = case.truth.model_params()
    if timestep is not None:
        arm = dataclasses.replace(arm, timestep=timestep)
    program = LabProgram(duration=duration, seed=case.seed)
    if any(EFFECTS[e].measure is not None for e in case.truth.effects):
        cols = _sensed(case, record(arm, joint, program, sensors=Sensors(encoder_bits=0, torque_noise=0.0)))
    else:
        cols = record(arm, joint, program)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "recording.csv"
    write_recording(path, Recording(t=cols["t"], u=cols["u"], q=cols["q"], theta=cols["theta"],
                                    tau=cols["tau"], gear_ratio=GEAR_RATIO, meta={}))
    return path


def _sensed(case: Case, cols: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Ideal link and torque readings as the truth's sensor effects and then the lab's sensors
    (``Sensors()``: the link encoder's counts, the torque cell's noise) log them. The loop is
    closed on the motor angle, which no sensor effect touches, so the run is the one logged."""
    lab = Sensors()
    rate = 1.0 / float(cols["t"][1] - cols["t"][0])
    seen = case.truth.measured({**cols, "delta": cols["q"] / GEAR_RATIO - cols["theta"]}, rate)
    rng = np.random.default_rng(case.seed)
    return {**cols, "theta": quantise(seen["theta"], lab.encoder_bits),
            "tau": seen["tau"] + rng.normal(0.0, lab.torque_noise, len(cols["tau"]))}


def _fitted_value(case: Case, structure: Structure) -> float | None:
    name = CONCEALED[case.effect][0]
    v = structure.values
    if name == "friction_asymmetry.ratio" and name not in v and "input_offset.offset" in v:
        # Named as its rival: an offset o is the asymmetry -o while the motor moves.
        return -float(v["input_offset.offset"]) / float(v["coulomb_friction.fc"])
    if name is None or not all(k in v for k in _needed(name)):
        return None
    if name == "torque_ripple.amplitude":
        return float(np.hypot(structure.values["torque_ripple.a"], structure.values["torque_ripple.b"]))
    if name == "gravity.g":  # compare gravity torques: the truth's tip mass differs from nominal
        mass = float(structure.values.get("mass.tip", NOMINAL.tip_mass))
        return float(structure.values["gravity.g"]) * mass / case.truth.nominal.tip_mass
    return float(structure.values[name])


def _needed(name: str) -> tuple[str, ...]:
    return ("torque_ripple.a", "torque_ripple.b") if name == "torque_ripple.amplitude" else (name,)


def run_case(effect: str, seed: int, folder: Path, duration: float = 20.0,
             options: DiagnoseOptions = DiagnoseOptions(), progress=None) -> Score:
    case = make_case(effect, seed)
    path = write_case_recording(case, folder, duration)
    start = time.perf_counter()
    rec = read_recording(path, gear_ratio=GEAR_RATIO)  # the tool's only input, with the base list
    predictor = Predictor(Measured.from_recording(rec, GEAR_RATIO), WindowDesign(seed=seed))
    base = Structure.create(case.base_effects, NOMINAL, GEAR_RATIO)
    diag = diagnose(predictor, base, options, progress)
    seconds = time.perf_counter() - start
    signal = max(diag.initial.nrmse_test, key=diag.initial.nrmse_test.get)
    # A step that names a rival the data cannot tell from the hidden effect names it, honestly
    # hedged ("input_offset, or indistinguishable here, friction_asymmetry").
    found = {st.effect for st in diag.steps if st.effect == effect or effect in st.alternatives}
    return Score(case=effect, seed=seed, named=bool(found),
                 false_additions=[m for m in diag.missing if m not in found], signal=signal,
                 nrmse_before=diag.initial.nrmse_test[signal], nrmse_after=diag.final.nrmse_test[signal],
                 parameter=CONCEALED[effect][0], truth=case.truth_value(),
                 fitted=_fitted_value(case, diag.final.structure), rollouts=diag.rollouts, seconds=seconds,
                 nrmse_truth=evaluate(predictor, case.truth)[3][signal])  # scoring only, after the run
