"""The complete parameter set of one elastic joint, and its MJCF ``<config>`` form.

A joint is the chapter's topology (Fig. 1, Fig. 7): motor friction, transmission (stiffness,
hysteresis, damping, backlash), load bearing friction, and optionally a motor torque ripple,
plus any term a user declares (``physics.catalogue``). Each term can be switched off
(``None``); without a transmission the joint is a direct drive whose motor joint carries the
load itself (a linear axis, a servo with one encoder): its output side must then be
``GROUND``. The MJCF plugin instance carries exactly these values as flat config keys
``<section>`` (the term's kind, or ``none``) and ``<section>.<field>``, read off the terms'
declarations; ``JointParams.to_config``/``from_config`` convert both ways, and the plugin's
init parses the config with the same code, so the MJCF is the model.
"""
from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass

from .params import fields_dict, is_number
from .physics.catalogue import BY_SECTION, TERMS
from .physics.load import LoadFriction
from .physics.ripple import TorqueRipple
from .physics.stribeck import StaticFriction
from .physics.transmission import Transmission
from .physics.twosep import TwoSEP

# section -> {kind name: class}; the kind is what the MJCF says, e.g. friction="2sep".
SECTIONS: dict[str, dict[str, type]] = {t.section: dict(t.kinds) for t in TERMS}
# A joint name meaning "fixed to the world": cuts that side free of motion (locked output,
# Fig. 11; or a spring to ground, Fig. 4).
GROUND = "world"


