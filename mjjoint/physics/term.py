"""The declaration of a physics term, from which every other layer derives.

A term is one section of the joint: its MJCF config keys (``<section>`` for the kind and
``<section>.<field>`` for each parameter), its slots in the plugin's parameter block and
state, its ``JointParams`` field, its model-file table, its stability bound and its initial
states are all read off its ``Term``. Nothing else lists a term's parameters.

Two roles:
- The motor friction, the transmission and its hysteresis, and the output bearing's friction
  are integrated by the joint's scheme (the rotor's torques implicit, the gear's stiffness
  limited, the bearing taken at the step's end: ``coupling.kernels``), which calls their
  kernels by name.
- Every other term is an additive torque at a site: its ``torque`` kernel returns the
  generalised forces on the motor and link dofs, and its optional ``advance`` kernel steps its
  states. The plugin sums them in declaration order; a new term of this kind needs nothing but
  its declaration (``catalogue.declare``).

Kernel signatures of an additive term, with ``o``/``s`` its first slot in the block/state::

    torque(blk, o, st, s, q, wq, theta, wtheta) -> (f_motor, f_link)
    advance(blk, o, st, s, q, wq, theta, wtheta, h) -> None

``blk[o]`` is the term's kind (0: absent, else 1 + the kind's index) and ``blk[o + 1 + i]`` its
i-th field (``Term.fields``): ``Term.offsets`` names them for the kernel.
"""
from __future__ import annotations

import dataclasses
from collections import namedtuple
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

SITES = ("motor", "gear", "link")


@dataclass(frozen=True)
class Term:
    """One physics term of the joint (see the module docstring)."""

    section: str                       # config section and JointParams field, e.g. "ripple"
    kinds: Mapping[str, type]          # MJCF kind name -> frozen parameter dataclass
    site: str                          # where it acts: "motor", "gear" or "link"
    doc: str                           # what it is, in words (the model files' section comment)
    states: tuple[str, ...] = ()       # internal states it adds to the plugin state
    torque: Any = None                 # additive-term kernel (module docstring), or None
    advance: Any = None                # state kernel of an additive term, or None
    default_on: bool = True            # present when the MJCF does not mention the section
    absent: Mapping[str, float] = field(default_factory=dict)  # block values while the term is off
    nested_in: str | None = None       # the section whose dataclass holds this one (hysteresis)
    # (params, motor_inertia, link_inertia) -> (stiffnesses, slopes): the explicit forces it puts
    # on the one inertia they act on (the motor's, the link's, or the deflection's reduced one),
    # as {label: k/J} and {label: c/J}; see joint.stable_timestep.
    stability: Callable | None = None
    # (params, motion) -> {state: values}: the states on the steady branch of the measured motion
    # where a window of a recording starts; ``motion`` holds arrays q, w (motor velocity),
    # theta, wtheta (link velocity; 0 without an output side) and delta (deflection).
    steady: Callable | None = None

    def __post_init__(self) -> None:
        if self.site not in SITES:
            raise ValueError(f"site={self.site!r} is not one of {', '.join(SITES)}")
        if not self.kinds:
            raise ValueError(f"term {self.section!r} declares no kind")
        if self.advance is not None and self.torque is None:
            raise ValueError(f"term {self.section!r}: an advance kernel needs a torque kernel")

    @property
    def fields(self) -> tuple[str, ...]:
        """Its parameter fields over all kinds, in declaration order (nested terms excluded)."""
        names: list[str] = []
        for klass in self.kinds.values():
            names += [f.name for f in dataclasses.fields(klass)
                      if f.name not in names and not _is_term_field(f)]
        return tuple(names)

    @property
    def offsets(self):
        """Slot of each field relative to the term's first slot (its kind): a namedtuple, which
        numba reads as constants."""
        return namedtuple(f"{self.section}_offsets", self.fields)(*range(1, 1 + len(self.fields)))

    def kind_of(self, params: object) -> str:
        """The kind name of a parameter set of this term."""
        return next(k for k, c in self.kinds.items() if isinstance(params, c))

    def kind_code(self, kind: str) -> float:
        """The block value of a kind: 1 + its index (0: absent)."""
        return 1.0 + list(self.kinds).index(kind)

    def block_values(self, params: object | None) -> list[float]:
        """The term's slots (kind, then ``fields``) for a parameter set, or for none."""
        if params is None:
            return [0.0] + [float(self.absent.get(f, 0.0)) for f in self.fields]
        own = {f.name for f in dataclasses.fields(params)}
        return [self.kind_code(self.kind_of(params))] + [
            float(getattr(params, f)) if f in own else float(self.absent.get(f, 0.0)) for f in self.fields]


def nested(term_section: str, default: object):
    """A dataclass field that holds another term's parameters (``Term.nested_in``)."""
    return field(default=default, metadata={"term": term_section})


def _is_term_field(f: dataclasses.Field) -> bool:
    return "term" in f.metadata
