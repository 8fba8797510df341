"""KUKA KR300 R2500 ultra recordings (Weigand et al., IROS 2021) as single-joint recordings.

Source: public repository JonasWeigand/Robot_Identification, ``data/`` (MIT); fields and units
in ``shared/data/SOURCES.md``. Each ``data_FF_*.mat`` holds struct ``rec`` (6 x 2501 rows,
250 Hz): motor position already converted to the link side and secondary-encoder (link)
position [deg], motor torque [N m, motor side]; the authors' rigid-body model torques along
the reference trajectory (``m_all`` = M_ii; ``tau_a_all``, ``tau_c_all``, ``tau_g_all`` =
inertia coupling from the other axes, Coriolis/centrifugal, gravity with the axis-2 hydraulic
counterbalance, read from how their ``FFSingleAxis`` adds them to M_ii q''; ``tau_ff_all`` =
their feed-forward motor torque, motor side); and
struct ``para``, their identified values per axis (link side).

Conventions of the returned ``Recording`` (mjjoint's): q = gear ratio x motor position
[rad, before the gear]; theta = link position [rad]; u = motor torque [N m, motor side]. The
sign and side of u were checked on the data: u regressed on the authors' feed-forward motor
torque ``tau_ff_all`` has slope 0.86-0.97 for axes 1-3, and a link-side inverse-dynamics fit
gives the inertia (M_ii + J_mr N^2), which only a motor-side torque times N does.
No transmission torque is measured, so tau is None.

Beyond reading, this module holds what the single-joint view of this robot needs and mjjoint
does not have (see docs/datasets.md): the encoder alignment (a constant offset between the
two encoders and a timing skew of the link encoder), a link-side inverse-dynamics estimate,
the nominal ``ArmSpec`` and the torque scale into the effect catalogue's ranges.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.signal import butter, savgol_filter, sosfiltfilt

from ..assets import ArmSpec
from ..recordings import Recording, RecordingError
from ..recordings.mat_io import read_mat_table
from .paths import dataset_dir

DATASET = "kr300"
FILES = {"A": "data_FF_A.mat", "B": "data_FF_B.mat"}
LINK_ENCODER_AXES = (1, 2, 3)  # SOURCES.md: only axes 1-3 carry a secondary (link) encoder
N_AXES = 6
REC_FIELDS = ("time_cont", "act_pos_mot_deg", "act_pos_se_deg", "act_torque_abs_nm")
MODEL_FIELDS = ("m_all", "tau_a_all", "tau_c_all", "tau_g_all", "tau_ff_all")
# para fields kept per axis, with their units in the authors' (link-side) model.
PUBLISHED_UNITS = {
    "u": "-", "J_mr": "kg m^2 (motor side)", "c_rad_ff": "N m/rad", "c_rad_ode": "N m/rad",
    "q_back": "rad", "f_coul": "N m", "f_vis": "N m s/rad", "f_asym": "N m", "f_a": "N m",
    "f_b": "s/rad", "k_T": "N m/A",
}
# A period this far from the median is irregular time (float rounding of 4 ms is ~1e-15).
JITTER = 1e-6

# Every torque and inertia is divided by this for the simulator. Why: the effect catalogue's
# ranges were set for a lab joint (inertia.link <= 1e2 kg m^2, load friction <= 50 N m, ...)
# and the KR300 axis 1 has ~1.5e3 kg m^2 behind a ~5e6 N m/rad gear; scaling all torques and
# inertias alike leaves the motion, hence every prediction residual, unchanged.
MODEL_TORQUE_SCALE = 1e3
# Units of a catalogue parameter that scale with torque (inertias are torque x s^2).
_TORQUE_UNITS = ("N m", "kg m^2")


# ---- reading ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Kr300File:
    """One ``data_FF_*.mat`` file: signal rows (6 x n), the model torques and ``para``."""

    path: Path
    t: np.ndarray
    rec: dict[str, np.ndarray]
    model: dict[str, np.ndarray]
    para: dict[str, np.ndarray]

    def published(self, axis: int) -> dict[str, float]:
        """The authors' identified values for ``axis`` (units in ``PUBLISHED_UNITS``)."""
        _check_axis(self.path, axis, range(1, N_AXES + 1))
        return {k: float(v[axis - 1]) for k, v in self.para.items()}

    def recording(self, axis: int, compensate: bool = False) -> Recording:
        """Axis ``axis`` (1-3) in mjjoint's conventions, on a uniform time grid.

        ``compensate`` subtracts the authors' model torques from the other axes (inertia
        coupling, Coriolis/centrifugal, gravity; link side, divided by the gear ratio) from u,
        leaving the axis's own inertia, friction and gear to explain the motion.
        """
        _check_axis(self.path, axis, LINK_ENCODER_AXES)
        i = axis - 1
        ratio = float(self.para["u"][i])
        theta_deg = self.rec["act_pos_se_deg"][i]
        if not np.any(theta_deg):
            raise RecordingError(f"{self.path}: axis {axis} has no link-encoder signal (act_pos_se_deg is all zero)")
        u = self.rec["act_torque_abs_nm"][i]
        if compensate:
            u = u - sum(self.model[k][i] for k in ("tau_a_all", "tau_c_all", "tau_g_all")) / ratio
        t, (u, mot, theta_deg) = _uniform(self.t, [u, self.rec["act_pos_mot_deg"][i], theta_deg])
        m_ii = self.model["m_all"][i]
        meta = {"dataset": DATASET, "file": self.path.name, "axis": axis, "compensated": compensate,
                "published": self.published(axis),
                # configuration-dependent link inertia M_ii along the trajectory [kg m^2]
                "link_inertia_model": (float(m_ii.min()), float(m_ii.mean()), float(m_ii.max()))}
        return Recording(t=t, u=u, q=ratio * np.deg2rad(mot), theta=np.deg2rad(theta_deg),
                         tau=None, gear_ratio=ratio, meta=meta)


