"""Hand paths: piecewise-linear paths through waypoints, travelled at constant speed.

A :class:`HandPath` is the reference the controller tracks. It passes through its waypoints in
order at a constant speed along arc length, so the time spent on each segment is proportional to
the segment's length. Before ``start_time`` the hand waits at the first waypoint, after
``end_time`` it rests at the last one (velocity zero in both cases).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from previewctl.errors import TrajectoryError
from previewctl.validation import check_finite, real_array, real_scalar, rotation_matrix, show


def _real_array(value: object, name: str) -> NDArray[np.float64]:
    return real_array(value, name, TrajectoryError)


def _real_scalar(value: object, name: str) -> float:
    return real_scalar(value, name, TrajectoryError)


def _check_finite(array: NDArray[np.float64], name: str) -> None:
    check_finite(array, name, TrajectoryError)


@dataclass(frozen=True, eq=False)
class HandPath:
    """A piecewise-linear hand path travelled at constant speed.

    The hand passes the waypoints in order, moving at constant speed ``length / duration``
    along the polyline. Evaluation is right-continuous: exactly at a waypoint the velocity is
    that of the following segment, and at ``end_time`` it is already zero. Consecutive repeated
    waypoints (zero-length segments) are allowed; they are passed in zero time.

    Instances compare by identity (``eq=False``) because their fields are arrays.

    Attributes:
        waypoints: Waypoints, shape (K, d) with K >= 2 and d in {2, 3} [m]. Read-only copy.
        duration: Time to travel the whole path [s], > 0.
        start_time: Time at which the hand leaves the first waypoint [s].
        orientation: Fixed hand rotation for pose tasks, shape (3, 3), or ``None``.
            Read-only copy.
    """

    waypoints: NDArray[np.float64]
    duration: float
    start_time: float = 0.0
    orientation: NDArray[np.float64] | None = None
    _times: NDArray[np.float64] = field(init=False, repr=False)
    _directions: NDArray[np.float64] = field(init=False, repr=False)
    _time_list: list[float] = field(init=False, repr=False)
    _length: float = field(init=False, repr=False)

    def __post_init__(self) -> None:
        """Validate and freeze the fields; precompute waypoint times and segment directions.

        Raises:
            TrajectoryError: If any field is malformed; the message names the bad value.
        """
        points = _real_array(self.waypoints, "waypoints")
        if points.ndim != 2 or points.shape[1] not in (2, 3):
            raise TrajectoryError(
                f"waypoints must have shape (K, 2) or (K, 3), got shape {points.shape}: {show(points)}"
            )
        if points.shape[0] < 2:
            raise TrajectoryError(f"waypoints needs at least 2 points, got {points.shape[0]}: {show(points)}")
        _check_finite(points, "waypoints")
        duration = _real_scalar(self.duration, "duration")
        if duration <= 0.0:
            raise TrajectoryError(f"duration must be > 0 [s], got {duration!r}")
        start = _real_scalar(self.start_time, "start_time")
        if not start + duration > start:
            raise TrajectoryError(
                f"duration {duration!r} [s] is lost to rounding at start_time {start!r} [s]; "
                "use a longer duration or an earlier start_time"
            )

        steps = np.diff(points, axis=0)
        seg_lengths = np.linalg.norm(steps, axis=1)
        length = float(seg_lengths.sum())
        if not np.isfinite(length):
            raise TrajectoryError(f"waypoints are too far apart (length overflows): {show(points)}")
        if length <= 0.0:
            raise TrajectoryError(
                f"waypoints must not all coincide (total length is 0): {show(points)}; "
                "give at least two distinct points"
            )

        orientation = self.orientation
        if orientation is not None:
            orientation = rotation_matrix(orientation, "orientation", TrajectoryError)
            orientation.flags.writeable = False

        cumulative = np.concatenate(([0.0], np.cumsum(seg_lengths)))
        times = start + duration * (cumulative / length)
        times[0] = start
        times[-1] = start + duration
        nonzero = seg_lengths > 0.0
        directions = np.zeros_like(steps)
        directions[nonzero] = steps[nonzero] / seg_lengths[nonzero, None]

        for array in (points, times, directions):
            array.flags.writeable = False
        object.__setattr__(self, "waypoints", points)
        object.__setattr__(self, "duration", duration)
        object.__setattr__(self, "start_time", start)
        object.__setattr__(self, "orientation", orientation)
        object.__setattr__(self, "_times", times)
        object.__setattr__(self, "_time_list", times.tolist())  # for bisect on one time
        object.__setattr__(self, "_directions", directions)
        object.__setattr__(self, "_length", length)

    @property
    def dim(self) -> int:
        """Dimension d of the workspace (2 or 3)."""
        return int(self.waypoints.shape[1])

    @property
    def length(self) -> float:
        """Total arc length of the path [m]."""
        return self._length

    @property
    def speed(self) -> float:
        """Constant travel speed ``length / duration`` [m/s]."""
        return self._length / self.duration

    @property
    def end_time(self) -> float:
        """Time at which the last waypoint is reached, ``start_time + duration`` [s]."""
        return float(self._times[-1])

    def waypoint_times(self) -> NDArray[np.float64]:
        """Times at which each waypoint is passed.

        Returns:
            Non-decreasing times, shape (K,) [s]; the first is ``start_time``, the last
            ``end_time``. A fresh, writable array.
        """
        return self._times.copy()

    def position(self, t: float | ArrayLike) -> NDArray[np.float64]:
        """Hand position on the path at time ``t``.

        Args:
            t: A time [s], or times of shape (T,) [s].

        Returns:
            Position, shape (d,) for a scalar ``t`` or (T, d) for an array [m].

        Raises:
            TrajectoryError: If ``t`` is not finite or has more than one dimension.
        """
        if isinstance(t, float) and math.isfinite(t):  # one time: the same arithmetic without array overhead
            if t >= self.end_time:
                return self.waypoints[-1].copy()
            held = max(t, self.start_time)
            k = self._segment(held)
            return self.waypoints[k] + self._directions[k] * (self.speed * (held - self._time_list[k]))
        times, scalar = self._times_arg(t)
        # Clipping holds the first waypoint before start_time (segment 0, offset 0) and keeps
        # offsets bounded far after end_time. Exactly at a waypoint time the offset is 0.
        clipped = np.clip(times, self.start_time, self.end_time)
        segment, _ = self._locate(clipped)
        offset = self.speed * (clipped - self._times[segment])
        out = self.waypoints[segment] + self._directions[segment] * offset[:, None]
        out[times >= self.end_time] = self.waypoints[-1]
        return out[0] if scalar else out

    def velocity(self, t: float | ArrayLike) -> NDArray[np.float64]:
        """Hand velocity on the path at time ``t`` (right-continuous).

        Args:
            t: A time [s], or times of shape (T,) [s].

        Returns:
            Velocity, shape (d,) for a scalar ``t`` or (T, d) for an array [m/s]; zero before
            ``start_time`` and from ``end_time`` on, of magnitude ``speed`` in between.

        Raises:
            TrajectoryError: If ``t`` is not finite or has more than one dimension.
        """
        if isinstance(t, float) and math.isfinite(t):  # one time: the same arithmetic without array overhead
            if not self.start_time <= t < self.end_time:
                return np.zeros(self.dim)
            return self._directions[self._segment(t)] * self.speed
        times, scalar = self._times_arg(t)
        segment, inside = self._locate(times)
        out = self._directions[segment] * self.speed
        out[~inside] = 0.0
        return out[0] if scalar else out

    def _times_arg(self, t: float | ArrayLike) -> tuple[NDArray[np.float64], bool]:
        """Validate a time argument; return it as a (T,) array and whether it was a scalar."""
        times = _real_array(t, "t")
        if times.ndim > 1:
            raise TrajectoryError(f"t must be a number or an array of shape (T,), got shape {times.shape}")
        _check_finite(times, "t")
        scalar = times.ndim == 0
        return (times.reshape(1) if scalar else times), scalar

    def _segment(self, t: float) -> int:
        """:meth:`_locate`'s segment index for one time ``t`` [s]."""
        return min(max(bisect.bisect_right(self._time_list, t) - 1, 0), len(self._time_list) - 2)

    def _locate(self, times: NDArray[np.float64]) -> tuple[NDArray[np.intp], NDArray[np.bool_]]:
        """Segment index for each time (right-continuous) and whether it is on the path.

        Args:
            times: Times, shape (T,) [s].

        Returns:
            ``(segment, inside)``: segment indices in [0, K-2], shape (T,), and a mask that is
            true where ``start_time <= t < end_time``. Because the segment is chosen with
            ``times[i] <= t < times[i+1]``, a zero-length segment is never selected inside.
        """
        segment = np.searchsorted(self._times, times, side="right") - 1
        segment = np.clip(segment, 0, len(self._times) - 2)
        inside = (times >= self.start_time) & (times < self.end_time)
        return segment, inside
