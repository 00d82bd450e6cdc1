"""The observed world: the obstacles a controller knows from observations, as they come and go.

:class:`World` holds a base scene (what stays known: the static obstacles, and the moving ones that are not observed)
and one :class:`~previewctl.sensing.track.Track` per observed obstacle. Its rules (issue 33):

* an observation is validated whole before anything changes (:class:`~previewctl.errors.ObservationError` naming the
  bad value); positions with 2 entries are planar (``z = 0``);
* an observation under a name not observed yet adds the obstacle: its shape is the one given, else the one last
  known for that name (the scenario's, or an earlier observation's), else the observation is refused;
* an observation older than the obstacle's last is late: ignored and counted; older by more than the timeout, it is a
  clock that went back, refused with both times;
* :meth:`World.advance` (at each control step) drops the obstacles not observed for longer than the timeout, judged at
  the step's time, and reports what was added and dropped since the previous step;
* :meth:`World.forget` and :meth:`World.forget_all` drop obstacles at once.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import get_args

import numpy as np
from numpy.typing import ArrayLike

from previewctl.errors import ObservationError, UnknownNameError
from previewctl.scene.shapes import Obstacle, Scene, Shape
from previewctl.sensing.options import Sensing
from previewctl.sensing.track import Track
from previewctl.types import Array
from previewctl.validation import check_finite, real_array, real_scalar, rotation_matrix, show

SHAPES: tuple[type, ...] = get_args(Shape)
"""The shape types an observation may carry."""


@dataclass(frozen=True)
class Changes:
    """What :meth:`World.advance` reports for one control step.

    Attributes:
        added: the obstacles added since the previous step (first observed, or observed with a new shape).
        dropped: the obstacles forgotten or timed out since the previous step.
        late: late observations ignored so far (in total).
        changed: whether the set of obstacles (or a shape) changed: the controller needs a scene with it.
    """

    added: tuple[str, ...] = ()
    dropped: tuple[str, ...] = ()
    late: int = 0
    changed: bool = False


class World:
    """The obstacles a controller knows (module docstring).

    Args:
        scene: the scenario's scene: obstacles observed by ``sensing.names`` leave it until first observed.
        sensing: predictor, timeout, observed names, margin.
        spatial: the name of the arm if it is spatial (positions and velocities then need 3 entries), ``None`` for a
            planar arm (2 entries mean ``z = 0``).

    Raises:
        ObservationError: ``sensing.names`` names a static obstacle or one the scene does not have.
    """

    def __init__(self, scene: Scene, sensing: Sensing, *, spatial: str | None = None) -> None:
        self.sensing, self.spatial = sensing, spatial
        names = sensing.observed(scene)
        known = {o.name: o for o in scene.obstacles}
        for name in names:
            if name not in known:
                raise UnknownNameError("observed obstacle (Sensing.names)", name, known)
        self._base = tuple(o for o in scene.obstacles if o.name not in names)
        self._shapes: dict[str, Shape] = {name: known[name].shape for name in names}
        self._surfaces = {name for name in names if known[name].work_surface}
        self._tracks: dict[str, tuple[Shape, Track]] = {}
        self._added: list[str] = []
        self._dropped: list[str] = []
        self._late = 0
        self._changed = False
        self.scene = Scene(self._base)

    @property
    def observed(self) -> tuple[str, ...]:
        """The names of the obstacles observed now, in the order they were added."""
        return tuple(self._tracks)

    def observe(self, name: str, position: ArrayLike, t: float, *, rotation: ArrayLike | None = None,
                velocity: ArrayLike | None = None, shape: Shape | None = None) -> None:
        """Take an observation of obstacle ``name`` made at ``t`` [s] (module docstring).

        Args:
            name: the obstacle.
            position: ``(3,)`` [m], or ``(2,)`` for a planar arm (``z = 0``).
            t: when it was observed [s], on the path's clock (not when it was delivered).
            rotation: its rotation matrix ``(3, 3)``; default: the last one (the identity at first).
            velocity: its measured velocity ``(3,)`` or ``(2,)`` [m/s], if any.
            shape: its shape; needed for a name whose shape is not known yet.

        Raises:
            ObservationError: a bad value (named), a new name without a known shape, the name of an obstacle that is
                not observed (a static one of the scene), or ``t`` earlier than the obstacle's last observation by
                more than the timeout.
        """
        if not isinstance(name, str) or not name:
            raise ObservationError(f"an observation needs an obstacle name (a non-empty str), got {show(name)}")
        if any(o.name == name for o in self._base):
            raise ObservationError(f"obstacle {name!r} is known from the scene and not observed; observed: "
                                   f"{', '.join(self._shapes) or 'none'} (Sensing.names)")
        time = real_scalar(t, "t", ObservationError)
        point = self._vector(position, f"position of {name!r}")
        turn = None if rotation is None else rotation_matrix(rotation, f"rotation of {name!r}", ObservationError)
        speed = None if velocity is None else self._vector(velocity, f"velocity of {name!r}")
        if shape is not None and not isinstance(shape, SHAPES):
            raise ObservationError(f"shape of {name!r} must be one of {', '.join(s.__name__ for s in SHAPES)}, got "
                                   f"{type(shape).__name__} {show(shape)}")
        entry = self._tracks.get(name)
        last = None if entry is None else entry[1].last
        if last is not None and time < last:
            if last - time > self.sensing.timeout:
                raise ObservationError(f"observation of {name!r} at t = {time:g} s is {last - time:g} s before its "
                                       f"last one at t = {last:g} s, more than the timeout {self.sensing.timeout:g} s: "
                                       "did the clock go back?")
            self._late += 1
            return
        if entry is None or (shape is not None and shape != entry[0]):
            self._add(name, shape, time)
        self._tracks[name][1].update(time, point, turn, speed)

    def _add(self, name: str, shape: Shape | None, t: float) -> None:
        """Start a track for ``name`` (with ``shape``, or its known one)."""
        shape = shape if shape is not None else self._shapes.get(name)
        if shape is None:
            raise ObservationError(f"obstacle {name!r} is observed for the first time at t = {t:g} s without a "
                                   f"shape: give shape=... (one of {', '.join(s.__name__ for s in SHAPES)})")
        old = self._tracks.get(name)  # a new shape: the same track
        track = old[1] if old is not None else Track(self.sensing.new_predictor(), self.sensing.confidence,
                                                      self.sensing.margin_cap)
        self._shapes[name] = shape
        self._tracks[name] = (shape, track)
        self._added.append(name)
        self._changed = True

    def forget(self, name: str) -> None:
        """Drop obstacle ``name`` now.

        Raises:
            UnknownNameError: ``name`` is not observed now (the message lists those that are).
        """
        if name not in self._tracks:
            raise UnknownNameError("observed obstacle", name, self._tracks)
        del self._tracks[name]
        self._dropped.append(name)
        self._changed = True

    def forget_all(self) -> None:
        """Drop every observed obstacle now."""
        for name in list(self._tracks):
            self.forget(name)

    def advance(self, t: float) -> Changes:
        """Drop the obstacles not observed for longer than the timeout at time ``t`` [s]; what changed since the
        previous call (and, when the set changed, :attr:`scene` is the new scene)."""
        for name, (_, track) in list(self._tracks.items()):
            if track.last is not None and t - track.last > self.sensing.timeout:
                self.forget(name)
        changes = Changes(tuple(self._added), tuple(self._dropped), self._late, self._changed)
        if self._changed:
            self.scene = Scene(self._base + tuple(
                Obstacle(name, shape, track, work_surface=name in self._surfaces)
                for name, (shape, track) in self._tracks.items()))
        self._added, self._dropped, self._changed = [], [], False
        return changes

    def _vector(self, value: ArrayLike, name: str) -> Array:
        """A position or velocity as ``(3,)`` (2 entries, around a planar arm: ``z = 0``); :class:`ObservationError`
        naming ``name``."""
        array = real_array(value, name, ObservationError)
        if array.shape not in ((2,), (3,)):
            raise ObservationError(f"{name} must have 2 or 3 entries, got shape {array.shape}: {show(array)}")
        if array.shape == (2,) and self.spatial is not None:
            raise ObservationError(f"{name} {show(array)} is 2-D, but robot {self.spatial!r} is spatial: give "
                                   "[x, y, z] [m] (2 entries are for planar arms)")
        check_finite(array, name, ObservationError)
        return np.append(array, 0.0) if array.shape == (2,) else array

    def observed_obstacles(self) -> tuple[Obstacle, ...]:
        """The observed obstacles of :attr:`scene` (each with its :class:`~previewctl.sensing.track.Track`)."""
        return tuple(o for o in self.scene.obstacles if isinstance(o.motion, Track))
