"""Generic terms: the open vocabulary the diagnosis falls back on when a located residual has a
structure that no catalogued effect explains.

Names follow one grammar, ``<site>_<form>[_<coordinate>]``:
- site: ``motor`` (a torque on the rotor) or ``link`` (a torque on the output);
- form: ``constant``, ``linear`` (proportional to the coordinate), ``periodic`` (a sinusoid of
  the coordinate at k cycles per revolution, k fitted: the period comes from the data), or
  ``friction_periodic`` (a friction level, opposing the motion, that is periodic in the coordinate);
- coordinate: ``theta`` (link angle) or ``q`` (motor angle).
Each form says which physical causes produce it (``Effect.causes``), so a named generic term is a
located, sized structure with its candidate explanations, not a claim of one mechanism.
"""
from __future__ import annotations

import dataclasses

from ..diagnosis.locate import MIN_CYCLES
from ..physics.generic import LinkForm, MotorForm
from .effect import Effect, Param, term_values


def _set(model, section: str, klass: type, **values):
    """The model with the generic term ``section`` updated by ``values``."""
    current = model[1].term(section) or klass()
    return model[0], model[1].with_term(section, dataclasses.replace(current, **values))


def _periodic_variants(conditions: tuple[str, ...], name: str):
    """Start at each distinct period the located ``conditions`` propose (their real k, the best
    scores first; at most three)."""
    def variants(conds: list[dict], structure) -> list[tuple[dict, dict]]:
        ranked = sorted((c for c in conds if c["name"] in conditions and c["params"].get("k_real")),
                        key=lambda c: -c["score"])
        ks = list(dict.fromkeys(float(c["params"]["k_real"]) for c in ranked))[:3] or [1.0]
        return [({f"{name}.cycles": k}, {}) for k in ks]
    return variants


def _periodic(name: str, physics: str, site: str, section: str, klass: type, fields: tuple[str, str],
              conditions: tuple[str, ...], evidence: tuple[str, ...], plot: str, causes: str, bound: float = 2.0,
              dim: str = "force", least: float = 0.5) -> Effect:
    """A form a sin(k x) + b cos(k x) of a term's two ``fields``; k, cycles per revolution (at
    least ``least``), is fitted from the periods the located ``conditions`` propose (a real
    number: a period between harmonics of the revolution is allowed)."""
    a, b, k = f"{name}.a", f"{name}.b", f"{name}.cycles"
    return Effect(
        name, physics,
        (Param(a, 0.0, -bound, bound, log=False, unit="N m", dim=dim),
         Param(b, 0.0, -bound, bound, log=False, unit="N m", dim=dim),
         Param(k, 1.0, least, 60.0, log=True)),
        lambda m, v: _set(m, section, klass, **{fields[0]: v[a], fields[1]: v[b], "cycles": v[k]}),
        site=site, term=section, evidence=evidence, plot=plot, generic=True, causes=causes,
        variants=_periodic_variants(conditions, name),
        read=term_values(section, {a: fields[0], b: fields[1]}, {k: "cycles"}))


GENERIC_EFFECTS: tuple[Effect, ...] = (
    Effect("link_constant", "generic: a constant torque on the link",
           (Param("link_constant.c0", 0.0, -1e3, 1e3, log=False, unit="N m"),),
           lambda m, v: _set(m, "link_form", LinkForm, constant=v["link_constant.c0"]),
           site="link", term="link_form", evidence=("delta",), plot="sin_theta", generic=True,
           read=term_values("link_form", {"link_constant.c0": "constant"}),
           causes="a counterbalance or gravity compensation set off its zero, a cable or hose pulling one way, "
                  "an offset of the torque or deflection sensor"),
    Effect("link_linear_theta", "generic: a torque on the link proportional to the link angle",
           (Param("link_linear_theta.c1", 0.0, -1e4, 1e4, log=False, unit="N m/rad"),),
           lambda m, v: _set(m, "link_form", LinkForm, linear=v["link_linear_theta.c1"]),
           site="link", term="link_form", evidence=("theta", "sin_theta"), plot="sin_theta", generic=True,
           read=term_values("link_form", {"link_linear_theta.c1": "linear"}),
           causes="a spring to the ground (cables, hoses, a gas spring, a counterbalance spring), gravity near "
                  "an upright or hanging pose"),
    _periodic("link_periodic_theta", "generic: a torque on the link periodic in the link angle", "link", "link_form",
              LinkForm, ("sin", "cos"), ("periodic_theta",), ("periodic_theta", "sin_theta", "cos_theta"), "sin_theta",
              bound=1e3, dim="",
              causes="gravity of an offset or tilted mass (one cycle), output-gear or bearing cogging and tooth "
                     "meshing (many cycles), an eccentric output or an encoder mounted off-centre"),
    _periodic("motor_periodic_q", "generic: a torque on the rotor periodic in the motor angle", "motor", "motor_form",
              MotorForm, ("sin", "cos"), ("periodic_q",), ("periodic_q",), "motor_revolution",
              causes="cogging or commutation ripple at a count other than the catalogue's whole harmonics, "
                     "a gear stage's tooth mesh seen from the motor, an encoder's interpolation error"),
    _periodic("motor_friction_periodic_q", "generic: a motor friction level periodic in the motor angle", "motor",
              "motor_form", MotorForm, ("friction_sin", "friction_cos"), ("friction_periodic_q", "periodic_q"),
              ("friction_periodic_q", "periodic_q", "coulomb"), "motor_velocity", least=MIN_CYCLES,
              causes="an eccentric or out-of-round bearing or shaft, a harmonic drive's wave generator (two cycles "
                     "per revolution), a seal or brush whose preload varies around the turn, a screw, guide or "
                     "output bearing whose preload varies along the travel (a period of several revolutions)"),
)
