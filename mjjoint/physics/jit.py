"""How every physics kernel is compiled."""
import hashlib
import importlib.util
import os

import warnings

import numba
from numba import njit
from numba.core.errors import NumbaExperimentalFeatureWarning

# The kernels unroll tuples of the terms' kernels (coupling.kernels), which numba types with its
# first-class function feature and then inlines: the warning says nothing a user can act on.
warnings.filterwarnings("ignore", message="First-class function type", category=NumbaExperimentalFeatureWarning)

# Cached, so CI and users compile once. numpy's error model: a division by zero yields inf/nan
# instead of raising. The parameter dataclasses rule such divisions out up front, and the
# per-division check with its exception path cost 40 % of the 2SEP state update per step.
kernel = njit(cache=True, error_model="numpy")
TERMS_ENV = "MJJOINT_TERMS"


def _term_set_key(names: list[str]) -> str:
    """A key of the user term modules (names and source stamps): kernels composed over the terms
    (``coupling.kernels``) bake the term set in, which numba's cache does not track."""
    h = hashlib.sha1()
    for name in names:
        spec = importlib.util.find_spec(name)
        origin = spec.origin if spec is not None and spec.origin else ""
        stamp = os.stat(origin) if os.path.isfile(origin) else None
        h.update(f"{name}:{origin}:{stamp.st_mtime_ns if stamp else 0}:{stamp.st_size if stamp else 0};".encode())
    return h.hexdigest()[:16]


def user_term_modules() -> list[str]:
    """The user term modules the environment names (``physics.catalogue``)."""
    return [n.strip() for n in os.environ.get(TERMS_ENV, "").split(",") if n.strip()]


# With user terms (physics.catalogue) the compiled kernels go to a cache of that term set.
_user = user_term_modules()
if _user:
    try:
        _key = _term_set_key(_user)
    except (ImportError, ValueError):  # physics.catalogue reports the bad module in one line
        _key = "unresolved"
    numba.config.CACHE_DIR = os.path.join(
        numba.config.CACHE_DIR or os.path.join(os.path.expanduser("~"), ".cache", "numba"), f"mjjoint-terms-{_key}")
