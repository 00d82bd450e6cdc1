"""``visualization_msgs/Marker`` to observations: what one marker on ``~/obstacles`` asks of the controller.

A marker is named ``"<ns>/<id>"``. Its action:

* ``ADD`` (= ``MODIFY``): an observation of that obstacle, at the marker's pose, made at its header's stamp;
  ``SPHERE`` (radius: half the largest of ``scale``, so an ellipsoid is covered), ``CUBE`` (edges ``scale``) and
  ``CYLINDER`` (radius: half the larger of ``scale.x``, ``scale.y``; length ``scale.z``; axis z) are obstacles;
* ``DELETE``: forget that obstacle;
* ``DELETEALL``: forget every observed obstacle.

Anything else (another marker type or action, a pose that is not finite, a quaternion of zero length, a scale that
makes no shape) raises :class:`~previewctl.errors.ObservationError`, which the node reports on ``~/status``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from previewctl.errors import ObservationError, SceneError
from previewctl.scene.shapes import Box, Cylinder, Sphere
from previewctl.types import Array

SPHERE, CUBE, CYLINDER = 2, 1, 3
"""The ``visualization_msgs/Marker`` types that are obstacles."""
ADD, DELETE, DELETEALL = 0, 2, 3
"""The ``visualization_msgs/Marker`` actions honoured (``MODIFY`` is ``ADD``)."""
TYPES = {SPHERE: "SPHERE", CUBE: "CUBE", CYLINDER: "CYLINDER"}
ACTIONS = {ADD: "ADD", DELETE: "DELETE", DELETEALL: "DELETEALL"}


@dataclass(frozen=True)
class Observe:
    """An observation of obstacle ``name``: ``position`` ``(3,)`` [m], ``rotation`` ``(3, 3)``, its shape, and
    ``stamp``, the time it was made [s] on the sender's clock (0: not given)."""

    name: str
    position: Array
    rotation: Array
    shape: Sphere | Box | Cylinder
    stamp: float


@dataclass(frozen=True)
class Forget:
    """Forget obstacle ``name`` (``DELETE``)."""

    name: str


@dataclass(frozen=True)
class ForgetAll:
    """Forget every observed obstacle (``DELETEALL``)."""


Request = Observe | Forget | ForgetAll


def marker_name(marker: Any) -> str:
    """``"<ns>/<id>"`` of a ``visualization_msgs/Marker``."""
    return f"{marker.ns}/{marker.id}"


def request_of(marker: Any) -> Request:
    """What a ``visualization_msgs/Marker`` asks (module docstring).

    Raises:
        ObservationError: an unknown type or action, a pose that is not finite, a zero quaternion or a scale that
            makes no shape; the message names the marker and the bad value.
    """
    name = marker_name(marker)
    if marker.action == DELETEALL:
        return ForgetAll()
    if marker.action == DELETE:
        return Forget(name)
    if marker.action != ADD:
        raise ObservationError(f"marker {name!r}: unknown action {marker.action}; valid: "
                               + ", ".join(f"{text} ({code})" for code, text in ACTIONS.items()))
    pose = marker.pose
    position = np.array([pose.position.x, pose.position.y, pose.position.z], dtype=float)
    if not np.all(np.isfinite(position)):
        raise ObservationError(f"marker {name!r}: position {position.tolist()} [m] is not finite")
    stamp = marker.header.stamp
    return Observe(name, position, _rotation(name, pose.orientation), _shape(name, marker),
                   stamp.sec + 1e-9 * stamp.nanosec)


def _rotation(name: str, q: Any) -> Array:
    """The rotation matrix of quaternion ``q`` (normalised); a zero or non-finite one is refused."""
    w, x, y, z = q.w, q.x, q.y, q.z
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    if not math.isfinite(norm) or norm < 1e-9:
        raise ObservationError(f"marker {name!r}: orientation (x, y, z, w) = ({x}, {y}, {z}, {w}) is not a rotation "
                               "(zero or not finite)")
    w, x, y, z = w / norm, x / norm, y / norm, z / norm
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def _shape(name: str, marker: Any) -> Sphere | Box | Cylinder:
    """The obstacle shape of a marker's type and scale."""
    sx, sy, sz = marker.scale.x, marker.scale.y, marker.scale.z
    try:
        if marker.type == SPHERE:
            return Sphere(max(sx, sy, sz) / 2)
        if marker.type == CUBE:
            return Box((sx, sy, sz))
        if marker.type == CYLINDER:
            return Cylinder(max(sx, sy) / 2, sz)
    except SceneError as exc:
        raise ObservationError(f"marker {name!r}: scale ({sx}, {sy}, {sz}) [m] makes no {TYPES[marker.type]}: "
                               f"{exc}") from exc
    raise ObservationError(f"marker {name!r}: type {marker.type} is not an obstacle; valid: "
                           + ", ".join(f"{text} ({code})" for code, text in TYPES.items()))
