"""The scenario file's schema: one pydantic model per TOML section, checked before anything is built.

:func:`previewctl.sim.scenario.scenario_from_dict` validates a parsed TOML document against
:class:`ScenarioFile`, then builds the runtime objects from the validated sections (a robot, a hand
path, a scene, a controller ...). Checks that need the robot (the number of ``q0`` entries, the
waypoint dimension, the hand at the path start) come in that second step.

Each bound is stated once. A section that mirrors a value object is made from that object's
dataclass fields by :func:`previewctl.validation.table`, so the file and the API obey the same rule:

====================  =====================================================================
``[robot]``           :class:`RobotSpec` + ``q0`` [rad] or ``q0_deg`` [deg]
``[path]``            :class:`PathTable` (values checked by :class:`~previewctl.path.HandPath`)
``[[obstacles]]``     :data:`previewctl.scene.schema.ObstacleTable` (shapes' fields + placement)
``[controller]``      ``name`` + :class:`~previewctl.control.params.ControllerParams` + ``[controller.ga]``
                      (:class:`~previewctl.search.ga.GAOptions`)
``[timing]``          :class:`Timing` (``duration`` defaults to the path's end)
``[index]``           :class:`~previewctl.index.amsi.IndexParams` but ``rank_tolerance``
``[potential]``       :class:`~previewctl.index.potential.Potential`
``[verdict]``         :class:`Verdict`
``[output]``          :class:`OutputSpec`
``[sensing]``         :class:`~previewctl.sensing.options.Sensing` (observed obstacles; ``predictor`` a name)
====================  =====================================================================

How to add a key:

* to a mirrored section, add the field to its value object, with its bound as the annotation (a
  type of :mod:`previewctl.validation`) and its unit in the docstring. For instance, in
  ``ControllerParams``: ``max_step: Positive = 0.1`` ("max_step: largest joint step [rad]"). Nothing
  else: ``max_step = 0.2`` in ``[controller]`` is then accepted and passed on, ``max_step = 0`` is
  refused with "controller.max_step must be > 0, got 0", and ``ControllerParams(max_step=0)``
  raises a ``ParameterError`` with the same words.
* to ``[path]``, ``[robot]`` (``q0``) or the top level: add a field to the model here and read it
  in :func:`~previewctl.sim.scenario.scenario_from_dict`.
* a rule across keys: the ``check()`` method of the value object (a
  :class:`~previewctl.validation.Checked`), or a ``model_validator`` here that raises
  :func:`previewctl.validation.invalid`.
* an obstacle shape or a motion type: see :mod:`previewctl.scene.schema`.

Messages come from :func:`previewctl.validation.explain`; add a test of the new key's message
(``tests/test_scenario.py`` has one per section).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Any, Literal, get_args

from pydantic import Field, ValidatorFunctionWrapHandler, WrapValidator, model_validator

from previewctl.control.params import GA_SETTINGS, ControllerName, ControllerParams
from previewctl.errors import ParameterError
from previewctl.index.amsi import IndexParams
from previewctl.index.load import load_robot
from previewctl.index.potential import Potential
from previewctl.robot.model import Geometry, Robot, Task
from previewctl.scene.schema import Angles, ObstacleTable
from previewctl.sensing.options import PredictorName, Sensing
from previewctl.validation import Checked, Finite, Flag, Integer, Positive, Section, Text, invalid, show, table

Figure = Literal["strobe", "S", "clearance", "error"]
FIGURES: tuple[Figure, ...] = get_args(Figure)
"""Figures the ``[output]`` section may ask for."""


# -------------------------------------------------------------------------------- value objects


_SRDF = ("an SRDF file naming the link pairs never checked for self-collision, relative to the scenario file "
         "(default: the robot's shipped SRDF, else sampled pairs)")


@dataclass(frozen=True)
class RobotSpec:
    """How the scenario's robot was loaded (to reload it, e.g. with exact meshes).

    Attributes mirror :func:`previewctl.index.load.load_robot`'s arguments.
    """

    source: Annotated[Text, Field(description="a URDF path, 'planar4' or an example-robot-data name like 'panda'")]
    tip: Text | None = None
    lock: tuple[Text, ...] | None = None
    task: Task | None = None
    guarded_links: tuple[Text, ...] | Literal["all", "intermediate"] = "all"
    control_points: tuple[Text, ...] | None = None
    geometry: Geometry = "convex"
    package_dirs: tuple[Text, ...] = ()
    collision_from_visual: Flag = False
    srdf: Annotated[Text, Field(description=_SRDF)] | None = None

    def load(self, geometry: Geometry | None = None) -> Robot:
        """Load the robot, optionally with another ``geometry``."""
        return load_robot(
            self.source,
            tip=self.tip,
            lock=self.lock,
            task=self.task,
            control_points=self.control_points,
            guarded_links=self.guarded_links,
            geometry=geometry or self.geometry,
            package_dirs=self.package_dirs,
            collision_from_visual=self.collision_from_visual,
            srdf=self.srdf,
        )


MAX_STEPS = 1_000_000
"""Most control periods of one run (e.g. 10 000 s at dt = 10 ms): the log holds a few arrays of this length."""


@dataclass(frozen=True)
class Timing(Checked):
    """Time steps of a run.

    Attributes:
        dt: control period [s].
        frame: camera frame period [s]; GA controllers run one generation per frame.
        duration: simulated time [s], at least ``dt``.
    """

    dt: Positive = 0.01
    frame: Positive = 0.033
    duration: Positive = 1.0

    def check(self) -> None:
        """A run has a step and at most :data:`MAX_STEPS`: ``dt <= duration <= MAX_STEPS dt`` (checked before any
        array of the run is allocated)."""
        if self.dt > self.duration:
            raise ParameterError(f"dt = {self.dt} s is longer than duration = {self.duration} s")
        if self.duration / self.dt > MAX_STEPS:
            raise ParameterError(f"duration = {self.duration:g} s at dt = {self.dt:g} s is "
                                 f"{self.duration / self.dt:.3g} control periods, more than {MAX_STEPS:,}; "
                                 f"valid: duration / dt <= {MAX_STEPS:,}")

    @property
    def steps(self) -> int:
        """Number of control periods in ``duration``."""
        return max(1, round(self.duration / self.dt))


@dataclass(frozen=True)
class Verdict(Checked):
    """When a run succeeds: it is collision-free *and* the hand stays on its path.

    Attributes:
        tolerance: largest hand error ``|r_d − r|`` [m] of a successful run.
    """

    tolerance: Positive = 0.005


@dataclass(frozen=True)
class OutputSpec(Checked):
    """What ``previewctl run`` writes besides the log.

    Attributes:
        figures: figure names among :data:`FIGURES`.
        gif: whether to write an animated GIF (planar arms).
        strobe_poses: number of arm poses drawn in the strobe plot.
    """

    figures: tuple[Figure, ...] = FIGURES
    gif: Flag = True
    strobe_poses: Annotated[Integer, Field(ge=2)] = 12


# ------------------------------------------------------------------------------------- sections

Configuration = tuple[Finite, ...]
"""Joint angles [rad] (or [deg] for ``q0_deg``), one per joint velocity or configuration entry."""


class _OneStart(Section):
    """``[robot]``'s rule across keys: the initial configuration is given once."""

    @model_validator(mode="after")
    def _one_start(self) -> _OneStart:
        if (getattr(self, "q0", None) is None) == (getattr(self, "q0_deg", None) is None):
            raise invalid("needs exactly one of q0 [rad] or q0_deg [deg] (the initial configuration)")
        return self


