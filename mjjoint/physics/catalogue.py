"""The joint's terms, in the order their slots and config keys take: the chapter's, then any
declared by a user.

A user term is a module that defines ``TERM = Term(...)`` (an additive term: ``physics.term``)
and, to make it a candidate of fit and diagnose, ``EFFECTS = (Effect(...), ...)``
(``identify.effect``). Its module is named in the environment variable ``MJJOINT_TERMS``
(comma-separated), read once when mjjoint is imported: the plugin's layout and kernels are
fixed from then on. Such a module imports only ``mjjoint.physics.term``, ``mjjoint.physics.jit``,
``mjjoint.identify.effect`` and its own dependencies, since it is loaded while mjjoint is.
"""
from __future__ import annotations

import importlib

from . import boucwen, friction, generic, load, ripple, transmission
from .jit import TERMS_ENV as ENV, user_term_modules
from .term import Term

BUILTIN: tuple[Term, ...] = (friction.TERM, transmission.TERM, boucwen.TERM, load.TERM, ripple.TERM,
                             generic.LINK_TERM, generic.MOTOR_TERM)


def _load(name: str):
    try:
        module = importlib.import_module(name)
    except ImportError as exc:
        raise ImportError(f"{ENV}: cannot import the term module {name!r}: {exc}") from None
    term = getattr(module, "TERM", None)
    if not isinstance(term, Term):
        raise ValueError(f"{ENV}: module {name!r} defines no TERM = Term(...)")
    if term.torque is None or term.nested_in is not None:
        raise ValueError(f"{ENV}: term {term.section!r} of {name!r} must be additive (a torque kernel, not nested)")
    return module, term


MODULES = tuple(_load(n)[0] for n in user_term_modules())
TERMS: tuple[Term, ...] = BUILTIN + tuple(m.TERM for m in MODULES)
BY_SECTION: dict[str, Term] = {t.section: t for t in TERMS}
if len(BY_SECTION) != len(TERMS):
    raise ValueError(f"{ENV}: two terms share a section name ({', '.join(t.section for t in TERMS)})")
