"""Diagnosing a fleet of recordings: a folder, a glob or a manifest of them, each on its own.

``inputs`` turns the argument into recordings with their per-recording options, ``task`` is
the unit of work a worker runs (one recording -> its report folder and result rows), and
``engines`` runs the tasks serially, on a local process pool or on a Dask cluster. The
command-line side is ``mjjoint.cli.fleet``; docs/fleet.md has usage and measured throughput.
"""
from .inputs import Entry, is_fleet, resolve

__all__ = ["Entry", "is_fleet", "resolve"]
