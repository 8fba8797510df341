"""The one error type of the recordings layer, and helpers that keep its messages short."""

from __future__ import annotations

from collections.abc import Iterable


class RecordingError(ValueError):
    """A recording file, or the options given to read it, cannot be used.

    The message is always a single line that names the file and, where relevant,
    the column and the row or value at fault.
    """

    def __init__(self, message: str) -> None:
        # Printed as one CLI line; text quoted from a corrupt file may hold line breaks.
        super().__init__(" ".join(message.splitlines()))


def quote(text: str, limit: int = 40) -> str:
    """repr() of a string taken from a file, cut short so one bad field cannot flood a message."""
    return repr(text if len(text) <= limit else text[: limit - 3] + "...")


def listing(names: Iterable[str], limit: int = 20) -> str:
    """Comma-separated quoted names, at most `limit` of them."""
    names = list(names)
    if not names:
        return "(none)"
    more = f", ... ({len(names) - limit} more)" if len(names) > limit else ""
    return ", ".join(quote(n) for n in names[:limit]) + more
