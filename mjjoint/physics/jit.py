"""How every physics kernel is compiled, and where numba caches it."""
import hashlib
import importlib.util
import os
import warnings
from pathlib import Path

import numba
from numba import njit
from numba.core.errors import NumbaExperimentalFeatureWarning

# Cached, so CI and users compile once. numpy's error model: a division by zero yields inf/nan
# instead of raising. The parameter dataclasses rule such divisions out up front, and the
# per-division check with its exception path cost 40 % of the 2SEP state update per step.
kernel = njit(cache=True, error_model="numpy")
TERMS_ENV = "MJJOINT_TERMS"

# The kernels unroll tuples of the terms' kernels (coupling.kernels), which numba types with its
# first-class function feature and then inlines: the warning says nothing a user can act on.
warnings.filterwarnings("ignore", message="First-class function type", category=NumbaExperimentalFeatureWarning)

_PACKAGE = Path(__file__).resolve().parent.parent
# The sources the kernels' constants come from: the terms' declarations and the layout derived
# from them (numba's cache tracks only a kernel's own file).
_LAYOUT_SOURCES = sorted([*(_PACKAGE / "physics").glob("*.py"), *(_PACKAGE / "coupling").glob("*.py"),
                          _PACKAGE / "joint.py"])


def user_term_modules() -> list[str]:
    """The user term modules the environment names (``physics.catalogue``)."""
    return [n.strip() for n in os.environ.get(TERMS_ENV, "").split(",") if n.strip()]


def _term_set_key(names: list[str]) -> str:
    """A key of the sources that fix the kernels' layout: mjjoint's term and layout modules and
    the user term modules (names and contents)."""
    h = hashlib.sha1()
    for path in _LAYOUT_SOURCES:
        h.update(path.name.encode() + path.read_bytes())
    for name in names:
        try:
            spec = importlib.util.find_spec(name)
        except (ImportError, ValueError):  # physics.catalogue reports the bad module in one line
            spec = None
        origin = spec.origin if spec is not None and spec.origin else ""
        h.update(name.encode() + (Path(origin).read_bytes() if os.path.isfile(origin) else b""))
    return h.hexdigest()[:16]


# Composed kernels bake the term set and the layout in, so the cache lives in a folder of that key.
numba.config.CACHE_DIR = os.path.join(
    numba.config.CACHE_DIR or os.path.join(os.path.expanduser("~"), ".cache", "mjjoint", "numba"),
    f"terms-{_term_set_key(user_term_modules())}")
