"""Derived signals: a ``--columns`` source that is an arithmetic expression of the file's values.

A drive that logs no torque often logs what its firmware computed it from. A position servo
(a Dynamixel, a hobby servo, a cobot joint in position mode) records the goal and the position;
its motor torque is the firmware's law applied to them:
``u=kt/R*(vin*clip(kp*(goal-position),-1,1)-kt*ddt(position))``. An expression maps such a
log to mjjoint's signals without a script, the law stated where the data are mapped.

Grammar (a subset of Python's, evaluated on NumPy arrays, never by ``eval``):
- references: a source name as the file's reader takes it (``qm``, ``rec.q``, ``entries.position``,
  ``data[:, 3]``); a name with spaces or operators cannot be referenced, only mapped alone. A
  scalar (a servo's ``kp`` in a JSON log, a 1 x 1 MAT variable) is a constant;
- numbers, ``pi``, ``+ - * / **``, comparisons ``< <= > >=`` (1.0 where true, else 0.0), brackets;
- functions: ``abs sign sqrt exp log sin cos tan atan2 clip(x, lo, hi) min(a, b) max(a, b)``
  (elementwise) and ``ddt(x)``, the time derivative: a centred cubic Savitzky-Golay fit over
  DDT_WINDOW samples at the median sample period (``ddt(x, 11)``: over 11), which needs samples
  evenly spaced within DDT_JITTER; on a rest it is exactly zero (``rates.savgol_rate``).
"""

from __future__ import annotations

import ast
import math
import re
from collections.abc import Callable, Mapping

import numpy as np

from .errors import RecordingError, quote

DDT_WINDOW = 7
DDT_ORDER = 3
DDT_JITTER = 0.05  # largest relative deviation of a sample period from the median for ddt
CONSTANTS = {"pi": math.pi}
FUNCTIONS: dict[str, tuple[Callable, int]] = {  # name -> (function, number of arguments)
    "abs": (np.abs, 1), "sign": (np.sign, 1), "sqrt": (np.sqrt, 1), "exp": (np.exp, 1), "log": (np.log, 1),
    "sin": (np.sin, 1), "cos": (np.cos, 1), "tan": (np.tan, 1), "atan2": (np.arctan2, 2),
    "clip": (np.clip, 3), "min": (np.minimum, 2), "max": (np.maximum, 2),
}
DERIVATIVE = "ddt"
_BINARY = {ast.Add: np.add, ast.Sub: np.subtract, ast.Mult: np.multiply, ast.Div: np.divide, ast.Pow: np.power}
_COMPARE = {ast.Lt: np.less, ast.LtE: np.less_equal, ast.Gt: np.greater, ast.GtE: np.greater_equal}
_UNARY = {ast.USub: np.negative, ast.UAdd: np.positive}
_PATH = re.compile(r"(?:[\w./:]|\[[^\]]*\])+")  # a source name or an HDF5 path: no spaces outside [...]
ALLOWED = ("a file's names (dotted paths, [:, j] picks), numbers, pi, + - * / **, < <= > >=, "
           f"{', '.join([*FUNCTIONS, DERIVATIVE])}")


def parse(source: str) -> ast.expr | None:
    """The expression ``source`` is, or None where it can only be a source name (``qm``, ``rec.q``,
    ``data[:, 3]``, ``/drive/time``)."""
    try:
        tree = ast.parse(source.strip(), mode="eval").body
    except SyntaxError:
        return None  # not an expression: the reader reports the name as not found
    return None if _is_reference(tree) else tree


def _is_reference(node: ast.expr) -> bool:
    """A name, a dotted path or a pick of one: what a reader resolves as one source."""
    if isinstance(node, ast.Name):
        return node.id not in CONSTANTS
    if isinstance(node, ast.Attribute):
        return _is_reference(node.value)
    if isinstance(node, ast.Subscript):
        return _is_reference(node.value)
    return False


