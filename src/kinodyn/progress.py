"""Progress bars for long work: shown on a terminal, silent otherwise (CI logs, pipes, tests)."""

from __future__ import annotations

import sys

__all__ = ["progress"]


def progress(iterable=None, total: int | None = None, desc: str = "", enabled: bool | None = None):
    """A tqdm bar over ``iterable`` when stderr is a terminal (or ``enabled`` is True), else the iterable.

    Returns an object with ``update(n)`` and ``close()`` either way, so callers need not branch.
    """
    if enabled is None:
        enabled = sys.stderr.isatty()
    from tqdm.auto import tqdm

    return tqdm(iterable, total=total, desc=desc, disable=not enabled, leave=False, dynamic_ncols=True)
