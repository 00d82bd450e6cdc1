"""Where a result comes from: the date it was measured and the code that measured it.

Every benchmark record carries :func:`stamp` (``measured``, ``commit``), and every generated report says which
commits and dates its records span, so a number is never read without the code it came from.
"""

from __future__ import annotations

import datetime
import functools
import importlib.metadata
import subprocess
from pathlib import Path

UNKNOWN = "unknown"
"""The commit of a record made outside a git checkout, or before records carried one."""


@functools.lru_cache(maxsize=1)
def source_commit() -> str:
    """The commit of the previewctl source in use: ``<short hash>``, with ``+dirty`` when its files differ from
    that commit; outside a git checkout (an installed wheel) ``v<version>``, or :data:`UNKNOWN`."""
    root = Path(__file__).resolve().parents[2]
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "--short=7", "HEAD"], capture_output=True,
                              text=True, timeout=10, check=True).stdout.strip()
        changed = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no", "--",
                                  "previewctl"], capture_output=True, text=True, timeout=10, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        try:
            return f"v{importlib.metadata.version('previewctl')}"
        except importlib.metadata.PackageNotFoundError:
            return UNKNOWN
    return f"{head}+dirty" if changed else head


def now() -> str:
    """The current UTC time, ISO 8601 to the second (``2026-12-02T07:45:55Z``)."""
    return datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


def stamp() -> dict[str, str]:
    """The provenance fields of a record made now: ``measured`` (:func:`now`) and ``commit`` (:func:`source_commit`)."""
    return {"measured": now(), "commit": source_commit()}
