"""Structure check of MATLAB v5 files before scipy parses them.

scipy 1.17's v5 reader uses each element's type code to index a C table without a range
check (scipy PR #25349), so a corrupt file can crash the interpreter instead of raising.
This walk over the element tags rejects such files first; it decodes no data.
"""

from __future__ import annotations

import math
import struct
import zlib
from collections.abc import Iterator

_DECODABLE = frozenset({1, 2, 3, 4, 5, 6, 7, 9, 12, 13, 16, 17, 18})  # mi* codes scipy has a dtype for
_INT32, _UINT32, _MATRIX, _COMPRESSED = 5, 6, 14, 15
_MAX_DIMS = 32  # scipy reads the dimensions into a fixed C array of this size
_CHAR, _SPARSE, _OPAQUE = 4, 5, 17  # mx* classes; opaque (class objects) has no dimensions
_CONTAINERS = frozenset({1, 2, 3, 16, 17, 18})  # cell, struct, object, ...: they nest variables
# Elements scipy reads for a plain variable, flags included: flags, dims, name and data
# (sparse: ir, jc, pr), plus an imaginary part when the complex flag is set.
_PARTS = {_CHAR: 4, _SPARSE: 6, **dict.fromkeys(range(6, 16), 4)}
_COMPLEX_FLAG = 0x0800
_MAX_DEPTH = 64  # nesting beyond this is corruption, and would exhaust the reader's stack


MAT_V5, MAT_V73 = 0x0100, 0x0200  # header versions: v5 (save -v6/-v7) and v7.3 (HDF5 inside)


def mat_version(data: bytes) -> int:
    """The version word of a MAT file's 128-byte header; ValueError if there is no header."""
    if len(data) < 128:
        raise ValueError("shorter than the 128-byte MAT header")
    order = {b"IM": "<", b"MI": ">"}.get(data[126:128])
    if order is None:
        raise ValueError("no MAT v5 or v7.3 header (MATLAB v4 files are not supported)")
    return struct.unpack_from(order + "H", data, 124)[0]


def check_mat_v5(data: bytes) -> None:
    """Raise ValueError naming the first structural problem of a MAT v5 file's bytes."""
    version = mat_version(data)
    order = "<" if data[126:128] == b"IM" else ">"
    if version != MAT_V5:
        raise ValueError(f"unknown MAT version 0x{version:04x}")
    for code, body in _elements(memoryview(data)[128:], order, padded=False):
        if code == _COMPRESSED:
            try:
                inner = zlib.decompress(body)
            except zlib.error as exc:
                raise ValueError(f"corrupt compressed variable ({exc})") from None
            elements = list(_elements(memoryview(inner), order, padded=False))
            if [c for c, _ in elements] != [_MATRIX]:
                raise ValueError("a compressed variable must hold exactly one matrix")
            code, body = elements[0]
        if code != _MATRIX:
            raise ValueError(f"top-level element of type {code}, expected a variable")
        _check_matrix(body, order, depth=0)


def _elements(buf: memoryview, order: str, padded: bool) -> Iterator[tuple[int, memoryview]]:
    """(type code, data) of each element in buf; inside variables, elements are 8-byte aligned."""
    pos = 0
    while pos < len(buf):
        if len(buf) - pos < 8:
            raise ValueError("truncated element tag")
        word, nbytes = struct.unpack_from(order + "II", buf, pos)
        if word >> 16:  # small element: type and size share the first word, data fills the second
            if word >> 16 > 4:
                raise ValueError("small element larger than 4 bytes")
            yield word & 0xFFFF, buf[pos + 4 : pos + 4 + (word >> 16)]
            pos += 8
            continue
        end = pos + 8 + nbytes
        if end > len(buf):
            raise ValueError("element runs past the end of the file or of its variable")
        yield word, buf[pos + 8 : end]
        pos = end + (-nbytes % 8 if padded else 0)


def _check_matrix(body: memoryview, order: str, depth: int) -> None:
    if depth > _MAX_DEPTH:
        raise ValueError(f"variables nested more than {_MAX_DEPTH} deep")
    children = list(_elements(body, order, padded=True))
    if not children:
        return  # empty matrix
    code, flags = children[0]
    if code != _UINT32 or len(flags) != 8:
        raise ValueError("variable without array flags")
    word = struct.unpack_from(order + "I", flags)[0]
    mx_class = word & 0xFF
    code, dims = children[1] if len(children) > 1 else (None, b"")
    if mx_class != _OPAQUE and (code != _INT32 or len(dims) % 4 or not 2 <= len(dims) // 4 <= _MAX_DIMS):
        raise ValueError(f"variable without valid dimensions (2 to {_MAX_DIMS} int32 values)")
    # scipy allocates the array before reading its data, so corrupt dimensions could exhaust
    # memory. Every element but a sparse one takes at least one byte of the variable.
    if mx_class not in (_SPARSE, _OPAQUE) and math.prod(struct.unpack(f"{order}{len(dims) // 4}i", dims)) > len(body):
        raise ValueError("variable dimensions larger than its data")
    if mx_class in _PARTS:
        # scipy reads these parts blindly: a missing one is taken from the next variable's tags.
        expected = _PARTS[mx_class] + (mx_class != _CHAR and bool(word & _COMPLEX_FLAG))
        if len(children) != expected:
            raise ValueError(f"variable of class {mx_class} has {len(children)} elements, expected {expected}")
    for code, child in children[1:]:
        if code == _MATRIX and mx_class in _CONTAINERS:
            _check_matrix(child, order, depth + 1)
        elif code not in _DECODABLE:
            raise ValueError(f"element type code {code} is not valid in a variable of class {mx_class}")
