"""Canonical signal names, the --columns / --scales options, and matching them to a file's names.

Single joint: t, u, q, theta and optional tau. Several joints: t plus u1, q1, theta1,
optional tau1, u2, ... numbered from 1 without gaps.
"""

from __future__ import annotations

import math
import re
from collections.abc import Collection, Iterator, Mapping, Sequence

from .errors import RecordingError, listing, quote

SIGNALS = ("t", "u", "q", "theta", "tau")
JOINT_SIGNALS = ("u", "q", "theta", "tau")
OPTIONAL = frozenset({"tau"})
DEG = math.pi / 180
ALLOWED = "t, u, q, theta, tau (or per joint: u1, q1, theta1, tau1, u2, ...)"

_PER_JOINT = re.compile(r"(u|q|theta|tau)([1-9][0-9]{0,3})")  # joints 1-9999: a longer number is no joint


def split_joint(name: str) -> tuple[str, int | None]:
    """'theta2' -> ('theta', 2); names without a joint number -> (name, None)."""
    m = _PER_JOINT.fullmatch(name)
    return (m[1], int(m[2])) if m else (name, None)


def is_canonical(name: str) -> bool:
    return name in SIGNALS or _PER_JOINT.fullmatch(name) is not None


def _items(text: str) -> list[str]:
    """``text`` split at the commas outside brackets: ``data[:, 3]`` and ``clip(x, -1, 1)`` are one item."""
    items, depth, start = [], 0, 0
    for i, c in enumerate(text):
        depth += (c in "([") - (c in ")]")
        if c == "," and depth == 0:
            items.append(text[start:i])
            start = i + 1
    return [*items, text[start:]]


def name_value_pairs(text: str, option: str, example: str) -> Iterator[tuple[str, str]]:
    """The name=value items of a comma list such as an option's value, each name once."""
    if not text.strip():
        raise RecordingError(f"{option}: empty; expected e.g. {example}")
    seen: set[str] = set()
    for item in _items(text):
        key, sep, value = (s.strip() for s in item.partition("="))
        if not (sep and key and value):
            raise RecordingError(f"{option}: {quote(item.strip())} is not of the form name=value (e.g. {example})")
        if key in seen:
            raise RecordingError(f"{option}: {quote(key)} is given twice")
        seen.add(key)
        yield key, value


def _check_keys(keys: Collection[str], option: str) -> None:
    unknown = [k for k in keys if not is_canonical(k)]
    if unknown:
        raise RecordingError(f"{option}: unknown signal name(s) {listing(unknown)}; allowed: {ALLOWED}")


def check_column_map(columns: Mapping[str, str], option: str = "columns") -> dict[str, str]:
    """Validated copy of a canonical -> source-name mapping."""
    _check_keys(columns, option)
    for key, source in columns.items():
        if not isinstance(source, str) or not source.strip():
            raise RecordingError(f"{option}: source name for {quote(key)} must be a non-empty string, got {source!r}")
    return {k: v.strip() for k, v in columns.items()}


def check_scales(scales: Mapping[str, float | str], option: str = "scales") -> dict[str, float]:
    """Validated copy of a canonical -> multiplier mapping; the word 'deg' means pi/180."""
    _check_keys(scales, option)
    out: dict[str, float] = {}
    for key, factor in scales.items():
        try:
            out[key] = DEG if isinstance(factor, str) and factor.strip().lower() == "deg" else float(factor)
        except (TypeError, ValueError):
            raise RecordingError(f"{option}: factor for {quote(key)} must be a number or 'deg', got {factor!r}") from None
        if not math.isfinite(out[key]) or out[key] == 0:
            raise RecordingError(f"{option}: factor for {quote(key)} must be finite and non-zero, got {factor!r}")
    return out


def parse_column_map(text: str) -> dict[str, str]:
    """Parse 't=time,u=vir,q=qm,theta=qm' into {canonical: source name}.

    In .mat and .npz files a source may pick a column (data[:, 3]) or a struct field (rec.q).
    """
    return check_column_map(dict(name_value_pairs(text, "--columns", "t=time,u=vir,q=qm,theta=qm")), "--columns")


def parse_scales(text: str) -> dict[str, float]:
    """Parse 'q=deg,theta=deg,u=2.5' into {canonical: multiplier}; 'deg' means pi/180."""
    return check_scales(dict(name_value_pairs(text, "--scales", "q=deg,theta=deg,u=2.5")), "--scales")


def resolve_columns(available: Sequence[str], columns: Mapping[str, str], where: str, kind: str,
                    single: Sequence[str] = SIGNALS, optional: Collection[str] = OPTIONAL) -> dict[str, str]:
    """Canonical name -> source name for every signal the file provides.

    The layout (single or several joints) follows from the mapped names and from the
    file's names that are canonical already. `kind` is 'column' or 'variable', for messages.
    `single`: the signals of a single joint's layout, `optional` those it may lack (a friction
    log: t, q, tau, all required).
    """
    names = set(columns) | {a for a in available if is_canonical(a)}
    joints = {j for n in names if (j := split_joint(n)[1]) is not None}
    singles = sorted(n for n in names if n in JOINT_SIGNALS)
    if joints and singles:
        raise RecordingError(f"{where}: mixes single-joint names ({', '.join(singles)}) with per-joint names (u1, q1, ...)")
    if joints and sorted(joints) != list(range(1, max(joints) + 1)):
        raise RecordingError(f"{where}: joints must be numbered 1, 2, ... without gaps; found {sorted(joints)}")
    wanted = ["t", *(f"{s}{j}" for j in sorted(joints) for s in JOINT_SIGNALS)] if joints else list(single)
    missing = [w for w in wanted if w not in names and split_joint(w)[0] not in optional]
    if missing:
        raise RecordingError(
            f"{where}: missing required {kind}(s) {', '.join(missing)}; {kind}s present: {listing(available)}; "
            f"name them with --columns, e.g. {missing[0]}=NAME"
        )
    return {w: columns.get(w, w) for w in wanted if w in names}


def expand_scales(scales: Mapping[str, float], names: Collection[str], where: str) -> dict[str, float]:
    """Per-signal factors: 'q' covers q1, q2, ... unless 'q2' is given itself."""
    factors: dict[str, float] = {}
    # Generic keys first, so that per-joint keys override them.
    for key in sorted(scales, key=lambda k: split_joint(k)[1] is not None):
        hits = [n for n in names if n == key or (split_joint(n)[0] == key and split_joint(n)[1] is not None)]
        if not hits:
            raise RecordingError(f"{where}: a scale is given for {quote(key)}, which this recording does not have")
        factors.update(dict.fromkeys(hits, scales[key]))
    return factors
