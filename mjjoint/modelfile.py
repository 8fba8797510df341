"""Model files: the arm and joint parameters of a simulation in TOML or YAML, or an MJCF path.

A TOML/YAML model file has the sections (all optional; an absent one keeps the defaults)::

    [simulation]     sample_rate
    [arm]            ArmSpec fields (segments, rod_length, ..., timestep)
    [joint]          motor_joint, link_joint ("world" locks the output)
    [friction]       kind = "2sep" | "static" | "none", plus that kind's fields
    [transmission]   gear_ratio, k1, k2, k3, damping, backlash
    [hysteresis]     kind = "boucwen" | "none", plus mu, a, beta, gamma, n
    [load_friction]  kind = "bearing" | "none", plus fc, viscous, v_eps
    [ripple]         kind = "sine" | "none", plus amplitude, harmonic, phase

A section given without ``kind`` uses its first kind (e.g. friction = 2sep). Every value is
checked by the parameter dataclasses themselves; errors are one line naming the key path,
e.g. ``transmission.k1=-3 is outside the allowed range (0, inf)``.
"""
from __future__ import annotations

import dataclasses
import json
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import yaml

from .assets import ASSETS_DIR, ArmSpec, load_model
from .joint import JOINT_FIELDS, SECTIONS, JointParams
from .physics.catalogue import TERMS
from .params import check, from_mapping, is_number

SUFFIXES = (".toml", ".yaml", ".yml", ".xml")
SECTION_NAMES = ("simulation", "arm", "joint", *SECTIONS)
NONE = "none"
_SCALARS = (bool, int, float, str)


@dataclass(frozen=True)
class Simulation:
    """The ``[simulation]`` section."""

    sample_rate: float = 1000.0  # [Hz]: the chapter's 1 kHz recordings

    def __post_init__(self) -> None:
        check("sample_rate", self.sample_rate, 0.0, lo_open=True)


@dataclass(frozen=True)
class ModelFile:
    """What a model file describes: an arm built from ``arm`` and ``joint``, or an MJCF file."""

    arm: ArmSpec | None = ArmSpec()
    joint: JointParams | None = JointParams()
    sample_rate: float = Simulation.sample_rate
    mjcf: Path | None = None  # set for an .xml model; arm and joint are then None
    # The sections the file states (the others hold defaults): where it came from, not what it describes.
    given: frozenset[str] = dataclasses.field(default=frozenset(), compare=False)

    def __post_init__(self) -> None:
        Simulation(self.sample_rate)

    def compile(self) -> mujoco.MjModel:
        if self.mjcf is not None:
            return load_model(self.mjcf)
        return load_model(None, arm=self.arm, joint=self.joint)


def from_section(cls: type, values: dict[str, Any], where: str, **objects: Any):
    """Build ``cls`` from a file section's scalar values plus already built ``objects``.

    Types are checked first (a string is not a number), then ``from_mapping`` rejects unknown
    keys and the dataclass checks ranges; a message about one field gets the key path
    ``where.`` prefixed.
    """
    defaults = {f.name: f.default for f in dataclasses.fields(cls)}
    values = {k: _typed(f"{where}.{k}", v, defaults[k]) if k in defaults else v
              for k, v in as_section(values, where).items()}
    try:
        return from_mapping(cls, {**values, **objects}, where)
    except ValueError as exc:
        msg = str(exc)
        raise ValueError(f"{where}.{msg}" if msg.split("=", 1)[0] in defaults else msg) from None
    except TypeError:  # a required field without a value
        missing = sorted(k for k, d in defaults.items() if d is dataclasses.MISSING and k not in values)
        raise ValueError(f"{where}.{missing[0]} is required") from None


def as_section(body: Any, where: str) -> dict:
    """``body`` where it is a section (a table of keys), else a one-line error naming ``where``."""
    if not isinstance(body, dict):
        raise ValueError(f"{where} must be a section of key = value pairs, not {brief(body)}")
    return body


def brief(value: Any, most: int = 40) -> str:
    """``repr(value)``, cut to ``most`` characters for a one-line message."""
    try:
        text = repr(value)
    except ValueError:  # an integer of more digits than Python converts to text
        return "an integer of thousands of digits"
    return text if len(text) <= most else text[:most - 3] + "..."


def _typed(name: str, value: Any, default: Any) -> Any:
    """``value`` if its type fits the field's default (an int is a valid float), else an error."""
    if isinstance(default, bool):
        ok, want = isinstance(value, bool), "true or false"
    elif isinstance(default, (int, float)):
        ok, want = isinstance(value, (int, float)) and not isinstance(value, bool), "a number"
        if ok and abs(value) > sys.float_info.max:  # an integer literal no float can hold
            raise ValueError(f"{name}={brief(value)} is beyond the largest number ({sys.float_info.max:.4g})")
        if ok and isinstance(default, float):
            value = float(value)
    elif isinstance(default, str) or default is dataclasses.MISSING:
        ok, want = isinstance(value, str), "a string"
    else:  # a term (dataclass or None): set by its own section, never as a value
        raise ValueError(f"{name} is not a value; use the section [{name.rsplit('.', 1)[1]}]")
    if not ok:
        if want == "a number" and isinstance(value, str) and is_number(value):
            want += " (it is quoted text; YAML also reads 1e-3 as text, write 1.0e-3)"
        raise ValueError(f"{name}={value!r} must be {want}")
    return value



# A model file describes the elastic arm, whose gear cannot be left out (direct drives are
# built in Python: mjjoint.assets.drive).
REQUIRED = ("transmission",)


