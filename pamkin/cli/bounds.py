"""Bounded requests: every size option of the command line has a documented range, and a request whose
estimated memory exceeds what this machine has is refused up front with the estimate (exit 2)."""

from __future__ import annotations

import os

from pamkin.errors import ParameterError

__all__ = ["available_memory", "check_count", "check_memory"]


def available_memory() -> int:
    """Bytes a request may use: half of this machine's physical memory (the rest for the system and numba)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") // 2
    except (ValueError, OSError, AttributeError):
        return 4 << 30


def check_count(option: str, n: int, lo: int, hi: int) -> int:
    """``n`` for ``option`` within [lo, hi], else :class:`ParameterError` naming the option and range."""
    if isinstance(n, bool) or not isinstance(n, int) or not lo <= n <= hi:
        raise ParameterError(f"{option} must be an integer in [{lo}, {hi}], got {n!r}")
    return n


def check_memory(what: str, n_items: int, bytes_per_item: int) -> None:
    """Refuse a request of ``n_items`` items of about ``bytes_per_item`` bytes each when the estimate exceeds
    :func:`available_memory`, naming the estimate."""
    need = int(n_items) * int(bytes_per_item)
    have = available_memory()
    if need > have:
        raise ParameterError(f"{what}: about {need / 2**30:.1f} GiB needed ({n_items} items), more than the "
                             f"{have / 2**30:.1f} GiB this machine allows a request; ask for fewer")
