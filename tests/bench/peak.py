"""Peak resident memory of a benchmark's stage: reset the peak before it, read it after.

VmHWM (/proc/self/status) is the peak that /proc/self/clear_refs resets (Linux >= 4.0);
ru_maxrss is not reset by it, and in a process started by fork and exec it keeps the parent's
resident size at the fork.
"""
from __future__ import annotations

import resource
from pathlib import Path


def peak_mb() -> float:
    """Peak resident memory of this process (MB) since the last :func:`reset_peak`."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024.0
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def reset_peak() -> bool:
    """Reset the peak resident memory to the present one; False where that is not possible."""
    try:
        Path("/proc/self/clear_refs").write_text("5")
        return True
    except OSError:
        return False
