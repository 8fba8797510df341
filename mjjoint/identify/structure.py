"""A model structure: which effects are on, and the values of all their parameters."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import mujoco
import numpy as np

from ..assets import ArmSpec, load_model
from ..assets.drive import DriveSpec
from ..assets.plant import build_plant
from .effects import (EFFECTS, Model, Param, Plant, base_params, check_effects, minimal_model, plant_effects,
                      rigid_gear)
from .initial import Estimate
from .intervals import near_bound


@dataclass(frozen=True)
class Structure:
    """Effects switched on over the minimal model, with every free parameter's value.

    ``settings`` holds discrete choices that are not fitted (e.g. the ripple harmonic, found
    from the evidence); ``values`` maps each free parameter's name to its physical value.
    """

    effects: tuple[str, ...]
    values: dict[str, float]
    nominal: Plant
    gear_ratio: float
    settings: dict[str, float] = field(default_factory=dict)
    # The recording's orders and estimates (``initial.Estimate``): every parameter's initial
    # value and bounds come from them; None: the catalogue's, scaled by the plant's ``scales``.
    start: Estimate | None = None

    @classmethod
    def create(cls, effects, nominal: Plant, gear_ratio: float, values=None, settings=None,
               start: Estimate | None = None) -> "Structure":
        effects = check_effects(effects, plant_effects(nominal))
        vals = {p.name: p.initial for p in _params(effects, nominal, start)}
        estimated = {} if start is None else start.values
        nominal_values = {"inertia.motor": nominal.motor_inertia}
        if "inertia.link" in vals:
            nominal_values["inertia.link"] = nominal.hub_inertia
        if "mass.tip" in vals:
            nominal_values["mass.tip"] = nominal.tip_mass
        vals.update({k: v for k, v in nominal_values.items() if k not in estimated})
        vals.update(values or {})
        return cls(effects, vals, nominal, float(gear_ratio), dict(settings or {}), start)

    @property
    def params(self) -> tuple[Param, ...]:
        return _params(self.effects, self.nominal, self.start)

    def with_effect(self, name: str, values=None, settings=None) -> "Structure":
        vals = dict(self.values)
        effects = check_effects(self.effects + (name,), plant_effects(self.nominal))
        vals.update({p.name: p.initial for p in _params(effects, self.nominal, self.start) if p.name not in vals})
        vals.update(values or {})
        return dataclasses.replace(self, effects=effects, values=vals,
                                   settings={**self.settings, **(settings or {})})

    def started(self, start: Estimate, keep=()) -> "Structure":
        """This structure with initial values and bounds from a recording's ``start``; the
        values named in ``keep`` (given by the user) stay as they are."""
        return Structure.create(self.effects, self.nominal, self.gear_ratio, {k: self.values[k] for k in keep},
                                self.settings, start)

    def at_timestep(self, timestep: float) -> "Structure":
        """This structure simulated at another step."""
        return dataclasses.replace(self, nominal=dataclasses.replace(self.nominal, timestep=timestep))

    def with_values(self, values: dict[str, float]) -> "Structure":
        return dataclasses.replace(self, values={**self.values, **values})

    # ---- optimiser coordinates ---------------------------------------------------------
    def vector(self, names=None) -> np.ndarray:
        ps = self._select(names)
        return np.array([p.to_unit(float(np.clip(self.values[p.name], p.lo, p.hi))) for p in ps])

    def from_vector(self, x: np.ndarray, names=None) -> "Structure":
        ps = self._select(names)
        # Clipped: exp(log(hi)) may round past hi, where a bound equal to the model's own
        # validated limit would be refused.
        return self.with_values({p.name: min(max(p.from_unit(float(v)), p.lo), p.hi) for p, v in zip(ps, x)})

    def bounds(self, names=None) -> tuple[np.ndarray, np.ndarray]:
        ps = self._select(names)
        lo = np.array([p.to_unit(p.lo) if p.log else p.lo for p in ps])
        hi = np.array([p.to_unit(p.hi) if p.log else p.hi for p in ps])
        return lo, hi

    def stand_in_bounds(self, names, x: np.ndarray) -> tuple[str, ...]:
        """Of the parameters ``names`` at ``x`` (the optimiser's coordinates), those near a bound
        that marks a stand-in: either bound, but a lower bound that is physical (``Param.lo_physical``)."""
        lo, hi = self.bounds(names)
        return tuple(p.name for p, v, a, b, at in zip(self._select(names), x, lo, hi, near_bound(x, lo, hi))
                     if at and not (p.lo_physical and v < (a + b) / 2))

    def near_physical_floor(self, factor: float) -> tuple[str, ...]:
        """The parameters within ``factor`` of a lower bound that is physical
        (``Param.lo_physical``): a term fitted to nearly nothing, which ``stand_in_bounds`` does
        not flag."""
        return tuple(p.name for p in self.params if p.lo_physical and self.values[p.name] < factor * p.lo)

    def _select(self, names) -> tuple[Param, ...]:
        ps = self.params
        return ps if names is None else tuple(p for p in ps if p.name in names)

    # ---- simulator ---------------------------------------------------------------------
    def model_params(self) -> Model:
        """The (ArmSpec, JointParams) this structure describes."""
        plant, joint = minimal_model(self.nominal, self.gear_ratio)
        vals = self.values
        if isinstance(plant, DriveSpec):
            inertias = {"mass": vals["inertia.motor"]}
        elif "mass.tip" in vals:
            inertias = {"motor_inertia": vals["inertia.motor"], "tip_mass": vals["mass.tip"]}
        else:
            inertias = {"motor_inertia": vals["inertia.motor"], "hub_inertia": vals["inertia.link"]}
        model = (dataclasses.replace(plant, **inertias), joint)
        v = {**self.values, **self.settings}
        for name in self.effects:
            model = EFFECTS[name].apply(model, v)
        arm, joint = model
        if isinstance(arm, ArmSpec) and arm.segments and "linear_stiffness" not in self.effects:
            # The rigid gear's spring is as stiff as the inertia behind it allows; a flexible
            # rod decouples at its first hinge, leaving the hub (effects.rigid_gear).
            joint = dataclasses.replace(joint, transmission=rigid_gear(arm, self.gear_ratio))
        return arm, joint

    def measured(self, pred: dict, rate: float) -> dict:
        """Predicted signals as this structure's sensors report them (sensor effects)."""
        v = {**self.values, **self.settings}
        for name in self.effects:
            if EFFECTS[name].measure is not None:
                pred = EFFECTS[name].measure(pred, v, rate)
        return pred

    @property
    def skew(self) -> float:
        """[s] how late the link encoder reads (``sensor_skew``; 0 without it)."""
        return self.values.get("sensor_skew.lag", 0.0) if "sensor_skew" in self.effects else 0.0

    def compile(self) -> mujoco.MjModel:
        return load_model(build_plant(*self.model_params()))

    def describe(self) -> dict:
        return {"effects": list(self.effects),
                "parameters": {k: float(v) for k, v in self.values.items()},
                "settings": {k: float(v) for k, v in self.settings.items()},
                "units": {p.name: p.unit for p in self.params}}


def _params(effects, nominal: Plant, start: Estimate | None = None) -> tuple[Param, ...]:
    params = base_params(nominal) + tuple(p for e in effects for p in EFFECTS[e].params)
    if start is None:
        return tuple(p.for_plant(nominal) for p in params)
    return tuple(start.param(p.for_plant(nominal, start.scales)) for p in params)

