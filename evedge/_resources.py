"""How much memory a run may take: the machine's available memory and the process limit.

Work that allocates in proportion to a parameter or a size declared in a file
is estimated first and compared with :func:`available_memory_bytes`, so a
mistake gives a clear error instead of an OOM kill or a ``MemoryError``
traceback half-way through.
"""

from __future__ import annotations

import os
import resource

#: Share of the available memory one run may plan to use (the rest is for the
#: interpreter, libraries and estimates that are low).
BUDGET_FRACTION = 0.8


def _meminfo_available() -> int | None:
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def _address_space_left() -> int | None:
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft == resource.RLIM_INFINITY:
        return None
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmSize:"):
                    return max(0, soft - int(line.split()[1]) * 1024)
    except (OSError, ValueError, IndexError):
        return None
    return soft


def available_memory_bytes() -> int:
    """Bytes this process can still allocate: the smaller of free RAM and its address-space limit.

    Returns
    -------
    int
        ``MemAvailable`` of ``/proc/meminfo`` (else total physical memory),
        capped by what ``RLIMIT_AS`` leaves.

    Examples
    --------
    >>> available_memory_bytes() > 0
    True
    """
    free = _meminfo_available()
    if free is None:
        try:
            free = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
        except (ValueError, OSError):
            free = 2**63 - 1
    left = _address_space_left()
    return free if left is None else min(free, left)


def memory_shortfall(needed_bytes: float, what: str) -> str | None:
    """A message when ``needed_bytes`` exceed the run's budget, else None.

    Parameters
    ----------
    needed_bytes : float
        Estimated peak allocation.
    what : str
        What needs it, for the message (``"5000 edge frames of 240x180"``).

    Returns
    -------
    str or None
        ``"<what> needs about X GiB; this machine has Y GiB available"``.

    Examples
    --------
    >>> memory_shortfall(1e3, "a tiny array") is None
    True
    >>> memory_shortfall(1e20, "a huge array").startswith("a huge array needs about")
    True
    """
    budget = BUDGET_FRACTION * available_memory_bytes()
    if needed_bytes <= budget:
        return None
    return (f"{what} needs about {needed_bytes / 2**30:.3g} GiB; this machine has "
            f"{available_memory_bytes() / 2**30:.3g} GiB available")