class Evaluator:
    """Evaluates parsed expressions on one file's values; ``references`` collects what they read."""

    def __init__(self, lookup: Callable[[str, str], np.ndarray], where: str):
        self._lookup = lookup  # (source name, role) -> 1-D array
        self._where = where
        self.references: set[str] = set()

    def __call__(self, tree: ast.expr, source: str, role: str, t: np.ndarray | None) -> np.ndarray:
        """The signal ``role`` as ``source`` (parsed: ``tree``) defines it; ``t`` the time, for ddt."""
        what = f"{self._where}: {role}={quote(source, 60)}"
        with np.errstate(all="ignore"):  # a non-finite result is reported by the signal checks, by sample
            try:
                x = np.asarray(self._eval(tree, source, role, t, what), dtype=np.float64)
            except (ValueError, TypeError) as exc:
                if isinstance(exc, RecordingError):
                    raise
                raise RecordingError(f"{what}: {exc}") from None
        if x.ndim != 1 or x.size < 2:
            raise RecordingError(f"{what} is a constant, not a signal: it must reference at least one of the file's signals")
        return x

    def _eval(self, node: ast.expr, source: str, role: str, t, what: str):
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not isinstance(node.value, bool):
            return float(node.value)
        if isinstance(node, ast.Name) and node.id in CONSTANTS:
            return CONSTANTS[node.id]
        if _is_reference(node):
            name = ast.get_source_segment(source.strip(), node)
            self.references.add(name)
            x = self._lookup(name, role)
            return x[0] if x.size == 1 else x  # a stored scalar (a gain, a supply voltage)
        if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            return _BINARY[type(node.op)](self._eval(node.left, source, role, t, what),
                                          self._eval(node.right, source, role, t, what))
        if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
            return _UNARY[type(node.op)](self._eval(node.operand, source, role, t, what))
        if isinstance(node, ast.Compare) and len(node.ops) == 1 and type(node.ops[0]) in _COMPARE:
            return _COMPARE[type(node.ops[0])](self._eval(node.left, source, role, t, what),
                                               self._eval(node.comparators[0], source, role, t, what)).astype(float)
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and not node.keywords:
            args = [self._eval(a, source, role, t, what) for a in node.args]
            if node.func.id == DERIVATIVE:
                return _derivative(args, t, what)
            if node.func.id in FUNCTIONS:
                f, n = FUNCTIONS[node.func.id]
                if len(args) != n:
                    raise RecordingError(f"{what}: {node.func.id} takes {n} argument(s), got {len(args)}")
                return f(*args)
        part = ast.get_source_segment(source.strip(), node) or source
        raise RecordingError(f"{what}: {quote(part)} is not allowed in an expression; allowed: {ALLOWED}")


def _derivative(args: list, t: np.ndarray | None, what: str) -> np.ndarray:
    """ddt(x[, window]): see the module doc."""
    if t is None:
        raise RecordingError(f"{what}: ddt cannot be used in t itself")
    if len(args) not in (1, 2):
        raise RecordingError(f"{what}: ddt takes a signal and optionally a window length, got {len(args)} arguments")
    window = args[1] if len(args) == 2 else DDT_WINDOW
    if not (np.ndim(window) == 0 and float(window).is_integer() and window % 2 == 1 and window > DDT_ORDER):
        raise RecordingError(f"{what}: ddt's window must be an odd whole number of samples above {DDT_ORDER}, got {window!r}")
    x = np.asarray(args[0], dtype=np.float64)
    if x.ndim != 1 or x.size != t.size:
        raise RecordingError(f"{what}: ddt takes a signal of the file's {t.size} samples")
    if x.size < window:
        raise RecordingError(f"{what}: ddt needs at least {int(window)} samples, the file has {x.size}")
    steps = np.diff(t)
    period = float(np.median(steps))
    if not (period > 0 and np.max(np.abs(steps - period)) <= DDT_JITTER * period):
        raise RecordingError(f"{what}: ddt needs evenly spaced samples (every period within {DDT_JITTER:.0%} of "
                             f"the median {period:.4g} s); differentiate after resampling instead")
    from .rates import savgol_rate  # scipy takes seconds to import: not on the way to simulating

    return savgol_rate(x, int(window), DDT_ORDER, period)


def read_columns(sources: Mapping[str, str], lookup: Callable[[str, str], np.ndarray],
                 where: str) -> tuple[dict[str, np.ndarray], set[str]]:
    """Each signal's values by canonical name, and the file's names they read. A source the
    file resolves as a name is one (an HDF5 path ``drive/meas[:, 0]`` is not a division); one it
    does not is evaluated as an expression where it parses as one (t first, for ddt)."""
    evaluate = Evaluator(lookup, where)
    out: dict[str, np.ndarray] = {}
    for role in sorted(sources, key=lambda r: r != "t"):
        source = sources[role]
        try:
            out[role] = lookup(source, role)
            evaluate.references.add(source)
        except RecordingError as plain:
            tree = parse(source)
            if tree is None:
                raise
            try:
                out[role] = evaluate(tree, source, role, out.get("t"))
            except RecordingError:
                if _PATH.fullmatch(source):  # meant as a path (drive/time/x): the path's error says more
                    raise plain from None
                raise
    return {role: out[role] for role in sources}, evaluate.references