@dataclass(frozen=True)
class JointParams:
    """All physics of one joint injected by the plugin (see the module docstring)."""

    motor_joint: str = "motor"   # joint of the rotor (q), or "world" for a fixed input
    link_joint: str = "link"     # joint of the gear output (theta), or "world" for a locked output
    friction: TwoSEP | StaticFriction | None = TwoSEP()
    transmission: Transmission | None = Transmission()
    load_friction: LoadFriction | None = LoadFriction()
    ripple: TorqueRipple | None = None
    # The user-declared terms that are on, as (section, parameters) pairs in catalogue order.
    extra: tuple[tuple[str, object], ...] = ()

    def __post_init__(self) -> None:
        for name in ("motor_joint", "link_joint"):
            if not isinstance(getattr(self, name), str) or not getattr(self, name):
                raise ValueError(f"{name}={getattr(self, name)!r} must be a non-empty joint name")
        if self.motor_joint == self.link_joint:
            raise ValueError(f"motor_joint and link_joint are both {self.motor_joint!r}; they must differ")
        if self.transmission is None and self.link_joint != GROUND:
            raise ValueError(f"transmission=none (a direct drive) needs link_joint={GROUND!r}, "
                             f"got {self.link_joint!r}")

    def term(self, section: str):
        """The parameters of the term ``section`` (``None``: off)."""
        if section == "hysteresis":
            return None if self.transmission is None else self.transmission.hysteresis
        if section in JOINT_FIELDS:
            return getattr(self, section)
        return dict(self.extra).get(section)

    def with_term(self, section: str, params) -> "JointParams":
        """A copy with the term ``section`` set to ``params`` (``None``: off)."""
        if section == "hysteresis":
            return self.replace(transmission=dataclasses.replace(self.transmission, hysteresis=params))
        if section in JOINT_FIELDS:
            return self.replace(**{section: params})
        extra = {**dict(self.extra), section: params}
        return self.replace(extra=tuple((t.section, extra[t.section]) for t in TERMS
                                        if extra.get(t.section) is not None))

    @property
    def direct_drive(self) -> bool:
        """No transmission: the motor joint is the output (see the module docstring)."""
        return self.transmission is None

    @property
    def gear_ratio(self) -> float:
        return 1.0 if self.transmission is None else self.transmission.gear_ratio

    def replace(self, **changes) -> "JointParams":
        return dataclasses.replace(self, **changes)

    # ---- MJCF config form -------------------------------------------------------------
    def to_config(self) -> dict[str, str]:
        """Flat string config for ``<plugin><instance><config key= value=/>``."""
        cfg = {"motor_joint": self.motor_joint, "link_joint": self.link_joint}
        for section, term in self._terms().items():
            cfg[section] = "none" if term is None else BY_SECTION[section].kind_of(term)
            if term is not None:
                for key, value in fields_dict(term).items():
                    if not dataclasses.is_dataclass(value) and value is not None:
                        cfg[f"{section}.{key}"] = repr(float(value))
        return cfg

    @classmethod
    def from_config(cls, cfg: dict[str, str]) -> "JointParams":
        """Inverse of ``to_config``; missing fields take their defaults, unknown keys fail."""
        unknown = sorted(set(cfg) - set(config_keys()))
        if unknown:
            raise ValueError(f"unknown config key {unknown[0]!r} (allowed: {', '.join(config_keys())})")
        terms = {}
        for section, kinds in SECTIONS.items():
            kind = cfg.get(section, "")
            values = {k.split(".", 1)[1]: v for k, v in cfg.items() if k.startswith(section + ".") and v != ""}
            if kind == "none":
                terms[section] = None
                continue
            if not kind and not values:  # not mentioned at all: the term's default
                terms[section] = _unmentioned(section)
                continue
            kind = kind or next(iter(kinds))  # fields given without a kind: the first kind
            if kind not in kinds:
                allowed = ["none", *kinds]
                raise ValueError(f"{section}={kind!r} is not a known kind (allowed: {', '.join(allowed)})")
            klass = kinds[kind]
            names = {f.name for f in dataclasses.fields(klass)}
            bad = sorted(set(values) - names)
            if bad:
                raise ValueError(f"config key {section}.{bad[0]} does not apply to {section}={kind} "
                                 f"(allowed: {', '.join(sorted(names))})")
            try:
                parsed = {k: float(v) for k, v in values.items()}
            except ValueError:
                k = next(k for k, v in values.items() if not is_number(v))
                raise ValueError(f"{section}.{k}={values[k]!r} is not a number") from None
            try:
                terms[section] = klass(**parsed)
            except ValueError as exc:
                raise ValueError(f"{section}.{exc}") from None
        hysteresis = terms.pop("hysteresis")
        transmission = terms.pop("transmission")
        if transmission is not None:
            transmission = dataclasses.replace(transmission, hysteresis=hysteresis)
        extra = tuple((k, v) for k, v in terms.items() if k not in JOINT_FIELDS and v is not None)
        own = {k: v for k, v in terms.items() if k in JOINT_FIELDS}
        return cls(motor_joint=cfg.get("motor_joint", "motor"), link_joint=cfg.get("link_joint", "link"),
                   transmission=transmission, extra=extra, **own)

    def _terms(self) -> dict[str, object]:
        return {t.section: self.term(t.section) for t in TERMS}


# The terms JointParams holds in fields of their own; the others live in ``JointParams.extra``.
JOINT_FIELDS = {f.name for f in dataclasses.fields(JointParams)} & {t.section for t in TERMS}


def _unmentioned(section: str):
    """A term's parameters when the MJCF does not mention it: its first kind's defaults, or off."""
    t = BY_SECTION[section]
    return next(iter(t.kinds.values()))() if t.default_on else None


@functools.lru_cache(maxsize=None)
def config_keys() -> tuple[str, ...]:
    """Every config attribute the plugin declares to MuJoCo."""
    return ("motor_joint", "link_joint", JOINTS_KEY,
            *(k for t in TERMS for k in (t.section, *(f"{t.section}.{f}" for f in t.fields))))


# One plugin instance may drive several joints: ``joints="motor1:link1 motor2:link2"``, and every
# other key then holds one value for all of them or one per joint, space-separated.
JOINTS_KEY = "joints"


