"""The declaration of an effect: a named, fittable piece of physics (``identify.effects``
holds the catalogue).

This module has no dependency on the simulator, so a user term module
(``physics.catalogue``) can declare its effects while mjjoint is still being imported.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Callable

# The evidence figures an effect can declare (report.evidence): tau-delta loops, the
# cross-correlation of a time shift, the residual spectrum, or the residual against a condition.
PLOTS = ("loops", "time_shift", "spectrum", "sin_theta", "motor_revolution", "link_velocity", "motor_velocity",
         "measured_torque")
SITES = ("motor", "gear", "link", "sensor")


@dataclass(frozen=True)
class Param:
    """One free parameter: ``name`` is unique across effects (``<effect>.<symbol>``)."""

    name: str
    initial: float
    lo: float
    hi: float
    log: bool = True
    unit: str = ""
    dim: str = ""        # physical dimension, for plants of other scales (see DIMENSIONS)
    # The lower bound stands for a value the effect keeps its meaning at (a rod of negligible
    # damping still bends): a fit there is an estimate, not a stand-in (``FitResult.on_bound``).
    lo_physical: bool = False
    # A constant of nature (g): its range holds every plant and is what the model accepts, so
    # the recording's estimate starts it where it lies inside and never moves the range.
    scale_free: bool = False

    def to_unit(self, value: float) -> float:
        """Map a physical value to the optimiser's coordinate."""
        return math.log(value) if self.log else value

    def from_unit(self, x: float) -> float:
        return math.exp(min(x, 700.0)) if self.log else x  # an infinite interval stays finite

    def for_plant(self, plant, scales: dict[str, float] | None = None) -> "Param":
        """This parameter for a plant of other force/speed/position orders (``scales``, by
        default the plant's own) and units."""
        s = plant.scales if scales is None else scales
        f = DIMENSIONS[self.dim](s["force"], s["speed"], s["position"])
        unit = plant.unit(self.unit)
        if f == 1.0 and unit == self.unit:
            return self
        return dataclasses.replace(self, initial=self.initial * f, lo=self.lo * f, hi=self.hi * f, unit=unit)


# Factor of each dimension for force F, speed V and position X orders (all 1 on the arm).
DIMENSIONS: dict[str, Callable[[float, float, float], float]] = {
    "": lambda f, v, x: 1.0,
    "force": lambda f, v, x: f,
    "force/speed": lambda f, v, x: f / v,
    "force/position": lambda f, v, x: f / x,
    "speed": lambda f, v, x: v,
    "1/position": lambda f, v, x: 1.0 / x,
    "inertia": lambda f, v, x: f * x / (v * v),   # F = J a, a ~ V^2 / X
}

@dataclass(frozen=True)
class Effect:
    """One entry of the effect catalogue: a named piece of physics a model may contain.

    ``apply`` switches its simulator term on with the values of its free ``params``; ``read`` is
    the inverse (its values in a model that has it, else None), so a model file maps onto
    effects. The rest is what the diagnosis and the report need to know of it.
    """

    name: str
    physics: str                       # what it is, in words (printed in reports)
    params: tuple[Param, ...]
    apply: Callable[[Any, dict[str, float]], Any]
    requires: tuple[str, ...] = ()
    excludes: tuple[str, ...] = ()    # effects that cannot be in one model with it
    # Effects whose fitted values stand in for this one while it is missing (a rigid link's fit
    # damps the rod's oscillation with the gear's damper): freed with it when it is screened.
    stand_ins: tuple[str, ...] = ()
    site: str = "motor"    # where it acts: "motor" (torque on the rotor), "gear", "link" or "sensor"
    term: str = ""         # the simulator term it sets (physics.catalogue); "" for the arm's or a sensor's
    # A sensor effect changes what is measured, not the physics: it maps the predicted signals
    # (windows x samples arrays by name), given the values and the sample rate.
    measure: Callable[[dict, dict[str, float], float], dict] | None = None
    senses: tuple[str, ...] = ()       # the measured signals ``measure`` changes
    # Located conditions (diagnosis.locate) it would explain, and signs of the recording itself
    # (diagnosis.loop.recorded_signs) that make an effect screened on request a default candidate.
    evidence: tuple[str, ...] = ()
    acts_under: str | None = None      # the one condition it acts mainly under, rank-tested there too
    plot: str = ""                     # its evidence figure (report.evidence.PLOTS)
    direct_drive: bool = False         # whether a direct drive (no gear, no output side) can have it
    read: Callable[[Any], dict[str, float] | None] | None = None
    # (located conditions) -> [(initial values, discrete settings)] to screen it with; one plain
    # variant when None.
    variants: Callable[[list[dict], Any], list[tuple[dict, dict]]] | None = None
    # A generic form (identify.generic): screened only where no catalogued effect explains a
    # located residual; ``causes`` names the physics that produce the form.
    generic: bool = False
    causes: str = ""
    # Whether the plant's step resolves the term at any of its values: the plugin integrates its
    # terms converged at the shipped step (docs/design.md); a flexible rod's hinges are MuJoCo's
    # own springs, stable long before their modes are resolved (diagnosis.loop._refined).
    step_resolved: bool = True
    # Screened only where the options name it (``--candidates``): a form the data seldom tell
    # from a richer rival, whose parsimony would otherwise displace it.
    on_request: bool = False
    # (structure) -> the frequency [Hz] of the mode the effect adds (a flexible rod's first mode
    # with the hub held), for effects whose evidence is a resonance; None for the others.
    mode_hz: Callable[[Any], float] | None = None

    def __post_init__(self) -> None:
        if self.site not in SITES:
            raise ValueError(f"effect {self.name!r}: site={self.site!r} is not one of {', '.join(SITES)}")
        if self.plot not in PLOTS:
            raise ValueError(f"effect {self.name!r}: plot={self.plot!r} is not one of {', '.join(PLOTS)}")
        if (self.site == "sensor") != bool(self.senses):
            raise ValueError(f"effect {self.name!r}: a sensor effect, and only one, names the signals it senses "
                             f"(site={self.site!r}, senses={self.senses!r})")
        for p in self.params:
            if p.name.split(".", 1)[0] != self.name:
                raise ValueError(f"parameter {p.name!r} of effect {self.name!r} must be named {self.name}.<symbol>")



def term_values(section: str, fields: dict[str, str], qualifiers: dict[str, str] | None = None):
    """An ``Effect.read`` for values one simulator term holds: ``fields`` and ``qualifiers``
    map parameter -> the term's field. None where the term is off or every one of ``fields`` is
    zero (a ``qualifier``, such as a period, does not make the effect present)."""
    def read(model):
        term = model[1].term(section)
        if term is None or not any(getattr(term, f) for f in fields.values()):
            return None
        return {name: getattr(term, f) for name, f in {**fields, **(qualifiers or {})}.items()}
    return read
