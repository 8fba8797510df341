"""Parameter rows shared by all threads, keyed by the model they were parsed from.

``mujoco.rollout`` pairs any thread's mjData with any model of the batch, so parameters
cannot live in per-mjData memory: a row holds one plugin instance's parameter block, keyed by
(mjModel address, address of the instance's config bytes in that model, instance) together
with a copy of those config bytes. Each mjData's ``plugin_data`` slot only caches a row
number, which the callbacks re-validate every step: the key words, then the live config bytes
against the row's copy. A model freed and another compiled at the same address with a
different config therefore never picks up old parameters, even if it was never registered
(it fails loudly instead).

The per-step check is written for the hot path: plain loads through raw addresses (no array
objects, so nothing for numba to reference-count) and a branch-free OR over the config words,
which LLVM vectorises; a hash over the same bytes is a chain of dependent multiplies and cost
2 % of a MuJoCo step (``scripts/bench_step.py``).
"""
from __future__ import annotations

import ctypes

import numpy as np
from numba import njit

from .layout import BLOCK_LEN, MAX_JOINTS
from .pointers import u64_array

CAPACITY = 4096
# key columns
K_MODEL, K_ATTR, K_LEN, K_INSTANCE = range(4)
NKEY = 4
# An instance's config (its values, NUL-separated) is 150-300 bytes for one joint of the shipped
# models, a few times that for an instance that drives several.
CONFIG_BYTES = 4096
CONFIG_WORDS = CONFIG_BYTES // 8

keys = np.zeros((CAPACITY, NKEY), dtype=np.uint64)
configs = np.zeros((CAPACITY, CONFIG_WORDS), dtype=np.uint64)
params = np.zeros((CAPACITY, MAX_JOINTS * BLOCK_LEN))  # the blocks of an instance's joints
ROW_LEN = MAX_JOINTS * BLOCK_LEN
KEYS_ADDRESS = keys.ctypes.data
CONFIGS_ADDRESS = configs.ctypes.data
PARAMS_ADDRESS = params.ctypes.data


def config_words(address: int, nbytes: int) -> np.ndarray:
    """The config bytes at ``address`` as zero-padded words, the form a row keeps."""
    if nbytes > CONFIG_BYTES:
        raise ValueError(f"mjjoint.joint config of {nbytes} bytes; at most {CONFIG_BYTES} are supported")
    words = np.zeros(CONFIG_WORDS, dtype=np.uint64)
    words.view(np.uint8)[:nbytes] = np.frombuffer(ctypes.string_at(address, nbytes), dtype=np.uint8)
    return words


@njit(cache=True, inline="always")
def keys_match(keys_addr, r, model, attr, instance):
    """Whether row r was registered for this model address, config address and instance."""
    key = u64_array(keys_addr + 8 * NKEY * r, NKEY)
    # All uint64: numba compares a uint64 with an int64 through float64 conversions.
    return (key[K_MODEL] == np.uint64(model) and key[K_ATTR] == np.uint64(attr)
            and key[K_INSTANCE] == np.uint64(instance))


@njit(cache=True, inline="always")
def row_matches(keys_addr, configs_addr, r, model, attr, instance):
    """Whether row r holds this model instance: key words equal, config bytes unchanged."""
    if not keys_match(keys_addr, r, model, attr, instance):
        return False
    nbytes = u64_array(keys_addr + 8 * NKEY * r, NKEY)[K_LEN]
    nwords = (nbytes + 7) // 8
    live = u64_array(attr, nwords)  # the last word may read up to 7 bytes past the config
    kept = u64_array(configs_addr + 8 * CONFIG_WORDS * r, nwords)
    diff = np.uint64(0)
    for i in range(nwords - 1):
        diff |= live[i] ^ kept[i]
    tail = nbytes - 8 * (nwords - 1)  # 1..8 bytes of the last word belong to the config
    mask = np.uint64(0xFFFFFFFFFFFFFFFF) >> np.uint64(64 - 8 * tail)
    return (diff | ((live[nwords - 1] ^ kept[nwords - 1]) & mask)) == 0


@njit(cache=True)
def find_row(keys_addr, configs_addr, model, attr, instance):
    """Row holding this model instance's parameters, or -1 if it was never registered."""
    for r in range(CAPACITY):
        if row_matches(keys_addr, configs_addr, r, model, attr, instance):
            return r
    return -1
