"""The Python face of ``mjjoint fit`` and ``mjjoint diagnose``: one call each, a recording in,
typed results out (``mjjoint.fit``, ``mjjoint.diagnose``)."""
from .diagnose import diagnose
from .fit import fit

__all__ = ["diagnose", "fit"]