def load(path: str | Path) -> Kr300File:
    """Parse a ``data_FF_*.mat`` file; one-line RecordingError if it is missing or malformed."""
    path = Path(path)
    if not path.is_file():
        raise RecordingError(f"{path}: no such file")
    arrays = read_mat_table(path).arrays
    rec = _struct(path, arrays, "rec", REC_FIELDS)
    para = _struct(path, arrays, "para", tuple(PUBLISHED_UNITS))
    t = _vector(path, "rec.time_cont", rec["time_cont"])
    n = len(t)
    rows = {k: _rows(path, f"rec.{k}", rec[k], n) for k in REC_FIELDS[1:]}
    model = {k: _rows(path, k, _top(path, arrays, k), n) for k in MODEL_FIELDS}
    published = {k: _vector(path, f"para.{k}", para[k], N_AXES) for k in PUBLISHED_UNITS}
    if not np.all(published["u"] > 0):
        raise RecordingError(f"{path}: para.u (gear ratios) must be positive, got {published['u'].tolist()}")
    if n < 2 or not np.all(np.diff(t) > 0):
        raise RecordingError(f"{path}: rec.time_cont must increase strictly ({n} samples)")
    return Kr300File(path, t, rows, model, published)


def read_axis(path: str | Path, axis: int = 1, compensate: bool = False) -> Recording:
    """``load(path).recording(axis, compensate)``."""
    return load(path).recording(axis, compensate)


def default_file(which: str = "A") -> Path:
    """``data_FF_A.mat`` or ``data_FF_B.mat`` under the data root."""
    if which not in FILES:
        raise ValueError(f"KR300 recording {which!r} unknown; choose one of {', '.join(FILES)}")
    return dataset_dir(DATASET) / FILES[which]


def _check_axis(path: Path, axis: int, allowed) -> None:
    if axis not in allowed:
        raise RecordingError(f"{path}: axis {axis} not available; choose one of {', '.join(map(str, allowed))}")