def _term(section: str, values: dict[str, Any] | None, default: Any, **objects: Any):
    """One physics term from its section: the default when absent, None for kind = "none"."""
    if values is None:
        return default
    kinds = SECTIONS[section]
    values = dict(values)
    kind = values.pop("kind", next(iter(kinds)))
    allowed = ([] if section in REQUIRED else [NONE]) + list(kinds)
    if not isinstance(kind, str) or kind not in allowed:
        raise ValueError(f"{section}.kind={kind!r} is not a known kind (allowed: {', '.join(allowed)})")
    if kind == NONE:
        if values:
            raise ValueError(f"{section}.{next(iter(values))} is set but {section}.kind is {NONE!r}")
        return None
    return from_section(kinds[kind], values, section, **objects)


def parse_model(data: Any) -> ModelFile:
    """A ``ModelFile`` from the parsed mapping of a TOML/YAML model file."""
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ValueError(f"the file must hold sections ({', '.join(SECTION_NAMES)}), not a {type(data).__name__}")
    unknown = sorted(set(data) - set(SECTION_NAMES), key=str)
    if unknown:
        raise ValueError(f"unknown section {unknown[0]!r} (allowed: {', '.join(SECTION_NAMES)})")
    for name, body in data.items():
        as_section(body, name)
    # A section absent from the file leaves its term as the defaults have it; a nested term
    # (the transmission's hysteresis) is read first and handed to the term that holds it.
    d = JointParams()
    terms: dict[str, Any] = {}
    for t in sorted(TERMS, key=lambda t: t.nested_in is None):
        inner = {u.section: terms.pop(u.section) for u in TERMS if u.nested_in == t.section}
        given = data.get(t.section, {} if t.section in REQUIRED else None)
        terms[t.section] = _term(t.section, given, d.term(t.section), **inner)
    extra = tuple((s, v) for s, v in terms.items() if s not in JOINT_FIELDS and v is not None)
    own = {s: v for s, v in terms.items() if s in JOINT_FIELDS}
    return ModelFile(
        arm=from_section(ArmSpec, data.get("arm", {}), "arm"),
        joint=from_section(JointParams, data.get("joint", {}), "joint", extra=extra, **own),
        sample_rate=from_section(Simulation, data.get("simulation", {}), "simulation").sample_rate,
        given=frozenset(data),
    )


def shipped(path: Path) -> Path:
    """``path``, or the shipped MJCF it names by its bare name ("arm3.xml") where no such file is here."""
    if (path.suffix.lower() == ".xml" and not path.is_file() and path.parent == Path(".")
            and (ASSETS_DIR / path.name).is_file()):
        return ASSETS_DIR / path.name
    return path


def load_model_file(path: str | Path) -> ModelFile:
    """Read a .toml, .yaml/.yml or .xml model; every problem is a one-line ``ValueError``."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise ValueError(f"{path}: unsupported model file type {suffix!r} (allowed: {', '.join(SUFFIXES)})")
    path = shipped(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such file")
    if suffix == ".xml":
        return ModelFile(arm=None, joint=None, mjcf=path)
    try:
        text = path.read_text(encoding="utf-8")
        data = tomllib.loads(text) if suffix == ".toml" else yaml.safe_load(text)
        return parse_model(data)
    except (ValueError, yaml.YAMLError, OSError) as exc:
        raise ValueError(f"{path}: {one_line(exc)}") from None


def one_line(exc: Exception) -> str:
    """A parser's or compiler's error on one line: YAML's problem and where, else its text."""
    mark = getattr(exc, "problem_mark", None)  # YAML: the problem and where, without the excerpt
    if mark is not None and getattr(exc, "problem", None):
        return f"{exc.problem} (at line {mark.line + 1}, column {mark.column + 1})"
    return " ".join(str(exc).split())


def model_mapping(arm: ArmSpec = ArmSpec(), joint: JointParams = JointParams(),
                  sample_rate: float = Simulation.sample_rate) -> dict[str, dict[str, Any]]:
    """The sections of a model file describing ``arm`` and ``joint`` (inverse of ``parse_model``)."""
    out = {"simulation": {"sample_rate": float(sample_rate)}, "arm": _values(arm),
           "joint": {"motor_joint": joint.motor_joint, "link_joint": joint.link_joint}}
    for t in TERMS:
        term = joint.term(t.section)
        out[t.section] = {"kind": NONE} if term is None else {"kind": t.kind_of(term), **_values(term)}
    return out


def _values(obj: Any) -> dict[str, Any]:
    """Scalar fields of a parameter set as the file types them (a float field stays a float)."""
    out = {}
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if isinstance(v, _SCALARS):
            out[f.name] = float(v) if isinstance(f.default, float) else v
    return out


def dump_model_file(path: str | Path, arm: ArmSpec = ArmSpec(), joint: JointParams = JointParams(),
                    sample_rate: float = Simulation.sample_rate) -> Path:
    """Write a .toml or .yaml/.yml model file that ``load_model_file`` reads back unchanged."""
    path = Path(path)
    sections = model_mapping(arm, joint, sample_rate)
    suffix = path.suffix.lower()
    if suffix == ".toml":
        docs = {t.section: f"  # {t.doc}" for t in TERMS}
        text = "\n".join(f"[{name}]{docs.get(name, '')}\n"
                         + "".join(f"{k} = {_toml_value(v)}\n" for k, v in body.items())
                         for name, body in sections.items())
    elif suffix in (".yaml", ".yml"):
        text = yaml.safe_dump(sections, sort_keys=False)
    else:
        raise ValueError(f"{path}: model files are written as .toml, .yaml or .yml, not {suffix!r}")
    path.write_text(text, encoding="utf-8")
    return path


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)  # a JSON string is a valid TOML basic string
    return repr(v)  # ints and floats (repr round-trips exactly; "inf" is TOML too)
