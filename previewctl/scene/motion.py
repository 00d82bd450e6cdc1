"""Obstacle motions: where an obstacle is, and how it is turned, at any time.

Every motion gives the obstacle's placement at time ``t`` [s] as ``(position (3,), rotation
(3, 3))``. All motions here keep a fixed rotation; only the position changes. Positions (and
velocities, amplitudes, centres) may be given with 2 entries for planar scenes, in which case
``z = 0`` is appended.

:func:`previewctl.scene.file.motion_from_dict` builds a motion from a TOML-like table, e.g.
``{"type": "periodic", "center": [0.4, 0, 0.3], "amplitude": [0, 0.1, 0], "period": 4.0}``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from previewctl.errors import SceneError
from previewctl.validation import check_finite, real_array, real_scalar, rotation_matrix, show


@runtime_checkable
class Motion(Protocol):
    """Anything that places an obstacle in space as a function of time."""

    def placement(self, t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Placement at time ``t`` [s]: ``(position (3,) [m], rotation (3, 3))``, fresh copies."""
        ...

    def positions(self, times: ArrayLike) -> NDArray[np.float64]:
        """Positions at times of shape (T,) [s], as an array of shape (T, 3) [m]."""
        ...


@runtime_checkable
class Uncertain(Protocol):
    """A motion that is a prediction (:mod:`previewctl.sensing`): the distance computations
    (:class:`~previewctl.scene.clearance.Clearance`, the planar path of the evaluator) inflate its obstacle by
    :meth:`margin`, and read its state again whenever :attr:`revision` changes (a new observation)."""

    @property
    def revision(self) -> int:
        """A number that changes whenever the prediction does."""
        ...

    def margin(self, times: ArrayLike) -> NDArray[np.float64]:
        """How much the obstacle is inflated at times ``(T,)`` [s]: ``(T,)`` [m], >= 0."""
        ...


def margin_at(motion: Motion, t: float) -> float:
    """The inflation [m] of an obstacle with ``motion`` at time ``t`` [s]: an :class:`Uncertain` motion's margin, else
    0."""
    return float(motion.margin(np.array([t]))[0]) if isinstance(motion, Uncertain) else 0.0


# ----------------------------------------------------------------------------- validation


def _real_array(value: object, name: str) -> NDArray[np.float64]:
    return real_array(value, name, SceneError)


def _check_finite(array: NDArray[np.float64], name: str) -> None:
    check_finite(array, name, SceneError)


def _scalar(value: object, name: str) -> float:
    return real_scalar(value, name, SceneError)


def _frozen(array: NDArray[np.float64]) -> NDArray[np.float64]:
    """Mark ``array`` read-only and return it."""
    array.flags.writeable = False
    return array


def _points(value: object, name: str, *, single: bool, flat: list[str] | None = None) -> NDArray[np.float64]:
    """Validate a 3-vector (``single``) or a (K, 3) array; 2-entry rows get ``z = 0`` (and ``name`` is appended
    to ``flat``: the motion remembers it, see :func:`planar_fields`).

    Returns:
        A fresh float64 array of shape (3,) or (K, 3) with K >= 1.
    """
    array = _real_array(value, name)
    if single:
        if array.ndim != 1 or array.shape[0] not in (2, 3):
            raise SceneError(f"{name} must have 2 or 3 entries, got shape {array.shape}: {show(array)}")
    elif array.ndim != 2 or array.shape[0] < 1 or array.shape[1] not in (2, 3):
        raise SceneError(
            f"{name} must have shape (K, 2) or (K, 3) with K >= 1, got shape {array.shape}: {show(array)}"
        )
    _check_finite(array, name)
    if array.shape[-1] == 2:
        if flat is not None:
            flat.append(name)
        array = np.concatenate((array, np.zeros((*array.shape[:-1], 1))), axis=-1)
    return array


def _rotation(value: object, name: str = "rotation") -> NDArray[np.float64]:
    """Validate a rotation matrix (shape (3, 3), orthonormal, det +1) and return a copy."""
    return rotation_matrix(value, name, SceneError)


def _time(t: object) -> float:
    """Validate a single evaluation time [s]."""
    if isinstance(t, np.ndarray) and t.ndim == 0:
        t = t[()]
    return _scalar(t, "t")


def _times(times: ArrayLike) -> NDArray[np.float64]:
    """Validate evaluation times: a finite array of shape (T,) [s]."""
    array = _real_array(times, "times")
    if array.ndim != 1:
        raise SceneError(f"times must have shape (T,), got shape {array.shape}: {show(array)}")
    _check_finite(array, "times")
    return array


def _identity() -> NDArray[np.float64]:
    """Default rotation: the identity."""
    return np.eye(3)


def planar_fields(motion: Motion) -> tuple[str, ...]:
    """The fields of ``motion`` given with 2 entries (padded with ``z = 0``: written for a planar arm), e.g.
    ``("position",)``; ``()`` for a motion given in 3-D or one defined outside this module."""
    flat = getattr(motion, "_planar_fields", ())
    return flat if isinstance(flat, tuple) else ()