def _auto_or_angles(value: Any, handler: ValidatorFunctionWrapHandler) -> Any:
    """``"auto"`` as is; anything else checked as a :data:`Configuration` (its messages name the entry)."""
    if isinstance(value, str) and value != "auto":
        raise invalid("must be a list of numbers [rad] or \"auto\", got {value}", value=show(value))
    return value if value == "auto" else handler(value)


StartConfiguration = Annotated[Configuration, WrapValidator(_auto_or_angles)]
"""``q0``: joint angles [rad], or ``"auto"``."""

RobotTable: Any = table("robot", RobotSpec, base=_OneStart, q0=(StartConfiguration | None, None),
                        q0_deg=(Configuration | None, None))
"""``[robot]``: how to load the arm and its initial configuration ``q0`` [rad] or ``q0_deg`` [deg];
``q0 = "auto"``: the best collision-free configuration with the hand at the first waypoint."""


class PathTable(Section):
    """``[path]``: the hand path (a :class:`~previewctl.path.HandPath`; it checks the values)."""

    waypoints: Annotated[tuple[tuple[Finite, ...], ...], Field(description="[[x, y(, z)], ...] [m]")]
    duration: Annotated[Finite, Field(description="time to travel the path [s]")]
    start_time: Finite = 0.0
    orientation_rpy: Angles | None = None


ControllerTable: Any = table("controller", ControllerParams, exclude=("ga_options",),
                             name=(ControllerName, "none"), ga=(GA_SETTINGS, GA_SETTINGS()))
"""``[controller]``: ``name``, every :class:`~previewctl.control.params.ControllerParams` field but
``ga_options``, which is the ``[controller.ga]`` table."""
TimingTable: Any = table("timing", Timing, exclude=("duration",), duration=(Positive | None, None))
"""``[timing]``: :class:`Timing`; ``duration`` defaults to the path's end."""
IndexTable: Any = table("index", IndexParams, exclude=("rank_tolerance",))
PotentialTable: Any = table("potential", Potential)
VerdictTable: Any = table("verdict", Verdict)
OutputTable: Any = table("output", OutputSpec)
SensingTable: Any = table("sensing", Sensing, exclude=("predictor",), predictor=(PredictorName, Sensing.predictor))
"""``[sensing]``: :class:`~previewctl.sensing.options.Sensing`, its ``predictor`` one of the built-in names."""


class ScenarioFile(Section):
    """A whole scenario file. Every section but ``[robot]`` and ``[path]`` is optional."""

    name: Annotated[Text, Field(min_length=1)] | None = None
    description: Text = ""
    seed: Annotated[Integer, Field(ge=0)] = 0
    robot: RobotTable = Field(description="with at least source = ... and q0 = [...]")
    path: PathTable = Field(description="with waypoints = [[x, y(, z)], ...] and duration = ...")
    obstacles: tuple[ObstacleTable, ...] = ()
    controller: ControllerTable = ControllerTable()
    timing: TimingTable = TimingTable()
    index: IndexTable = IndexTable()
    potential: PotentialTable = PotentialTable()
    verdict: VerdictTable = VerdictTable()
    output: OutputTable = OutputTable()
    sensing: SensingTable | None = None