def _top(path: Path, arrays: dict, name: str) -> np.ndarray:
    if name not in arrays:
        raise RecordingError(f"{path}: variable {name!r} missing; is this a KR300 data_FF_*.mat file?")
    return arrays[name]


def _struct(path: Path, arrays: dict, name: str, fields: tuple[str, ...]) -> dict[str, np.ndarray]:
    s = _top(path, arrays, name)
    if s.dtype.names is None or s.size != 1:
        raise RecordingError(f"{path}: variable {name!r} is not a 1x1 struct")
    missing = [f for f in fields if f not in s.dtype.names]
    if missing:
        raise RecordingError(f"{path}: struct {name!r} lacks field {missing[0]!r}")
    return {f: np.asarray(s[f].flat[0]) for f in fields}


def _numeric(path: Path, what: str, x: np.ndarray) -> np.ndarray:
    if x.dtype.kind not in "iuf":
        raise RecordingError(f"{path}: {what} is not numeric (dtype {x.dtype})")
    x = x.astype(np.float64)
    if not np.all(np.isfinite(x)):
        raise RecordingError(f"{path}: {what} holds non-finite values")
    return x


def _vector(path: Path, what: str, x: np.ndarray, n: int | None = None) -> np.ndarray:
    x = _numeric(path, what, x)
    if x.ndim != 2 or 1 not in x.shape or (n is not None and x.size != n):
        raise RecordingError(f"{path}: {what} has shape {x.shape}, expected a vector"
                             + (f" of {n} values" if n is not None else ""))
    return x.ravel()


def _rows(path: Path, what: str, x: np.ndarray, n: int) -> np.ndarray:
    x = _numeric(path, what, x)
    if x.shape != (N_AXES, n):
        raise RecordingError(f"{path}: {what} has shape {x.shape}, expected ({N_AXES}, {n})")
    return x


def _uniform(t: np.ndarray, columns: list[np.ndarray]) -> tuple[np.ndarray, list[np.ndarray]]:
    """The columns on a uniform grid of the median period (unchanged if t is uniform already)."""
    d = np.diff(t)
    dt = float(np.median(d))
    if np.max(np.abs(d - dt)) <= JITTER * dt:
        return t, columns
    grid = t[0] + dt * np.arange(math.floor((t[-1] - t[0]) / dt + 1e-9) + 1)
    return grid, [np.interp(grid, t, c) for c in columns]


# ---- encoder alignment -----------------------------------------------------------------
# Zero-phase low-pass for the quasi-static deflection fit: 8 Hz lies below the axis-1 gear
# mode (~16 Hz from para: c_rad / reduced inertia) and removes the torque's sample-to-sample
# chatter (velocity-loop noise), yet keeps the trajectories' content (< 2 Hz).
ALIGN_CUTOFF = 8.0   # [Hz]
ALIGN_EDGE = 0.1     # [s] dropped at both ends (filter transients)
# Savitzky-Golay derivatives at 250 Hz: 11 samples (44 ms) for velocity, 21 for acceleration.
VEL_WINDOW, ACC_WINDOW = 11, 21


@dataclass(frozen=True)
class Alignment:
    """Deflection model delta = offset + lag theta' + T / k, fitted by least squares.

    ``lag`` [s] is shared by the axes fitted together (one sensor bus); offsets [rad] and
    stiffnesses [N m/rad] are per axis (key: axis number). T = N u - J_mr N^2 q_m'' is the
    gear torque of a rigid motor; only the part of T not proportional to theta' (inertial,
    Coulomb) separates k from the lag.
    """

    lag: float
    offsets: dict[int, float]
    stiffness: dict[int, float]
    residual: dict[int, float]  # rms of the unexplained (low-passed) deflection / its spread