def group_config(joints: list[JointParams]) -> dict[str, str]:
    """The config of one instance driving ``joints`` (``split_config`` is its inverse)."""
    cfgs = [j.to_config() for j in joints]
    cfg = {JOINTS_KEY: " ".join(f"{c.pop('motor_joint')}:{c.pop('link_joint')}" for c in cfgs)}
    for key in dict.fromkeys(k for c in cfgs for k in c):
        values = [c.get(key, "") for c in cfgs]
        if any(v == "" for v in values):  # a field another kind of the term has
            values = [v or "nan" for v in values]
        cfg[key] = values[0] if len(set(values)) == 1 else " ".join(values)
    return cfg


def split_config(cfg: dict[str, str]) -> list[dict[str, str]]:
    """The single-joint configs of an instance's config: itself, or one per joint of a group."""
    pairs = cfg.get(JOINTS_KEY, "").split()
    if not pairs:
        return [cfg]
    if "motor_joint" in cfg or "link_joint" in cfg:
        raise ValueError(f"config key {JOINTS_KEY!r} lists the joints; motor_joint and link_joint must not be given")
    out = [{} for _ in pairs]
    for i, pair in enumerate(pairs):
        motor, sep, link = pair.partition(":")
        if not sep or not motor or not link:
            raise ValueError(f"{JOINTS_KEY}: {pair!r} must be motor_joint:link_joint")
        out[i].update(motor_joint=motor, link_joint=link)
    for key, value in cfg.items():
        if key == JOINTS_KEY:
            continue
        values = value.split()
        if len(values) not in (1, len(pairs)):
            raise ValueError(f"config key {key!r} has {len(values)} values for {len(pairs)} joints "
                             f"(give 1 or {len(pairs)})")
        for i in range(len(pairs)):
            v = values[0] if len(values) == 1 else values[i]
            if v != "nan" or len(values) == 1:
                out[i][key] = v
    return out


# Semi-implicit Euler with explicit spring and damper forces on one inertia is stable for
# c h/J + (w h)^2/2 < 2 (each alone: c h/J < 2, w h < 2; together they add up); 1.5 keeps margin.
STABILITY_BUDGET = 1.5


def _group_timestep(stiff: dict[str, float], slope: dict[str, float]) -> tuple[float, str]:
    """Largest h with sum(c/J) h + sum(k/J) h^2 / 2 <= ``STABILITY_BUDGET`` for terms acting on
    one inertia."""
    a = 0.5 * sum(stiff.values())
    b = sum(slope.values())
    if a <= 0 and b <= 0:
        return float("inf"), ""
    h = STABILITY_BUDGET / b if a <= 0 else (-b + (b * b + 4.0 * STABILITY_BUDGET * a) ** 0.5) / (2.0 * a)
    parts = {**{k: v * h * h / 2 for k, v in stiff.items()}, **{k: v * h for k, v in slope.items()}}
    return h, max(parts, key=parts.get)


def stable_timestep(params: JointParams, motor_inertia: float, link_inertia: float) -> tuple[float, str]:
    """Largest stable timestep for the explicitly injected forces, and the term that sets it.

    The plugin's forces are explicit in MuJoCo's integrator. Each term declares its stiffnesses
    k and velocity slopes c on an inertia J (``Term.stability``: the transmission on the reduced
    inertia of both sides, 2SEP's pre-sliding and a static map's Coulomb slope on the motor's,
    the bearing friction on the link's); a term's are combined (``_group_timestep``).
    ``link_inertia`` must be the apparent inertia behind the gear (``assets.stability``: the hub
    alone when the rod has flexible segments, since they decouple at these frequencies); ``inf``
    for a side fixed to the world.
    """
    for name, value in (("motor_inertia", motor_inertia), ("link_inertia", link_inertia)):
        if not value > 0:  # inf is allowed: a side fixed to the world
            raise ValueError(f"{name}={value!r} is outside the allowed range (0, inf]")
    groups = [t.stability(params.term(t.section), motor_inertia, link_inertia) for t in TERMS
              if t.stability is not None and params.term(t.section) is not None]
    return min((_group_timestep(*g) for g in groups), key=lambda r: r[0], default=(float("inf"), ""))
