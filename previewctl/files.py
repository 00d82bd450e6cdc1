"""Writing result files completely or not at all.

Every file previewctl writes (run logs, summaries, figures, GIFs) goes through a temporary file in
the target folder and ``os.replace``: a reader sees either the old file or the complete new one,
and a failure leaves no partial file behind.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from contextlib import suppress
from pathlib import Path
from typing import IO, Any

__all__ = ["append_line", "atomic_write", "atomic_write_bytes", "save_figure"]


def atomic_write(path: Path, write: Callable[[IO[bytes]], None]) -> None:
    """Write ``path`` through a temporary file in the same folder and ``os.replace``.

    On any failure the temporary file is removed and ``path`` is left as it was.
    """
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        os.chmod(tmp, 0o644)  # mkstemp makes it private; a result is an ordinary file
        with os.fdopen(fd, "wb") as handle:
            write(handle)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        with suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def atomic_write_bytes(path: Path, payload: bytes) -> None:
    """:func:`atomic_write` of ``payload``."""

    def write(handle: IO[bytes]) -> None:
        handle.write(payload)

    atomic_write(path, write)


def append_line(path: Path, line: str) -> None:
    """Append ``line`` (without its newline) and a newline to ``path`` in one write, then ``fsync``.

    A log of records (JSON Lines) grows this way: a crash leaves at most a torn last line, and the next
    append starts on a new line so that every line written whole stays whole.
    """
    payload = line.rstrip("\n").encode("utf-8") + b"\n"
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_APPEND, 0o644)
    try:
        size = os.fstat(fd).st_size
        if size and os.pread(fd, 1, size - 1) != b"\n":
            payload = b"\n" + payload
        while payload:
            payload = payload[os.write(fd, payload):]
        os.fsync(fd)
    finally:
        os.close(fd)


def save_figure(fig: Any, path: str | os.PathLike[str], **options: Any) -> Path:
    """Save a matplotlib figure atomically; the format follows the suffix (PNG without one).

    Args:
        fig: the figure (it stays open: closing it is the caller's ``finally``).
        path: the file.
        **options: ``Figure.savefig`` options (``dpi``, ``bbox_inches``, ...).

    Returns:
        ``path`` as a :class:`~pathlib.Path`.
    """
    out = Path(path)
    fmt = out.suffix.lstrip(".").lower() or "png"
    atomic_write(out, lambda handle: fig.savefig(handle, format=fmt, **options))
    return out
