"""EMPS: the electro-mechanical positioning system benchmark (Janot, Gautier, Brunot 2019).

A real prismatic axis (DC motor, ball screw, carriage) in closed-loop position control: the
estimation file ``DATA_EMPS.mat`` and the validation file ``DATA_EMPS_PULSES.mat`` (force
pulses added). mjjoint reads it as a direct drive (``mjjoint/assets/mjcf/linear_drive.xml``): u is the
motor force gtau * vir [N], q the carriage position [m]; there is no output-side sensor.

The published reference is the inverse-dynamics least-squares (IDIM-LS) fit of
M q'' + Fv q' + Fc sgn(q') + offset = force. ``idim_relative_error`` evaluates any parameter
set with the authors' own procedure (their script ``Scrip_IDIM_LS.m``: 4th-order Butterworth
at 100 Hz, zero phase; central differences; 50 border samples dropped; MATLAB ``decimate`` by
10, i.e. an 8th-order Chebyshev I at 0.8 of the new Nyquist, zero phase), which reproduces
their 4.08 % and 5.98 % to the digit, so our numbers and theirs are on one scale.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.signal import butter, cheby1, filtfilt

from ..recordings import Recording, RecordingError, read_recording
from ..recordings.mat_io import read_mat_table
from .paths import dataset_dir

ESTIMATION = "DATA_EMPS.mat"
VALIDATION = "DATA_EMPS_PULSES.mat"
# The carriage is the drive's one joint: theta names the same column (see Measured(output=False)).
COLUMNS = {"t": "t", "u": "vir", "q": "qm", "theta": "qm"}


@dataclass(frozen=True)
class Published:
    """Janot et al. 2019, IDIM-LS on DATA_EMPS (as in the data's SOURCES.md and their script)."""

    mass: float = 95.11          # M [kg]
    viscous: float = 203.5       # Fv [N s/m]
    coulomb: float = 20.39       # Fc [N]
    offset: float = -3.16        # [N], on the friction side of their equation
    error_estimation: float = 4.08   # relative force error [%] on DATA_EMPS
    error_validation: float = 5.98   # the same model on DATA_EMPS_PULSES

    def as_vector(self) -> np.ndarray:
        return np.array([self.mass, self.viscous, self.coulomb, self.offset])


PUBLISHED = Published()


@dataclass(frozen=True)
class EmpsFile:
    recording: Recording       # u = gtau vir [N], q = theta = qm [m]
    gtau: float                # [N/V]
    reference: np.ndarray      # qg, the controller's reference [m]


def emps_path(name: str = ESTIMATION) -> Path:
    return dataset_dir("emps") / name


def read_emps(path: str | Path) -> EmpsFile:
    """One EMPS .mat file; a one-line ``RecordingError`` when it is not one."""
    path = Path(path)
    if not path.is_file():
        raise RecordingError(f"{path}: no such file")
    table = read_mat_table(path)
    missing = [k for k in ("t", "qm", "vir", "gtau", "qg") if k not in table.names]
    if missing:
        raise RecordingError(f"{path}: not an EMPS file: variable {missing[0]!r} is missing")
    gtau = np.asarray(table.column("gtau", "gtau"), float).ravel()
    if gtau.size != 1 or not np.isfinite(gtau[0]) or gtau[0] <= 0:
        raise RecordingError(f"{path}: gtau must be one positive number [N/V], got {gtau[:3]!r}")
    rec = read_recording(path, columns=COLUMNS, scales={"u": float(gtau[0])}, allow_extra=True)
    return EmpsFile(recording=rec, gtau=float(gtau[0]),
                    reference=np.asarray(table.column("qg", "qg"), float).ravel())


def _matlab_decimate(x: np.ndarray, r: int) -> np.ndarray:
    """MATLAB's decimate(x, r): Chebyshev I (8, 0.05 dB, 0.8/r) both ways, last sample kept."""
    b, a = cheby1(8, 0.05, 0.8 / r)
    y = filtfilt(b, a, x, padtype="odd", padlen=3 * (max(len(a), len(b)) - 1))
    n_out = -(-len(x) // r)
    start = r - (r * n_out - len(x)) - 1
    return y[start::r]


def idim_regressors(rec: Recording) -> tuple[np.ndarray, np.ndarray]:
    """The decimated observation matrix [q'', q', sgn q', 1, |q'|] and force, as in the authors'
    script, whose model is the first four columns; |q'| is the regressor of a direction-dependent
    viscous slope (Fv + Fa sgn q') q' (mjjoint's ``viscous_asymmetry``, ratio Fa / Fv)."""
    dt = float(rec.t[1] - rec.t[0])
    nyquist = 0.5 / dt
    b, a = butter(4, 100.0 / nyquist)
    qf = filtfilt(b, a, rec.q, padtype="odd", padlen=3 * (max(len(a), len(b)) - 1))
    v = np.gradient(qf, dt)
    acc = np.gradient(v, dt)
    border = 49  # MATLAB's q_f(50:end)
    x = np.column_stack([acc, v, np.sign(v), np.ones_like(v), np.abs(v)])[border:]
    ratio = int(round(0.8 * nyquist / 40.0))
    xd = np.column_stack([_matlab_decimate(c, ratio) for c in x.T])
    return xd, _matlab_decimate(rec.u[border:], ratio)


def idim_relative_error(rec: Recording, params: np.ndarray) -> float:
    """100 ||F - X p|| / ||F|| [%] for p = (M, Fv, Fc, offset[, Fa]) on the decimated data."""
    x, f = idim_regressors(rec)
    p = np.asarray(params, float)
    return float(100.0 * np.linalg.norm(f - x[:, :p.size] @ p) / np.linalg.norm(f))


def idim_least_squares(rec: Recording, min_speed: float = 0.0, asymmetric: bool = False) -> np.ndarray:
    """The IDIM-LS estimate (M, Fv, Fc, offset): the published method, for reference.

    ``min_speed`` > 0 [m/s] drops the decimated samples slower than it. Not the published
    method: a diagnostic of how much its parameters owe to the slow approaches to the
    reversals, where the measured friction lies below the Coulomb-plus-viscous line
    (``sliding_friction``; docs/datasets.md). ``asymmetric`` adds the fifth regressor |q'|
    and its coefficient Fa (the published method applied to the model the diagnosis finds).
    """
    x, f = idim_regressors(rec)
    keep = np.abs(x[:, 1]) >= min_speed
    cols = 5 if asymmetric else 4
    return np.linalg.lstsq(x[keep, :cols], f[keep], rcond=None)[0]


def symmetric_equivalent(rec: Recording, params: np.ndarray) -> np.ndarray:
    """(M, Fv, Fc, offset): the published (symmetric) model closest to a model ``params`` =
    (M, Fv, Fc, offset, Fa) along a recording: the least-squares projection of that model's
    force X p onto the published regressors, with the authors' filters and decimation.

    How models of different structure are compared: it is what the authors' IDIM-LS would
    estimate if the force were exactly the given model's. A model without Fa maps to itself.
    """
    x, _ = idim_regressors(rec)
    p = np.asarray(params, float)
    return np.linalg.lstsq(x[:, :4], x[:, :p.size] @ p, rcond=None)[0]


def sliding_friction(rec: Recording, mass: float, min_speed: float = 0.03,
                     max_accel: float = 0.05) -> dict[int, tuple[float, float]]:
    """Per direction (+1, -1): (slope [N s/m], level at zero speed [N]) of the friction force.

    The friction force is F - M q'' on the authors' decimated regressors, taken where the
    carriage slides steadily (|q'| >= ``min_speed``, |q''| <= ``max_accel``: the EMPS's
    constant-speed plateaus, where M barely matters), and fitted by a straight line in q'
    separately for each direction. A symmetric Coulomb-viscous model has equal slopes and
    opposite levels.
    """
    x, f = idim_regressors(rec)
    acc, v = x[:, 0], x[:, 1]
    friction = f - mass * acc
    steady = (np.abs(v) >= min_speed) & (np.abs(acc) <= max_accel)
    out = {}
    for sign in (1, -1):
        m = steady & (np.sign(v) == sign)
        if m.sum() < 2:
            raise ValueError(f"no steady sliding in direction {sign:+d} (|v| >= {min_speed}, |a| <= {max_accel})")
        slope, level = np.polyfit(v[m], friction[m], 1)
        out[sign] = (float(slope), float(level))
    return out


def published_structure(nominal):
    """The published model as an mjjoint structure (for predictions on the same footing)."""
    from ..identify.structure import Structure
    p = PUBLISHED
    return Structure.create(("coulomb_friction", "viscous_friction", "input_offset"), nominal, 1.0, {
        "inertia.motor": p.mass, "viscous_friction.sigma": p.viscous, "coulomb_friction.fc": p.coulomb,
        "input_offset.offset": -p.offset})


def equivalent_parameters(structure) -> np.ndarray:
    """(M, Fv, Fc, offset, Fa) of a fitted structure in the terms of ``idim_regressors``.

    A constant input offset o is the published offset -o; friction asymmetry a (the levels
    shifted by a in the direction of motion) is the same force as an offset a while the axis
    moves, which the EMPS does 99 % of the time. Fa = Fv r for a viscous asymmetry r (0 without
    one; the published model has none). Terms neither model has are left out.
    """
    v = structure.values
    fc = v.get("coulomb_friction.fc", 0.0)
    sigma = v.get("viscous_friction.sigma", 0.0)
    offset = -v.get("input_offset.offset", 0.0) + fc * v.get("friction_asymmetry.ratio", 0.0)
    return np.array([v["inertia.motor"], sigma, fc, offset, sigma * v.get("viscous_asymmetry.ratio", 0.0)])
