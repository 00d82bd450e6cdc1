"""The scene file format: obstacle tables (:mod:`previewctl.scene.schema`) into obstacles and motions.

A scene file holds ``[[obstacles]]`` tables (the same tables as a scenario file's), e.g.::

    [[obstacles]]
    name = "ball"
    shape = "sphere"
    radius = 0.1
    position = [0.4, 0.5, 0.0]
    # or, moving: motion = { type = "periodic", center = [0.4, 0, 0.3], amplitude = [0, 0.1, 0], period = 4.0 }

Every error is a :class:`~previewctl.errors.SceneError` naming the bad key (``obstacles[1].motion.period``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from previewctl.errors import SceneError
from previewctl.scene.motion import (
    ConstantVelocity,
    Motion,
    Periodic,
    RandomWalk,
    SpeedChange,
    Static,
    Turn,
    Waypoints,
    rpy_to_matrix,
)
from previewctl.scene.schema import SHAPES, MotionTable, SceneFile
from previewctl.scene.shapes import Obstacle, Scene
from previewctl.validation import validate
from previewctl.validation.toml import read_toml


def motion_from_table(spec: Any, where: str) -> Motion:
    """The motion a validated motion table describes; ``where`` (``"obstacles[2].motion"``) prefixes messages.

    Raises:
        SceneError: a value the motion rejects (e.g. a period <= 0, times not increasing).
    """
    rotation = rpy_to_matrix(spec.rpy)
    try:
        if spec.type == "static":
            return Static(spec.position, rotation)
        if spec.type == "constant_velocity":
            return ConstantVelocity(spec.position, spec.velocity, rotation, spec.start_time)
        if spec.type == "waypoints":
            return Waypoints(spec.times, spec.positions, rotation, spec.loop)
        if spec.type == "periodic":
            return Periodic(spec.center, spec.amplitude, spec.period, spec.phase, rotation)
        if spec.type == "turn":
            return Turn(spec.position, spec.velocity, spec.turn_time, spec.angle, spec.rate, spec.axis, rotation)
        if spec.type == "stop":
            return SpeedChange(spec.position, spec.velocity, spec.stop_time, 0.0, spec.braking_time, rotation)
        if spec.type == "speed_change":
            return SpeedChange(spec.position, spec.velocity, spec.change_time, spec.factor, spec.ramp_time, rotation)
        return RandomWalk(spec.position, spec.center, spec.half_size, spec.speed, spec.seed, spec.velocity,
                          spec.correlation_time, spec.duration, spec.step, rotation)
    except SceneError as exc:  # the motions' messages start with the key, e.g. "period must be > 0"
        raise SceneError(f"{where}.{exc}") from exc


def motion_from_dict(spec: Mapping[str, object], where: str) -> Motion:
    """Build a motion from a TOML-like table, e.g. ``{"type": "static", "position": [0.3, 0.2, 0.0]}``.

    Keys per ``type`` (:class:`~previewctl.scene.schema.StaticTable` and its siblings; ``rpy``
    [rad] is optional for each): ``static``: ``position``; ``constant_velocity``: ``position``,
    ``velocity``, ``start_time = 0``; ``waypoints``: ``times``, ``positions``, ``loop = false``;
    ``periodic``: ``center``, ``amplitude``, ``period``, ``phase = 0``; ``turn``: ``position``, ``velocity``,
    ``turn_time``, ``angle``, ``rate = None`` (at once), ``axis = [0, 0, 1]``; ``stop``: ``position``, ``velocity``,
    ``stop_time``, ``braking_time = 0``; ``speed_change``: ``position``, ``velocity``, ``change_time``, ``factor``,
    ``ramp_time = 0``; ``random_walk``: ``position``, ``center``, ``half_size``, ``speed``, ``seed``,
    ``velocity = 0``, ``correlation_time = 1``, ``duration = 60``, ``step = 0.05``. Vectors may have 2 entries
    (planar scenes; ``z = 0``).

    Args:
        spec: the table.
        where: its dotted key, the prefix of every message (e.g. ``"obstacles[2].motion"``).

    Raises:
        SceneError: an unknown or missing ``type`` or key, a value of the wrong type or a bad value;
            the message names ``where.key``, the value and the valid choices.
    """
    return motion_from_table(validate(MotionTable, spec, SceneError, where=where), where)


def obstacle_from_table(spec: Any, where: str, base_dir: Path) -> Obstacle:
    """The obstacle a validated obstacle table describes (relative mesh paths resolve against ``base_dir``)."""
    kind = SHAPES[spec.shape]
    values = {f.name: getattr(spec, f.name) for f in dataclasses.fields(kind)}
    if spec.shape in ("halfspace", "plane"):
        normal = np.array(spec.normal)
        values["normal"] = tuple(float(v) for v in normal / np.linalg.norm(normal))
    if spec.shape == "mesh":
        resolved = Path(spec.path) if Path(spec.path).is_absolute() else base_dir / spec.path
        if not resolved.is_file():
            raise SceneError(f"{where}.path: mesh file {str(resolved)!r} does not exist")
        values["path"] = str(resolved)
    if spec.motion is not None:
        motion = motion_from_table(spec.motion, f"{where}.motion")
    else:
        motion = Static(np.array(spec.position), rpy_to_matrix(spec.rpy))
    return Obstacle(spec.name or where, kind(**values), motion, spec.work_surface)


def scene_from_tables(tables: Sequence[Any], base_dir: Path = Path(".")) -> Scene:
    """The scene of validated ``[[obstacles]]`` tables."""
    return Scene(tuple(obstacle_from_table(t, f"obstacles[{i}]", base_dir) for i, t in enumerate(tables)))


def scene_from_dict(obstacles: Sequence[Mapping[str, object]], base_dir: Path = Path(".")) -> Scene:
    """Build a scene from a list of obstacle tables (``[[obstacles]]`` in TOML).

    Raises:
        SceneError: a bad table, named by its dotted key (``obstacles[1].radius``).
    """
    return scene_from_tables(validate(SceneFile, {"obstacles": obstacles}, SceneError).obstacles, base_dir)


def load_scene(path: str | Path) -> Scene:
    """Read a scene TOML file holding ``[[obstacles]]`` tables.

    Raises:
        SceneError: missing or unreadable file, TOML syntax error, or a bad obstacle (named in the message).
    """
    file = Path(path)
    data = read_toml(file, SceneError, "scene file")
    doc = validate(SceneFile, data, SceneError, prefix=f"scene file {str(file)!r}: ", root="the scene")
    return scene_from_tables(doc.obstacles, file.parent)
