"""HDF5 recordings (.h5, .hdf5) and MATLAB v7.3 .mat files, which are HDF5 files (h5py).

A source name is a dataset path, `/group/time` or `group/time`, or the same path dotted,
`rec.time` (a v7.3 MATLAB struct is a group, its fields the group's members), with the index
forms of arrays.py. MATLAB writes arrays column-major, so HDF5 holds a v7.3 variable with its
dimensions reversed (an N x k matrix as k x N): those are transposed back, and `data[:, 3]`
is column 3 of MATLAB's N x k `data`, as in a v5 file. Plain HDF5 datasets are taken as
stored (row-major, the layout of h5py, pandas and C writers).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import h5py
import numpy as np

from .arrays import as_signal, parse_pick
from .errors import RecordingError, listing, quote

# MATLAB classes of real numeric arrays; char, cell, logical, function handles, objects are not signals.
_NUMERIC = frozenset({"double", "single", "int8", "int16", "int32", "int64", "uint8", "uint16", "uint32", "uint64"})
_SEP = re.compile(r"[/.]")


@dataclass(frozen=True)
class H5Table:
    """The top-level members of an HDF5 file; a dataset is read only when it is asked for."""

    file: str
    path: Path
    names: tuple[str, ...]
    matlab: bool  # a MATLAB v7.3 file: dimensions reversed, MATLAB_class attributes
    kind: ClassVar[str] = "variable"
    # Like .mat and .npz, HDF5 logs hold parameters and other channels beside the signals.
    strict: ClassVar[bool] = False
    lines: ClassVar[None] = None

    def column(self, name: str, role: str) -> np.ndarray:
        """The 1-D float64 signal `name` (a dataset path, see the module) used as `role`."""
        pick = parse_pick(name, f"{self.file}: source {quote(name)} (for {role})")
        what = f"{self.file}: {'variable' if self.matlab else 'dataset'} {quote(pick.path)} (for {role})"
        try:
            with h5py.File(self.path, "r") as f:
                x = self._dataset(_find(f, pick.path, what), what)
        except (OSError, KeyError, RuntimeError) as exc:  # h5py surfaces corrupt data this way
            raise RecordingError(f"{what}: cannot read ({type(exc).__name__}: {exc})") from None
        return as_signal(x, pick, what)

    def _dataset(self, node: h5py.Dataset | h5py.Group, what: str) -> np.ndarray:
        if isinstance(node, h5py.Group):
            kind = "struct" if self.matlab else "group"
            raise RecordingError(f"{what} is a {kind} with members {listing(_members(node))}; pick one with {node.name.lstrip('/')}.NAME")
        if h5py.check_dtype(ref=node.dtype) is not None:
            raise RecordingError(f"{what} holds references (a MATLAB cell or struct array), not numbers; "
                                 "only a numeric array or a field of a single struct can be read")
        if self.matlab:
            cls = _text(node.attrs.get("MATLAB_class", b"double"))
            if cls not in _NUMERIC:
                raise RecordingError(f"{what} is a MATLAB {cls} array, not a numeric one")
            if "MATLAB_empty" in node.attrs and node.attrs["MATLAB_empty"]:
                raise RecordingError(f"{what} is empty")
            return np.asarray(node[()]).T
        return np.asarray(node[()])


def _text(value: bytes | str | np.ndarray) -> str:
    value = value.tobytes() if isinstance(value, np.ndarray) else value
    return value.decode("ascii", "replace") if isinstance(value, bytes) else str(value)


def _find(f: h5py.File, path: str, what: str) -> h5py.Dataset | h5py.Group:
    """The member at `path` (slashes or dots), with the step that failed named otherwise."""
    exact = path.strip("/")
    if exact and exact in f:
        return f[exact]
    node, walked = f, ""
    for part in _SEP.split(exact):
        if not isinstance(node, h5py.Group):
            raise RecordingError(f"{what}: {quote(walked)} is a dataset of shape {node.shape}, so has no member {quote(part)}")
        if not part or part not in node:
            where = f"{quote(walked)} has" if walked else "the file has"
            raise RecordingError(f"{what} not found: {where} no member {quote(part)}; members: {listing(_members(node))}")
        node, walked = node[part], f"{walked}/{part}" if walked else part
    return node


def _members(group: h5py.Group) -> list[str]:
    # MATLAB keeps cell contents and class data in '#refs#' and '#subsystem#': no variables.
    return [k for k in group if not k.startswith("#")]


def read_h5_table(path: Path, matlab: bool = False) -> H5Table:
    """The top-level names of an HDF5 file, or of a MATLAB v7.3 .mat file (`matlab`); read only."""
    try:
        with h5py.File(path, "r") as f:
            names = tuple(_members(f))
    except (OSError, RuntimeError) as exc:  # not HDF5, truncated, or unreadable
        kind = "MATLAB v7.3 (HDF5)" if matlab else "HDF5"
        raise RecordingError(f"{path}: not a readable {kind} file ({type(exc).__name__}: {exc})") from None
    return H5Table(str(path), path, names, matlab)
