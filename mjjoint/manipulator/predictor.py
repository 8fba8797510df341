"""The windowed predictor of one joint with a known load on its dofs, applied every step.

The windows, their start states, lead-ins and cost are ``identify.windows.Predictor``'s; each
step of every rollout also applies ``load`` (``manipulator.load``) as ``qfrc_applied`` on the
joint's dofs, sampled at the step's start time. The load is the mechanics of the rest of the
arm, so a fitted input delay does not shift it.
"""
from __future__ import annotations

import mujoco
import numpy as np

from ..identify.windows import Measured, Predictor, WindowDesign


class LoadedPredictor(Predictor):
    """``Predictor`` whose model also feels ``load`` ({joint name: generalised force per sample of
    ``measured``}) on the dofs of the joints so named."""

    control_spec = int(mujoco.mjtState.mjSTATE_CTRL | mujoco.mjtState.mjSTATE_QFRC_APPLIED)

    def __init__(self, measured: Measured, load: dict[str, np.ndarray], design: WindowDesign = WindowDesign(),
                 nthread: int | None = None, fit_signals: tuple[str, ...] | None = None, describe: str = ""):
        super().__init__(measured, design, nthread, fit_signals)
        bad = [k for k, v in load.items() if len(v) != len(measured.t)]
        if bad:
            raise ValueError(f"load on {bad[0]!r} has {len(load[bad[0]])} samples; the recording {len(measured.t)}")
        self.load = load
        self.describe = describe  # where the load comes from, for reports

    def on(self, measured: Measured, fit_signals: tuple[str, ...] | None = None) -> "LoadedPredictor":
        """The same load on other measurements of the same motion (a twin on the recording's grid)."""
        return LoadedPredictor(measured, self.load, self.design, self.nthread, fit_signals, describe=self.describe)

    def _controls(self, model, i0: np.ndarray, n: int, delay: float, ji) -> np.ndarray:
        ctrl = super()._controls(model, i0, n, delay, ji)
        m = self.m
        tk = m.t[i0][:, None] + model.opt.timestep * np.arange(ctrl.shape[1])[None, :]
        force = np.zeros(ctrl.shape[:2] + (model.nv,))
        for name, f in self.load.items():
            force[:, :, model.joint(name).dofadr[0]] = np.interp(tk, m.t, f)
        return np.concatenate([ctrl, force], axis=2)


def loaded_predictor(measured: Measured, structure, arm: mujoco.MjModel, rec, j: int, design: WindowDesign,
                     fit_signals: tuple[str, ...] | None = None, describe: str = "") -> LoadedPredictor:
    """Joint j's predictor with the load of the rest of ``arm`` along ``rec`` (``manipulator.load``),
    taken against ``structure``'s single-joint model (joint j's view, as the fit starts)."""
    from ..assets.plant import build_plant
    from ..coupling.plugin import register_model
    from .load import coupling_load

    view = build_plant(*structure.model_params()).compile()
    register_model(view)
    grid, load = coupling_load(arm, view, rec, j)
    if len(grid) != len(measured.t) or not np.allclose(grid, measured.t):
        raise ValueError(f"joint {j}: the arm's load and the recording are on different time grids")
    return LoadedPredictor(measured, load, design, fit_signals=fit_signals, describe=describe)


def load_note(predictor) -> str:
    """One line on how joint j meets the rest of the arm, and the size of the load where computed."""
    where = predictor.describe or "the arm"
    link = getattr(predictor, "load", {}).get("link")
    if link is None:
        return f"simulated inside {where}, the other joints following their measured motion"
    tau = predictor.m.tau
    size = f"rms {np.sqrt(np.mean(link ** 2)):.3g} N m on the link"
    if tau is not None and np.any(tau):
        size += f" ({np.sqrt(np.mean(link ** 2)) / np.sqrt(np.mean((tau - tau.mean()) ** 2)):.2g} x tau's spread)"
    return f"the other joints' measured motion loads it through {where}: {size}"