def _smooth_derivatives(rec: Recording):
    dt = rec.dt
    sos = butter(4, ALIGN_CUTOFF, fs=1.0 / dt, output="sos")
    ratio = rec.gear_ratio
    motor_link = rec.q / ratio
    thetad = savgol_filter(rec.theta, VEL_WINDOW, 3, deriv=1, delta=dt)
    motor_acc = savgol_filter(motor_link, ACC_WINDOW, 3, deriv=2, delta=dt)
    j_m = rec.meta["published"]["J_mr"]
    torque = sosfiltfilt(sos, ratio * rec.u) - j_m * ratio ** 2 * sosfiltfilt(sos, motor_acc)
    delta = sosfiltfilt(sos, motor_link - rec.theta)
    edge = round(ALIGN_EDGE / dt)
    keep = slice(edge, rec.n - edge)
    return delta[keep], thetad[keep], torque[keep]


def estimate_alignment(recs: list[Recording], with_lag: bool = True) -> Alignment:
    """Shared-lag deflection fit over recordings of different axes (``meta['axis']``).

    Use recordings WITHOUT coupling compensation: the gear carries the other axes' gravity
    and coupling torques too, so its deflection follows the motor torque N u. ``with_lag``
    False fixes the lag at 0 (offsets and stiffnesses only).
    """
    axes = [r.meta["axis"] for r in recs]
    if len(set(axes)) != len(axes):
        raise ValueError(f"one recording per axis, got axes {axes}")
    parts = [_smooth_derivatives(r) for r in recs]
    rows = sum(len(p[0]) for p in parts)
    a = np.zeros((rows, 1 + 2 * len(recs)))
    b = np.concatenate([p[0] for p in parts])
    start = 0
    for j, (delta, thetad, torque) in enumerate(parts):
        block = slice(start, start + len(delta))
        a[block, 0] = thetad
        a[block, 1 + 2 * j] = 1.0
        a[block, 2 + 2 * j] = torque
        start += len(delta)
    if not with_lag:
        a[:, 0] = 0.0  # lstsq gives a zero-column the minimum-norm coefficient, 0
    coef, *_ = np.linalg.lstsq(a, b, rcond=None)
    res = b - a @ coef
    residual, start = {}, 0
    for ax, (delta, _, _) in zip(axes, parts):
        block = slice(start, start + len(delta))
        residual[ax] = float(np.std(res[block]) / max(np.std(delta), 1e-300))
        start += len(delta)
    compliance = coef[2::2]
    return Alignment(lag=float(coef[0]), offsets={ax: float(coef[1 + 2 * j]) for j, ax in enumerate(axes)},
                     stiffness={ax: (1.0 / c if c > 0 else math.inf) for ax, c in zip(axes, compliance)},
                     residual=residual)


def align(rec: Recording, lag: float, offset: float) -> Recording:
    """The link angle read ``lag`` later and shifted by ``offset``: delta loses offset + lag theta'.

    theta(t + lag) by a cubic spline; past the end the last value is held (the recordings start
    and end at rest).
    """
    spline = CubicSpline(rec.t, rec.theta)
    theta = spline(np.clip(rec.t + lag, rec.t[0], rec.t[-1])) + offset
    meta = {**rec.meta, "link_lag": lag, "link_offset": offset}
    return Recording(t=rec.t, u=rec.u, q=rec.q, theta=theta, tau=rec.tau, gear_ratio=rec.gear_ratio, meta=meta)


# ---- inverse dynamics and the nominal model ----------------------------------------------
# Sign regularisation of the Coulomb column [rad/s, link side]: 0.01 rad/s is ~2 % of the
# trajectories' peak speed (~0.44 rad/s), so the column is a sign except near reversals.
ID_SIGN_SPEED = 0.01


@dataclass(frozen=True)
class InverseDynamics:
    """N u = J theta'' + F_v theta' + F_c sgn(theta') + c, least squares (link side).

    ``inertia`` is everything the motor torque accelerates: link plus reflected rotor
    (J_mr N^2). ``relative_error``: rms residual over the spread of N u.
    """

    inertia: float     # [kg m^2]
    viscous: float     # [N m s/rad]
    coulomb: float     # [N m]
    offset: float      # [N m]
    relative_error: float


