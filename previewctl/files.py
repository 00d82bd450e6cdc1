"""Writing result files and folders completely or not at all.

Every file previewctl writes (run logs, summaries, figures, GIFs) goes through a temporary file in
the target folder and ``os.replace``: a reader sees either the old file or the complete new one,
and a failure leaves no partial file behind. A run's output folder is written the same way as a whole
(:func:`atomic_folder`): into a temporary sibling, which replaces the old folder only once complete.

Temporaries are named ``.<name>.<pid>.<random>.tmp`` (``.old`` for a folder being replaced). A process
killed with SIGKILL cannot remove its own; the next write to the same name removes those whose process is
gone, so they never pile up.
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import IO, Any

from previewctl.errors import OutputError

__all__ = ["append_line", "atomic_folder", "atomic_write", "atomic_write_bytes", "check_output_file",
           "check_output_folder", "remove_stale", "save_figure"]


def atomic_write(path: Path, write: Callable[[IO[bytes]], None]) -> None:
    """Write ``path`` through a temporary file in the same folder and ``os.replace``.

    On any failure the temporary file is removed and ``path`` is left as it was.
    """
    remove_stale(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=_prefix(path), suffix=".tmp")
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


@contextmanager
def atomic_folder(path: Path) -> Iterator[Path]:
    """Yield a new empty temporary sibling of the folder ``path`` to write into; once the block ends
    without error, it becomes ``path``, and the old ``path`` (kept until then) is removed.

    On an error the temporary folder is removed and ``path`` is left as it was. The swap is two renames
    (old folder aside, new folder in); a kill between them leaves the complete old and new folders as
    temporaries, never a mix of the two.

    Raises:
        OutputError: ``path`` is a file, or its parent cannot be created or written.
    """
    path = check_output_folder(path)
    remove_stale(path)
    try:
        tmp = Path(tempfile.mkdtemp(dir=path.parent, prefix=_prefix(path), suffix=".tmp"))
    except OSError as exc:  # the folder changed since it was checked
        raise OutputError(f"output folder {str(path)!r}: cannot write in folder {str(path.parent)!r}: "
                          f"{exc.strerror or exc}") from exc
    try:
        os.chmod(tmp, 0o755)  # mkdtemp makes it private; a result is an ordinary folder
        yield tmp
        old = Path(tempfile.mkdtemp(dir=path.parent, prefix=_prefix(path), suffix=".old"))
        if path.exists():
            os.replace(path, old)
        os.replace(tmp, path)
        shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def check_output_file(path: str | os.PathLike[str]) -> Path:
    """``path`` as a :class:`~pathlib.Path` if a file can be written there, before any work is done.

    Raises:
        OutputError: ``path`` is a folder, or its folder does not exist or is not writable.
    """
    out = Path(path)
    if out.is_dir():
        raise OutputError(f"output file {str(out)!r} is a folder; give a file name, e.g. {str(out / 'map.png')!r}")
    parent = out.parent
    if not parent.is_dir():
        raise OutputError(f"output file {str(out)!r}: folder {str(parent)!r} does not exist; create it first")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"output file {str(out)!r}: folder {str(parent)!r} is not writable")
    _probe(out, f"output file {str(out)!r}")
    return out


def check_output_folder(path: str | os.PathLike[str]) -> Path:
    """``path`` as a :class:`~pathlib.Path` if a folder can be written there (its parents are created).

    Raises:
        OutputError: ``path`` or a parent is a file, or the parent cannot be created or written.
    """
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise OutputError(f"output folder {str(out)!r} is a file; give a folder")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"output folder {str(out)!r}: cannot create {str(out.parent)!r}: {exc.strerror}") from exc
    if not os.access(out.parent, os.W_OK | os.X_OK):
        raise OutputError(f"output folder {str(out)!r}: folder {str(out.parent)!r} is not writable")
    _probe(out, f"output folder {str(out)!r}")
    return out


def _probe(path: Path, what: str) -> None:
    """Make and remove an empty temporary sibling of ``path`` (named as its temporaries are, so that a leftover is
    removed by the next write): the permission bits do not say everything (root passes ``os.access`` on a
    read-only file system, and nothing can be made under ``/proc``).

    Raises:
        OutputError: ``what`` cannot be written, with the folder and the OS's reason.
    """
    try:
        os.rmdir(tempfile.mkdtemp(dir=path.parent, prefix=_prefix(path), suffix=".tmp"))
    except OSError as exc:
        raise OutputError(f"{what}: cannot write in folder {str(path.parent)!r}: {exc.strerror or exc}") from exc


def remove_stale(path: Path) -> None:
    """Remove the temporaries of ``path`` (files or folders) left by processes that no longer run; an old
    folder set aside by a process killed in the middle of :func:`atomic_folder`'s swap is put back first."""
    pattern = re.compile(re.escape(f".{path.name}.") + r"(\d+)\.[^.]+\.(tmp|old)$")
    with suppress(OSError):
        for entry in sorted(path.parent.iterdir()):
            match = pattern.match(entry.name)
            if not match or _alive(int(match.group(1))):
                continue
            if match.group(2) == "old" and not path.exists():
                os.replace(entry, path)
            elif entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry, ignore_errors=True)
            else:
                with suppress(OSError):
                    entry.unlink()


def _prefix(path: Path) -> str:
    """Start of a temporary's name for ``path``: ``.<name>.<pid>.``."""
    return f".{path.name}.{os.getpid()}."


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (one of another user counts as running)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True
