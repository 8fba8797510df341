"""Refuse work that will not fit in memory, before allocating it, with the reason in one line.

A run far too long for the machine would otherwise grow until the kernel's OOM killer ends
it (no message, no output) or the machine swaps to a halt.
"""
from __future__ import annotations

import re
from pathlib import Path

from .errors import CliError

# Copies alive at the peak beyond the counted arrays: the CSV table as Python floats, the
# Rerun columns, the plot's lines. Measured peak of 'mjjoint simulate' on the shipped arm:
# about 1.5 kB a sample with CSV, plot and .rrd, against 1.05 kB of counted arrays.
HEADROOM = 1.5


def available_bytes() -> int | None:
    """Memory the system can give without swapping (MemAvailable), or None where unknown."""
    try:
        import psutil
        return int(psutil.virtual_memory().available)
    except ImportError:
        pass
    try:
        text = Path("/proc/meminfo").read_text()
    except OSError:
        return None
    m = re.search(r"^MemAvailable:\s+(\d+)\s+kB", text, re.MULTILINE)
    return None if m is None else 1024 * int(m.group(1))


def gigabytes(n: float) -> str:
    return f"{n / 1e9:.3g} GB"


def check_fits(need: float, what: str, hint: str) -> None:
    """Raise a one-line error if ``need`` bytes exceed the memory available now."""
    have = available_bytes()
    if have is not None and not need <= have:  # 'not <=' also refuses an infinite or NaN estimate
        raise CliError(f"{what} needs about {gigabytes(need)} of memory but {gigabytes(have)} "
                          f"is available; {hint}")