def inverse_dynamics(rec: Recording) -> InverseDynamics:
    dt = rec.dt
    sos = butter(4, ALIGN_CUTOFF, fs=1.0 / dt, output="sos")
    thetad = savgol_filter(rec.theta, VEL_WINDOW, 3, deriv=1, delta=dt)
    thetadd = savgol_filter(rec.theta, ACC_WINDOW, 3, deriv=2, delta=dt)
    torque = sosfiltfilt(sos, rec.gear_ratio * rec.u)
    a = np.column_stack([thetadd, thetad, np.tanh(thetad / ID_SIGN_SPEED), np.ones(rec.n)])
    coef, *_ = np.linalg.lstsq(a, torque, rcond=None)
    err = torque - a @ coef
    return InverseDynamics(*map(float, coef), relative_error=float(np.std(err) / np.std(torque)))


# Rod of the nominal arm: its inertia must be positive (ArmSpec) but negligible, so the hub
# carries the link inertia that ``inertia.link`` fits. 1 g at 0.4 m is 5e-5 kg m^2 (model units).
ROD_MASS = 1e-3  # [kg]
TIMESTEP = 5e-4  # [s]: 8 steps per 4 ms sample (Predictor needs 1/(rate h) integer)


def nominal_arm(rec: Recording, link_inertia: float, scale: float = MODEL_TORQUE_SCALE) -> ArmSpec:
    """Rigid single link, gravity off, published rotor inertia; inertias in model units."""
    j_m = rec.meta["published"]["J_mr"] / scale
    rod = ArmSpec(segments=0, rod_mass=ROD_MASS, tip_mass=0.0, hub_inertia=1.0)
    hub = link_inertia / scale - (rod.link_inertia - rod.hub_inertia)
    if not hub > 0:
        raise ValueError(f"link inertia {link_inertia:g} kg m^2 is below the rod's own inertia")
    return ArmSpec(segments=0, rod_mass=ROD_MASS, tip_mass=0.0, hub_inertia=hub, motor_inertia=j_m,
                   gravity=0.0, timestep=TIMESTEP)


def to_model_units(rec: Recording, scale: float = MODEL_TORQUE_SCALE) -> Recording:
    """u (and tau) divided by ``scale``: see MODEL_TORQUE_SCALE."""
    return rec.with_columns(u=rec.u / scale, tau=None if rec.tau is None else rec.tau / scale)


def from_model_units(value: float, unit: str, scale: float = MODEL_TORQUE_SCALE) -> float:
    """A fitted parameter back in SI: torques, stiffnesses, frictions and inertias times ``scale``."""
    return value * scale if unit.startswith(_TORQUE_UNITS) else value


def published_as_parameters(pub: dict[str, float], link_inertia: float) -> dict[str, float]:
    """The authors' values under mjjoint's parameter names (SI, mjjoint's sides).

    Their friction acts on the link speed: f_coul tanh(s theta') + f_a tanh(f_b theta') +
    f_vis theta' + f_asym. At running speed both tanh terms are signs, so the motor-side
    Coulomb level is (f_coul + f_a)/N, the viscous one f_vis/N^2, and the constant f_asym is a
    shift of both levels (friction_asymmetry ratio f_asym/(f_coul + f_a)). Their deflection
    T/c + q_back tanh(s_e T) spans +-q_back at T = 0: a dead zone of total width 2 q_back.
    """
    n = pub["u"]
    coulomb = pub["f_coul"] + pub["f_a"]
    return {"inertia.motor": pub["J_mr"], "inertia.link": link_inertia,
            "linear_stiffness.k1": pub["c_rad_ff"], "backlash.width": 2 * pub["q_back"],
            "coulomb_friction.fc": coulomb / n, "viscous_friction.sigma": pub["f_vis"] / n ** 2,
            "friction_asymmetry.ratio": pub["f_asym"] / coulomb}
