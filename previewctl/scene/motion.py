"""Obstacle motions: where an obstacle is, and how it is turned, at any time.

Every motion gives the obstacle's placement at time ``t`` [s] as ``(position (3,), rotation
(3, 3))``. All motions here keep a fixed rotation; only the position changes. Positions (and
velocities, amplitudes, centres) may be given with 2 entries for planar scenes, in which case
``z = 0`` is appended.

:func:`previewctl.scene.file.motion_from_dict` builds a motion from a TOML-like table, e.g.
``{"type": "periodic", "center": [0.4, 0, 0.3], "amplitude": [0, 0.1, 0], "period": 4.0}``.
"""

from __future__ import annotations

import math
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
    """An obstacle moving in a straight line from ``start_time`` on, held at its start before:
    ``p(t) = position + velocity (max(t, start_time) - t₀)`` with ``t₀ = max(start_time, 0)``.

    ``position`` is where the obstacle is when the run starts, or when it starts moving if that is later. A negative
    ``start_time`` is an obstacle already moving when the run starts (which a sensor running before the run sees,
    :attr:`~previewctl.sensing.options.Sensing.history`).

    Attributes:
        position: Position at ``max(start_time, 0)``, shape (3,) [m]. Read-only.
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
        elapsed = np.maximum(_times(times), self.start_time) - max(self.start_time, 0.0)
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


# ----------------------------------------------------------------------------- surprises
# Motions a constant-velocity predictor does not know: the velocity turns, the speed changes (or drops to 0), or the
# obstacle wanders. Each is at ``position`` at ``t = 0`` and came there in a straight line at ``velocity``: it is
# already moving when the run starts, as a sensor running before the run sees it (``Sensing.history``).


def _non_negative(value: object, name: str, unit: str) -> float:
    """``value`` as a finite real >= 0; :class:`SceneError` naming it otherwise."""
    number = _scalar(value, name)
    if number < 0.0:
        raise SceneError(f"{name} must be >= 0 [{unit}], got {number!r}")
    return number


def _positive(value: object, name: str, unit: str) -> float:
    """``value`` as a finite real > 0; :class:`SceneError` naming it otherwise."""
    number = _scalar(value, name)
    if number <= 0.0:
        raise SceneError(f"{name} must be > 0 [{unit}], got {number!r}")
    return number


@dataclass(frozen=True, eq=False)
class Turn(_Placed):
    """A straight line whose velocity turns by ``angle`` about ``axis`` from ``turn_time`` on, then a straight line.

    With ``ω = rate`` (signed like ``angle``), ``T = |angle| / rate`` and the velocity split into ``v_a`` along the
    axis and ``v_⊥`` across it, the velocity ``s`` seconds into the turn is ``v_a + v_⊥ cos(ω s) + (a × v_⊥) sin(ω s)``
    for ``s <= T`` (a circular arc of radius ``|v_⊥| / |ω|``), so the position is::

        p(t) = position + velocity t                                          t <= turn_time (t < 0 too)
        p(turn_time + s) = p(turn_time) + v_a s + v_⊥ sin(ω s) / ω + (a × v_⊥)(1 − cos(ω s)) / ω     s <= T

    and a straight line at the turned velocity after ``T``. ``rate = None`` turns at once (``T = 0``: the velocity
    jumps, the position is continuous).

    Attributes:
        position: Position at ``t = 0``, shape (3,) [m]. Read-only.
        velocity: Velocity before the turn (also before ``t = 0``), shape (3,) [m/s]. Read-only.
        turn_time: When the turn starts [s], >= 0.
        angle: How far the velocity turns [rad], about ``axis`` (right-hand rule).
        rate: Turn rate [rad/s], > 0, or ``None``: at once.
        axis: Turn axis, shape (3,), normalised (default z: a turn in a planar scene's plane). Read-only.
        rotation: Rotation matrix, shape (3, 3). Read-only.
    """

    position: NDArray[np.float64]
    velocity: NDArray[np.float64]
    turn_time: float
    angle: float
    rate: float | None = None
    axis: NDArray[np.float64] = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    rotation: NDArray[np.float64] = field(default_factory=_identity)

    def __post_init__(self) -> None:
        """Validate and freeze the fields.

        Raises:
            SceneError: If a field is malformed; the message names the bad value.
        """
        self._points("position")
        self._points("velocity")
        object.__setattr__(self, "turn_time", _non_negative(self.turn_time, "turn_time", "s"))
        object.__setattr__(self, "angle", _scalar(self.angle, "angle"))
        if self.rate is not None:
            object.__setattr__(self, "rate", _positive(self.rate, "rate", "rad/s"))
        axis = _real_array(self.axis, "axis")
        if axis.shape != (3,) or not np.all(np.isfinite(axis)) or np.linalg.norm(axis) == 0.0:
            raise SceneError(f"axis must be 3 finite numbers, not all 0, got {show(axis)}")
        object.__setattr__(self, "axis", _frozen(axis / np.linalg.norm(axis)))
        object.__setattr__(self, "rotation", _frozen(_rotation(self.rotation)))

    @property
    def duration(self) -> float:
        """How long the turn lasts, ``|angle| / rate`` [s] (0 for a turn at once)."""
        return 0.0 if self.rate is None else abs(self.angle) / self.rate

    def positions(self, times: ArrayLike) -> NDArray[np.float64]:
        """Positions at the given times.

        Args:
            times: Times, shape (T,) [s].

        Returns:
            Positions, shape (T, 3) [m]; a fresh array.
        """
        elapsed = _times(times)
        along = self.velocity.dot(self.axis) * self.axis
        across = self.velocity - along
        side = np.cross(self.axis, across)
        after = along + across * np.cos(self.angle) + side * np.sin(self.angle)
        straight = np.minimum(elapsed, self.turn_time)
        since = elapsed - straight
        turning = np.minimum(since, self.duration)
        path = self.position + straight[:, None] * self.velocity + (since - turning)[:, None] * after
        if self.rate is not None and self.angle != 0.0:
            omega = np.copysign(self.rate, self.angle)
            phase = omega * turning
            path += (turning[:, None] * along + np.sin(phase)[:, None] * across / omega
                     + (1.0 - np.cos(phase))[:, None] * side / omega)
        return path


@dataclass(frozen=True, eq=False)
class SpeedChange(_Placed):
    """A straight line whose speed changes by ``factor`` at ``change_time``, ramped linearly over ``ramp_time``.

    A stop is ``factor = 0`` (``ramp_time``: the braking time), a speed-up ``factor > 1``. With the speed scale
    ``σ(t)`` = 1 before ``change_time``, linear to ``factor`` over ``ramp_time``, ``factor`` after::

        p(t) = position + velocity ∫_0^t σ,   ∫ over the ramp = u + (factor − 1) u² / (2 ramp_time)

    for ``u`` seconds into the ramp (before ``t = 0``, ``σ = 1``).

    Attributes:
        position: Position at ``t = 0``, shape (3,) [m]. Read-only.
        velocity: Velocity before the change (also before ``t = 0``), shape (3,) [m/s]. Read-only.
        change_time: When the change starts [s], >= 0.
        factor: Speed after the change over speed before, >= 0 (0: the obstacle stops).
        ramp_time: How long the change takes [s], >= 0 (0: at once).
        rotation: Rotation matrix, shape (3, 3). Read-only.
    """

    position: NDArray[np.float64]
    velocity: NDArray[np.float64]
    change_time: float
    factor: float
    ramp_time: float = 0.0
    rotation: NDArray[np.float64] = field(default_factory=_identity)

    def __post_init__(self) -> None:
        """Validate and freeze the fields.

        Raises:
            SceneError: If a field is malformed; the message names the bad value.
        """
        self._points("position")
        self._points("velocity")
        object.__setattr__(self, "change_time", _non_negative(self.change_time, "change_time", "s"))
        object.__setattr__(self, "factor", _non_negative(self.factor, "factor", "1"))
        object.__setattr__(self, "ramp_time", _non_negative(self.ramp_time, "ramp_time", "s"))
        object.__setattr__(self, "rotation", _frozen(_rotation(self.rotation)))

    def positions(self, times: ArrayLike) -> NDArray[np.float64]:
        """Positions at the given times.

        Args:
            times: Times, shape (T,) [s].

        Returns:
            Positions, shape (T, 3) [m]; a fresh array.
        """
        elapsed = _times(times)
        before = np.minimum(elapsed, self.change_time)
        ramp = np.clip(elapsed - self.change_time, 0.0, self.ramp_time)
        after = np.maximum(elapsed - self.change_time - self.ramp_time, 0.0)
        ramped = ramp if self.ramp_time == 0.0 else ramp + (self.factor - 1.0) * ramp**2 / (2.0 * self.ramp_time)
        distance = before + ramped + self.factor * after
        return self.position + distance[:, None] * self.velocity


MAX_WALK_STEPS = 1_000_000
"""Most steps of a :class:`RandomWalk` (``duration / step``)."""


@dataclass(frozen=True, eq=False)
class RandomWalk(_Placed):
    """A smooth random walk inside the box ``center ± half_size``, the same for the same ``seed``.

    An unbounded walk ``x(t)`` is folded into the box per axis: ``p = center + h sin(x / h)`` (``h = half_size``),
    so the obstacle never leaves the box, slows down towards a wall and turns back there smoothly. ``ẋ`` is an
    Ornstein-Uhlenbeck process sampled every ``step`` (exact discretisation: ``u_{k+1} = u_k e^{−step/τ} +
    speed √(1 − e^{−2 step/τ}) ξ_k``, ``ξ_k`` standard normal from ``np.random.default_rng(seed)``, ``τ`` the
    correlation time), linear between the samples, so ``x`` is its exact integral: positions and velocities are
    continuous and the acceleration bounded. It is at ``position`` with ``velocity`` at ``t = 0``, came there with that
    constant ``ẋ`` before (folded like the rest), and holds its end after ``duration`` (rounded up to a whole step).
    An axis with ``half_size = 0`` stays at ``center``.

    Attributes:
        position: Start, shape (3,) [m], strictly inside the box. Read-only.
        center: Centre of the box, shape (3,) [m]. Read-only.
        half_size: Half extents of the box, shape (3,) [m], >= 0. Read-only.
        speed: Standard deviation of the walk's velocity per axis [m/s] (before the folding), >= 0.
        seed: Seed of the walk, an integer >= 0.
        velocity: Velocity at ``t = 0``, shape (3,) [m/s] (default 0). Read-only.
        correlation_time: How long the walk keeps a velocity, ``τ`` [s], > 0.
        duration: How long it walks [s], > 0.
        step: Time between velocity samples [s], > 0.
        rotation: Rotation matrix, shape (3, 3). Read-only.
    """

    position: NDArray[np.float64]
    center: NDArray[np.float64]
    half_size: NDArray[np.float64]
    speed: float
    seed: int
    velocity: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    correlation_time: float = 1.0
    duration: float = 60.0
    step: float = 0.05
    rotation: NDArray[np.float64] = field(default_factory=_identity)
    _walk: NDArray[np.float64] = field(init=False, repr=False)
    _rates: NDArray[np.float64] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        """Validate and freeze the fields, and draw the walk.

        Raises:
            SceneError: If a field is malformed; the message names the bad value.
        """
        for name in ("position", "center", "half_size", "velocity"):
            self._points(name)
        if np.any(self.half_size < 0.0):
            raise SceneError(f"half_size must be >= 0 [m] on every axis, got {show(self.half_size)}")
        offset, moving = self.position - self.center, self.half_size > 0.0
        if np.any(np.abs(offset[moving]) >= self.half_size[moving]) or np.any(offset[~moving] != 0.0):
            raise SceneError(f"position {show(self.position)} must be strictly inside the box center "
                             f"{show(self.center)} ± half_size {show(self.half_size)}")
        object.__setattr__(self, "speed", _non_negative(self.speed, "speed", "m/s"))
        if isinstance(self.seed, (bool, np.bool_)) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise SceneError(f"seed must be an integer >= 0, got {show(self.seed)}")
        object.__setattr__(self, "seed", int(self.seed))
        for name, unit in (("correlation_time", "s"), ("duration", "s"), ("step", "s")):
            object.__setattr__(self, name, _positive(getattr(self, name), name, unit))
        if self.duration / self.step > MAX_WALK_STEPS:
            raise SceneError(f"duration / step = {self.duration / self.step:.3g} steps, more than {MAX_WALK_STEPS:,}; "
                             f"valid: a longer step or a shorter duration")
        object.__setattr__(self, "rotation", _frozen(_rotation(self.rotation)))
        self._draw(moving)

    def _draw(self, moving: NDArray[np.bool_]) -> None:
        """The unfolded walk ``x`` and its velocity ``u`` at the samples, shape (K + 1, 3) each."""
        h = np.where(moving, self.half_size, 1.0)
        start = np.where(moving, h * np.arcsin((self.position - self.center) / h), 0.0)
        count = math.ceil(self.duration / self.step)
        decay = math.exp(-self.step / self.correlation_time)
        kicks = self.speed * math.sqrt(1.0 - decay**2) * np.random.default_rng(self.seed).standard_normal((count, 3))
        rates = np.empty((count + 1, 3))
        rates[0] = np.where(moving, self.velocity / np.cos(start / h), 0.0)
        for k in range(count):
            rates[k + 1] = decay * rates[k] + kicks[k]
        rates[:, ~moving] = 0.0
        walk = start + np.concatenate((np.zeros((1, 3)), np.cumsum(0.5 * self.step * (rates[1:] + rates[:-1]), axis=0)))
        object.__setattr__(self, "_walk", _frozen(walk))
        object.__setattr__(self, "_rates", _frozen(rates))

    def positions(self, times: ArrayLike) -> NDArray[np.float64]:
        """Positions at the given times.

        Args:
            times: Times, shape (T,) [s].

        Returns:
            Positions, shape (T, 3) [m]; a fresh array.
        """
        at = _times(times)
        elapsed = np.minimum(np.maximum(at, 0.0), (self._walk.shape[0] - 1) * self.step)
        k = np.minimum((elapsed // self.step).astype(np.int64), self._walk.shape[0] - 2)
        s = (elapsed - k * self.step)[:, None]
        u0, u1 = self._rates[k], self._rates[k + 1]
        walk = self._walk[k] + u0 * s + (u1 - u0) * s**2 / (2.0 * self.step)
        before = at < 0.0
        walk[before] += at[before, None] * self._rates[0]  # the straight line it came in on
        moving = self.half_size > 0.0
        h = np.where(moving, self.half_size, 1.0)
        return np.where(moving, self.center + h * np.sin(walk / h), self.center)


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