class _Placed:
    """Shared behaviour: ``placement`` from ``positions`` plus the fixed ``rotation``; ``_planar_fields`` names
    the fields given with 2 entries (:func:`planar_fields`)."""

    rotation: NDArray[np.float64]
    _planar_fields: tuple[str, ...] = ()

    def _points(self, name: str, *, single: bool = True) -> None:
        """Validate and freeze field ``name`` (:func:`_points`), remembering whether it had 2 entries."""
        flat = list(self._planar_fields)
        object.__setattr__(self, name, _frozen(_points(getattr(self, name), name, single=single, flat=flat)))
        object.__setattr__(self, "_planar_fields", tuple(flat))

    def positions(self, times: ArrayLike) -> NDArray[np.float64]:  # pragma: no cover
        """Positions at times of shape (T,) [s], shape (T, 3) [m]."""
        raise NotImplementedError

    def placement(self, t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Placement at time ``t``.

        Args:
            t: Time [s].

        Returns:
            ``(position, rotation)``: position, shape (3,) [m], and rotation, shape (3, 3);
            fresh arrays that do not alias the motion's state.

        Raises:
            SceneError: If ``t`` is not a finite real number.
        """
        position = self.positions(np.array([_time(t)]))[0]
        return position, self.rotation.copy()


# ----------------------------------------------------------------------------- motions


@dataclass(frozen=True, eq=False)
class Static(_Placed):
    """An obstacle that does not move.

    Attributes:
        position: Position, shape (3,) [m] (2 entries are padded with z = 0). Read-only.
        rotation: Rotation matrix, shape (3, 3). Read-only.
    """

    position: NDArray[np.float64]
    rotation: NDArray[np.float64] = field(default_factory=_identity)

    def __post_init__(self) -> None:
        """Validate and freeze the fields.

        Raises:
            SceneError: If a field is malformed; the message names the bad value.
        """
        self._points("position")
        object.__setattr__(self, "rotation", _frozen(_rotation(self.rotation)))

    def positions(self, times: ArrayLike) -> NDArray[np.float64]:
        """Positions at the given times.

        Args:
            times: Times, shape (T,) [s].

        Returns:
            Positions, shape (T, 3) [m]; a fresh array.
        """
        return np.tile(self.position, (_times(times).shape[0], 1))


@dataclass(frozen=True, eq=False)
class ConstantVelocity(_Placed):
    """An obstacle moving in a straight line: ``p(t) = position + velocity (t - start_time)``.

    Before ``start_time`` the obstacle stays at ``position``.

    Attributes:
        position: Position at ``start_time``, shape (3,) [m]. Read-only.
        velocity: Velocity, shape (3,) [m/s]. Read-only.
        rotation: Rotation matrix, shape (3, 3). Read-only.
        start_time: Time the motion starts [s].
    """

    position: NDArray[np.float64]
    velocity: NDArray[np.float64]
    rotation: NDArray[np.float64] = field(default_factory=_identity)
    start_time: float = 0.0

    def __post_init__(self) -> None:
        """Validate and freeze the fields.

        Raises:
            SceneError: If a field is malformed; the message names the bad value.
        """
        self._points("position")
        self._points("velocity")
        object.__setattr__(self, "rotation", _frozen(_rotation(self.rotation)))
        object.__setattr__(self, "start_time", _scalar(self.start_time, "start_time"))

    def positions(self, times: ArrayLike) -> NDArray[np.float64]:
        """Positions at the given times.

        Args:
            times: Times, shape (T,) [s].

        Returns:
            Positions, shape (T, 3) [m]; a fresh array.
        """
        elapsed = np.maximum(_times(times) - self.start_time, 0.0)
        return self.position + elapsed[:, None] * self.velocity


@dataclass(frozen=True, eq=False)
class Waypoints(_Placed):
    """An obstacle moving linearly between timed positions.

    Without ``loop`` the obstacle holds ``waypoints[0]`` before ``times[0]`` and
    ``waypoints[-1]`` after ``times[-1]``. With ``loop`` the motion is extended periodically
    (in both directions) with period ``times[-1] - times[0]``; at each wrap it returns to
    ``waypoints[0]`` (it jumps there unless ``waypoints[-1] == waypoints[0]``).

    Attributes:
        times: Strictly increasing times, shape (K,) [s], K >= 1 (K >= 2 with ``loop``).
            Read-only.
        waypoints: Positions at ``times``, shape (K, 3) [m] (2 columns are padded with z = 0).
            Read-only. (Named ``waypoints``, not ``positions``, because ``positions`` is the
            evaluation method every :class:`Motion` has.)
        rotation: Rotation matrix, shape (3, 3). Read-only.
        loop: Whether the motion repeats.
    """

    times: NDArray[np.float64]
    waypoints: NDArray[np.float64]
    rotation: NDArray[np.float64] = field(default_factory=_identity)
    loop: bool = False

    def __post_init__(self) -> None:
        """Validate and freeze the fields.

        Raises:
            SceneError: If a field is malformed; the message names the bad value.
        """
        times = _real_array(self.times, "times")
        if times.ndim != 1 or times.shape[0] < 1:
            raise SceneError(f"times must have shape (K,) with K >= 1, got shape {times.shape}: {show(times)}")
        _check_finite(times, "times")
        steps = np.diff(times)
        if np.any(steps <= 0.0):
            i = int(np.argmax(steps <= 0.0))
            raise SceneError(
                f"times must be strictly increasing, but times[{i}] = {float(times[i])!r} and "
                f"times[{i + 1}] = {float(times[i + 1])!r} (in times = {show(times)})"
            )
        self._points("waypoints", single=False)
        points = self.waypoints
        if points.shape[0] != times.shape[0]:
            raise SceneError(
                f"waypoints must have one row per time: got {points.shape[0]} rows for "
                f"{times.shape[0]} times (times = {show(times)})"
            )
        if not isinstance(self.loop, (bool, np.bool_)):
            raise SceneError(f"loop must be true or false, got {show(self.loop)}")
        if self.loop and times.shape[0] < 2:
            raise SceneError(f"loop needs at least 2 times (a period > 0), got times = {show(times)}")
        object.__setattr__(self, "times", _frozen(times))
        object.__setattr__(self, "rotation", _frozen(_rotation(self.rotation)))
        object.__setattr__(self, "loop", bool(self.loop))

    @property
    def period(self) -> float | None:
        """Repeat period ``times[-1] - times[0]`` [s] if ``loop``, else ``None``."""
        return float(self.times[-1] - self.times[0]) if self.loop else None

    def positions(self, times: ArrayLike) -> NDArray[np.float64]:
        """Positions at the given times.

        Args:
            times: Times, shape (T,) [s].

        Returns:
            Positions, shape (T, 3) [m]; a fresh array.
        """
        query = _times(times)
        if self.loop:
            period = float(self.times[-1] - self.times[0])
            phase = np.mod(query - self.times[0], period)
            phase[phase >= period] = 0.0  # np.mod may round a tiny negative up to the period
            query = self.times[0] + phase
        return np.stack([np.interp(query, self.times, self.waypoints[:, axis]) for axis in range(3)], axis=1)


@dataclass(frozen=True, eq=False)
class Periodic(_Placed):
    """An obstacle oscillating: ``p(t) = center + amplitude * sin(2 pi t / period + phase)``.

    Attributes:
        center: Centre of the oscillation, shape (3,) [m]. Read-only.
        amplitude: Amplitude per axis, shape (3,) [m]. Read-only.
        period: Period [s], > 0.
        phase: Phase at ``t = 0`` [rad].
        rotation: Rotation matrix, shape (3, 3). Read-only.
    """

    center: NDArray[np.float64]
    amplitude: NDArray[np.float64]
    period: float
    phase: float = 0.0
    rotation: NDArray[np.float64] = field(default_factory=_identity)

    def __post_init__(self) -> None:
        """Validate and freeze the fields.

        Raises:
            SceneError: If a field is malformed; the message names the bad value.
        """
        self._points("center")
        self._points("amplitude")
        period = _scalar(self.period, "period")
        if period <= 0.0:
            raise SceneError(f"period must be > 0 [s], got {period!r}")
        object.__setattr__(self, "period", period)
        object.__setattr__(self, "phase", _scalar(self.phase, "phase"))
        object.__setattr__(self, "rotation", _frozen(_rotation(self.rotation)))

    def positions(self, times: ArrayLike) -> NDArray[np.float64]:
        """Positions at the given times.

        Args:
            times: Times, shape (T,) [s].

        Returns:
            Positions, shape (T, 3) [m]; a fresh array.
        """
        angle = 2.0 * np.pi * _times(times) / self.period + self.phase
        return self.center + np.sin(angle)[:, None] * self.amplitude


# ----------------------------------------------------------------------------- rotations


def rpy_to_matrix(rpy: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrix from roll, pitch, yaw: ``Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (``pin.rpy.rpyToMatrix``).

    Args:
        rpy: ``[roll, pitch, yaw]`` [rad].

    Returns:
        Rotation matrix, shape (3, 3).

    Raises:
        SceneError: If ``rpy`` is not 3 finite real numbers.
    """
    angles = _real_array(rpy, "rpy")
    if angles.shape != (3,):
        raise SceneError(f"rpy must be [roll, pitch, yaw] (3 numbers) [rad], got shape {angles.shape}: {show(angles)}")
    _check_finite(angles, "rpy")
    matrix: NDArray[np.float64] = pin.rpy.rpyToMatrix(angles)
    return matrix
