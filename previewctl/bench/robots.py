"""The robots of a sweep: a robot name or a URDF file, as the results record it, the workers load it and its scenes
are named, seeded and drawn.

A robot is recorded by its *source*, the string :func:`~previewctl.index.load.load_robot` takes: a robot name
(``planar4``, ``panda``, any arm ``previewctl robots`` lists) as given, a URDF file as its absolute path, so a rerun
from any folder, and every Dask worker, finds it. A file also has a *label*, its stem and the first 8 hex digits of
the SHA-256 of its content (``arm7-1a2b3c4d``); a name is its own label. The scene names, the kept runs' folders and
the scenes' random stream use the label, so a moved or copied file draws the same scenes; the content hash enters
the settings hash too (:func:`~previewctl.bench.runs.settings_hash`), so results of an edited URDF never count for
the new one. The results are keyed by the source: the runs of a moved file are run again (on the same scenes).
"""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path

from previewctl.bench.profiles import PROFILES, Profile, derived_profile
from previewctl.errors import RobotLoadError, UnknownNameError
from previewctl.index.load import example_robot_names, load_robot, shipped_robot_names, urdf_path
from previewctl.robot.model import Robot

VALID_ROBOTS = (*PROFILES, "a URDF file", "any arm `previewctl robots --all` lists")
"""What ``--robot`` takes, as an error message lists it."""


def bench_source(text: str) -> str:
    """The source of the robot ``text`` names: a robot name as it is, a URDF file as its absolute path.

    Raises:
        RobotLoadError: a path that is not a file.
        UnknownNameError: neither a path nor a robot name (:data:`VALID_ROBOTS` listed).
    """
    path = urdf_path(text)
    if path is None:
        if text in PROFILES or text in shipped_robot_names() or text in example_robot_names():
            return text
        raise UnknownNameError("robot", text, VALID_ROBOTS)
    if not path.is_file():
        raise RobotLoadError(f"URDF file {text!r} does not exist; valid: {', '.join(VALID_ROBOTS)}")
    return str(path.resolve())


def urdf_digest(source: str) -> str | None:
    """The first 12 hex digits of the SHA-256 of the URDF file ``source`` (``None`` for a robot name); read again
    only when the file's size or modification time changes.

    Raises:
        RobotLoadError: the file cannot be read.
    """
    path = urdf_path(source)
    if path is None:
        return None
    try:
        stat = path.stat()
    except OSError as exc:
        raise RobotLoadError(f"URDF file {str(path)!r} cannot be read: {exc}") from exc
    return _digest(path, stat.st_size, stat.st_mtime_ns)


@functools.lru_cache(maxsize=16)
def _digest(path: Path, size: int, mtime_ns: int) -> str:
    """The digest of :func:`urdf_digest`, once per file version."""
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()[:12]
    except OSError as exc:
        raise RobotLoadError(f"URDF file {str(path)!r} cannot be read: {exc}") from exc


def robot_label(source: str) -> str:
    """The name of ``source`` in scene names and folders: a robot name, or a file's stem and content hash."""
    digest = urdf_digest(source)
    return source if digest is None else f"{Path(source).stem}-{digest[:8]}"


@functools.lru_cache(maxsize=8)
def cached_robot(source: str, geometry: str = "convex") -> Robot:
    """``load_robot(source, geometry=...)``, once per process (robots are not pickled between workers)."""
    return load_robot(source, geometry=geometry)  # type: ignore[arg-type]


@functools.lru_cache(maxsize=8)
def profile(source: str) -> Profile:
    """The profile of the robot ``source``: its hand-written one, else one derived from the arm
    (:func:`~previewctl.bench.profiles.derived_profile`).

    Raises:
        RobotLoadError: a robot that does not load as an arm.
        ParameterError: an arm a profile cannot be derived for.
    """
    return PROFILES[source] if source in PROFILES else derived_profile(cached_robot(source))
