"""What a simulation needs in memory, estimated before it starts, against what this machine has:
a block or region that cannot be held is refused up front, with the estimate, rather than
swapping or being killed half-way with part of its files written."""
from __future__ import annotations

import os
from pathlib import Path

from ..core.errors import InputError

GB = 1024.0 ** 3
# Share of the memory available now that a simulation may plan to use: the interpreter, GDAL's
# caches and the rest of the machine need the remainder.
USABLE_SHARE = 0.8


def available_bytes() -> float:
    """Memory this process can take now (bytes): MemAvailable of /proc/meminfo (Linux), else the
    physical memory (os.sysconf), else infinity (no refusal where it cannot be known)."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return float("inf")


def refuse_beyond_memory(estimate: float, parameter: str, what: str, available: float | None = None) -> None:
    """InputError naming ``parameter`` when ``estimate`` bytes exceed :data:`USABLE_SHARE` of the
    memory ``available`` (bytes; default :func:`available_bytes`). ``what`` says what needs it and
    how the estimate was made, e.g. '1,000 products x 2,000 tie observations (about 230 bytes
    each)'."""
    have = available_bytes() if available is None else float(available)
    if estimate > USABLE_SHARE * have:
        raise InputError(f"{parameter}: {what} needs about {estimate / GB:.1f} GB of memory, more than this machine "
                         f"can give it ({USABLE_SHARE:.0%} of the {have / GB:.1f} GB available now); simulate "
                         "fewer products or fewer points, or on a machine with more memory", parameter=parameter)
