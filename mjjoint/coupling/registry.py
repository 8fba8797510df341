"""Parameter rows shared by all threads, keyed by the model they were parsed from.

``mujoco.rollout`` pairs any thread's mjData with any model of the batch, so parameters
cannot live in per-mjData memory: a row holds one plugin instance's parameter block, keyed by
(mjModel address, address and length of the instance's config bytes in that model, a checksum
of those bytes, instance). Each mjData's ``plugin_data`` slot only caches a row number, which
the callbacks re-validate every step (a few word reads); a stale or foreign row sends them to
``find_row``. A model freed and another compiled at the same address with a different config
fails the checksum, so recycled addresses never pick up old parameters.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .layout import BLOCK_LEN
from .pointers import u64_array

CAPACITY = 4096
# key columns
K_MODEL, K_ATTR, K_LEN, K_SUM, K_INSTANCE = range(5)
NKEY = 5

keys = np.zeros((CAPACITY, NKEY), dtype=np.uint64)
params = np.zeros((CAPACITY, BLOCK_LEN))
KEYS_ADDRESS = keys.ctypes.data
PARAMS_ADDRESS = params.ctypes.data


@njit(cache=True)
def checksum(address, nbytes):
    """Order-sensitive sum of the config bytes read 8 at a time (tail bytes one by one)."""
    nwords = nbytes // 8
    words = u64_array(address, nwords) if nwords > 0 else u64_array(address, 1)[:0]
    h = np.uint64(1469598103934665603)
    for i in range(nwords):
        h = (h ^ words[i]) * np.uint64(1099511628211)
    tail = u64_array(address + 8 * nwords, 1)[0] if nbytes % 8 else np.uint64(0)
    if nbytes % 8:
        tail = tail & ((np.uint64(1) << np.uint64(8 * (nbytes % 8))) - np.uint64(1))
        h = (h ^ tail) * np.uint64(1099511628211)
    return h


@njit(cache=True)
def row_matches(table, r, model, attr, instance):
    return (table[r, K_MODEL] == model and table[r, K_ATTR] == attr
            and table[r, K_INSTANCE] == instance
            and checksum(attr, table[r, K_LEN]) == table[r, K_SUM])


@njit(cache=True)
def find_row(table, model, attr, instance):
    """Row holding this model instance's parameters, or -1 if it was never registered."""
    for r in range(table.shape[0]):
        if table[r, K_MODEL] == model and row_matches(table, r, model, attr, instance):
            return r
    return -1
