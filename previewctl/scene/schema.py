"""The obstacle tables of a scene or scenario file (``[[obstacles]]``) and their motions, as pydantic models.

An obstacle table is a shape's fields plus its placement: a fixed ``position`` (2 or 3 numbers [m];
``z = 0`` for 2) and ``rpy`` ([rad]), or a ``motion`` table. The shape tables are made from the shape
value objects (:mod:`previewctl.scene.shapes`), so a radius is checked by the same rule in a file and
in ``Sphere(radius)``. Motion tables check types; the motions themselves
(:mod:`previewctl.scene.motion`) check values (a positive period, increasing times).

To add a shape: write its frozen dataclass in ``shapes.py`` (bounds as field annotations) and add it
to :data:`SHAPES`. To add a motion: a ``...Table`` model here, a member of :data:`MotionTable`, and a
case in :func:`previewctl.scene.file.motion_from_table`.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal, Union, get_args

from pydantic import Field, ValidationInfo, create_model, field_validator, model_validator

from previewctl.scene.shapes import Box, Capsule, Cylinder, Halfspace, Mesh, Plane, Sphere
from previewctl.validation import (
    Finite,
    Flag,
    Integer,
    NonNegative,
    Positive,
    Section,
    Size,
    Text,
    fields_of,
    invalid,
)

Point = Annotated[tuple[Finite, ...], Size(2, 3)]
"""A position [m]: 3 numbers, or 2 in a planar scene (``z = 0``)."""
Angles = Annotated[tuple[Finite, Finite, Finite], Size(3), Field(description="[roll, pitch, yaw] [rad]")]
"""Roll, pitch, yaw [rad]: the rotation ``Rz(yaw) Ry(pitch) Rx(roll)``."""
_ORIGIN = (0.0, 0.0, 0.0)
_NO_TURN = (0.0, 0.0, 0.0)


# ------------------------------------------------------------------------------------- motions


class StaticTable(Section):
    """``{type = "static", position = [...]}``."""

    type: Literal["static"]
    position: Point
    rpy: Angles = _NO_TURN


class ConstantVelocityTable(Section):
    """``{type = "constant_velocity", position, velocity [m/s], start_time [s] = 0}``."""

    type: Literal["constant_velocity"]
    position: Point
    velocity: Point
    start_time: Finite = 0.0
    rpy: Angles = _NO_TURN


class WaypointsTable(Section):
    """``{type = "waypoints", times [s], positions (one per time), loop = false}``."""

    type: Literal["waypoints"]
    times: tuple[Finite, ...]
    positions: tuple[Point, ...]
    loop: Flag = False
    rpy: Angles = _NO_TURN

    @field_validator("positions")
    @classmethod
    def _one_per_time(cls, positions: tuple[Point, ...], info: ValidationInfo) -> tuple[Point, ...]:
        times = info.data.get("times")
        if times is not None and len(positions) != len(times):
            raise invalid("must have one position per time: got {count} positions for {times} times {values}",
                          count=len(positions), times=len(times), values=list(times))
        return positions


class PeriodicTable(Section):
    """``{type = "periodic", center, amplitude [m], period [s], phase [rad] = 0}``."""

    type: Literal["periodic"]
    center: Point
    amplitude: Point
    period: Finite
    phase: Finite = 0.0
    rpy: Angles = _NO_TURN


class TurnTable(Section):
    """``{type = "turn", position, velocity [m/s], turn_time [s], angle [rad], rate [rad/s] = at once, axis = z}``."""

    type: Literal["turn"]
    position: Point
    velocity: Point
    turn_time: NonNegative
    angle: Finite
    rate: Positive | None = None
    axis: Annotated[tuple[Finite, Finite, Finite], Size(3)] = (0.0, 0.0, 1.0)
    rpy: Angles = _NO_TURN


class StopTable(Section):
    """``{type = "stop", position, velocity [m/s], stop_time [s], braking_time [s] = 0}``: a speed change to 0."""

    type: Literal["stop"]
    position: Point
    velocity: Point
    stop_time: NonNegative
    braking_time: NonNegative = 0.0
    rpy: Angles = _NO_TURN


class SpeedChangeTable(Section):
    """``{type = "speed_change", position, velocity [m/s], change_time [s], factor, ramp_time [s] = 0}``."""

    type: Literal["speed_change"]
    position: Point
    velocity: Point
    change_time: NonNegative
    factor: NonNegative
    ramp_time: NonNegative = 0.0
    rpy: Angles = _NO_TURN


class RandomWalkTable(Section):
    """``{type = "random_walk", position, center, half_size [m], speed [m/s], seed, velocity [m/s] = 0,
    correlation_time [s] = 1, duration [s] = 60, step [s] = 0.05}``."""

    type: Literal["random_walk"]
    position: Point
    center: Point
    half_size: Point
    speed: NonNegative
    seed: Annotated[Integer, Field(ge=0)]
    velocity: Point = _ORIGIN
    correlation_time: Positive = 1.0
    duration: Positive = 60.0
    step: Positive = 0.05
    rpy: Angles = _NO_TURN


MotionTable = Annotated[
    Union[StaticTable, ConstantVelocityTable, WaypointsTable, PeriodicTable, TurnTable, StopTable,  # noqa: UP007
          SpeedChangeTable, RandomWalkTable],
    Field(discriminator="type"),
]
"""A motion table, told apart by its ``type``."""
MOTION_TYPES: tuple[str, ...] = tuple(get_args(m.model_fields["type"].annotation)[0]
                                      for m in get_args(get_args(MotionTable)[0]))
"""Valid values of a motion table's ``type`` key."""


# ----------------------------------------------------------------------------------- obstacles


class Placement(Section):
    """The keys every obstacle table has besides its shape's: ``name``, ``work_surface`` (see
    :class:`~previewctl.scene.shapes.Obstacle`), then (after the shape's keys) ``position`` and ``rpy``,
    or ``motion``."""

    name: Annotated[Text, Field(min_length=1)] | None = None
    work_surface: Annotated[Flag, Field(description="the hand may touch it (the object it works on)")] = False

    @model_validator(mode="after")
    def _one_placement(self) -> Placement:
        if getattr(self, "motion", None) is not None and {"position", "rpy"} & self.model_fields_set:
            raise invalid("gives both 'motion' and 'position'/'rpy'; give one of them")
        return self


_PLACEMENT: dict[str, Any] = {"position": (Point, _ORIGIN), "rpy": (Angles, _NO_TURN),
                              "motion": (MotionTable | None, None)}

SHAPES: dict[str, type] = {"sphere": Sphere, "box": Box, "capsule": Capsule, "cylinder": Cylinder,
                           "halfspace": Halfspace, "plane": Plane, "mesh": Mesh}
"""Value of an obstacle's ``shape`` key -> the shape class whose fields are the table's other keys."""


def _shape_table(kind: str, cls: type) -> type[Section]:
    """The table of one shape: ``name``, ``shape = kind``, the shape's fields, the placement."""
    tag: Any = Literal[kind]
    model: type[Section] = create_model(kind, __base__=Placement, shape=(tag, ...), **fields_of(cls), **_PLACEMENT)
    return model


_SHAPE_TABLES = tuple(_shape_table(kind, cls) for kind, cls in SHAPES.items())
ObstacleTable: Any = Annotated[Union[_SHAPE_TABLES], Field(discriminator="shape")]  # noqa: UP007
"""An obstacle table, told apart by its ``shape``."""


class SceneFile(Section):
    """A scene file: ``[[obstacles]]`` tables."""

    obstacles: tuple[ObstacleTable, ...] = ()
