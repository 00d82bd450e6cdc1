"""Building a controller: :func:`make_controller` (from a scenario or from parts) and :func:`compose`.

:func:`compose` is the one place that maps a controller name and a robot to parts
(:mod:`previewctl.control.laws` has one class per name):

========== ===========================================================================================
name       parts
========== ===========================================================================================
none       :class:`~previewctl.control.laws.Tracking`; always the pseudo-inverse execution
qp         :class:`~previewctl.control.laws.QPBaseline`; always the QP execution
gradient   :class:`~previewctl.control.laws.Gradient` on :class:`~previewctl.control.nullspace.AmsipGradient`
single     one imaginary arm: tracked peak (coherent) or argmax (``coherent = false``)
multi      ``len(weights)`` imaginary arms: points of a route planned toward their peaks (``route``: coherent, on an
           arm the window planner covers), tracked peaks (``peaks``: coherent, ``imaginary_arms = "peaks"`` or an
           arm the planner does not cover) or argmax (``coherent = false``)
reach      ``len(weights)`` imaginary arms and a planner toward their peaks (coherent, on an arm the window planner
           covers), else straight sweeps (:class:`~previewctl.control.sweeps.SweepRoutes`)
horizon    a :class:`~previewctl.control.planner.WindowPlanner` over ``plan_window``, replanned
oracle     a :class:`~previewctl.control.planner.WindowPlanner` over the whole future (non-causal)
========== ===========================================================================================

The window planner covers spatial arms (the sampled search) and planar arms of up to 4 joints (the DP). Every
controller but ``none`` and ``qp`` is executed by ``params.execution`` (the QP by default). A combination a law
cannot honour is refused with a :class:`~previewctl.errors.ParameterError`; a setting the chosen controller does not
read (set to other than its default, e.g. by a scenario file shared between controllers) is reported by an
:class:`~previewctl.errors.IgnoredSettingWarning` and recorded in the :class:`~previewctl.control.base.Composition`
(``ctrl.describe()``, and the run log).

Randomness: the GA searches of ``single``, ``multi`` and ``reach`` draw from a
``numpy.random.Generator``, never from numpy's global state. ``seed`` is an ``int`` (the generator is
``np.random.default_rng(seed)``) or a ``Generator`` you own; each imaginary arm gets its own child
stream (``Generator.spawn``), so the arms are independent and the same seed gives the same run.
"""

from __future__ import annotations

import copy
import logging
import warnings
from collections.abc import Callable, Mapping
from dataclasses import MISSING, dataclass, fields
from functools import partial
from typing import Any, Protocol, runtime_checkable

import numpy as np

from previewctl.control.background import BackgroundOptions, BackgroundPlanning, ObservedSide, PlanningSide, answer
from previewctl.control.base import Composition, ControlLaw, Execution
from previewctl.control.controller import CONTROL_PERIOD, FRAME_PERIOD, Controller, Observed, positive_period
from previewctl.control.execution import PseudoInverseExecution, QPExecution
from previewctl.control.imaginary import (
    ArgmaxArms,
    ArmPolicy,
    ImaginaryArms,
    RoutePoints,
    SearchFactory,
    SearchLike,
    TrackedPeaks,
)
from previewctl.control.laws import Gradient, Horizon, MultiPreview, Oracle, QPBaseline, Reach, SinglePreview, Tracking
from previewctl.control.nullspace import AmsipGradient
from previewctl.control.params import (
    CONTROLLER_NAMES,
    MEASURED,
    SETTING_GROUPS,
    ControllerParams,
    ControllerSpec,
    execution_of,
)
from previewctl.control.planner import PeakPlanner, PlanTiming, WindowPlanner
from previewctl.control.sweeps import SweepRoutes
from previewctl.control.worker import Compute
from previewctl.errors import IgnoredSettingWarning, ParameterError, UnknownNameError
from previewctl.index.amsi import IndexParams
from previewctl.index.evaluator import Evaluator
from previewctl.index.potential import Potential
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.scene.shapes import Scene
from previewctl.search.ga import OneStepGA
from previewctl.search.maps import redundancy_map
from previewctl.search.planar import PlanarRedundancy
from previewctl.sensing.options import Sensing
from previewctl.sensing.world import World

_log = logging.getLogger(__name__)

Seed = int | np.random.Generator | None
"""An ``int`` seed, a ``numpy.random.Generator``, or ``None`` (see :func:`make_controller`)."""
PLANNING_MODES = ("inline", "background")
"""Where the searches and the planner run: inside :meth:`Controller.step` (``inline``, the default: deterministic) or
in a worker process beside the loop (``background``, :mod:`previewctl.control.background`)."""
BACKGROUND_CONTROLLERS = ("single", "multi", "reach", "horizon", "oracle")
"""The controllers that can plan in the background (``reach`` with its planner only: coherent, on an arm the window
planner covers); the others have nothing to plan."""


class _Timing(Protocol):
    @property
    def dt(self) -> float: ...

    @property
    def frame(self) -> float: ...


@runtime_checkable
class ScenarioLike(Protocol):
    """What :func:`make_controller` reads from a scenario (:class:`previewctl.sim.scenario.Scenario` has it)."""

    @property
    def robot(self) -> Robot: ...

    @property
    def path(self) -> HandPath: ...

    @property
    def scene(self) -> Scene: ...

    @property
    def controller(self) -> ControllerSpec: ...

    @property
    def index(self) -> IndexParams: ...

    @property
    def potential(self) -> Potential: ...

    @property
    def seed(self) -> int: ...

    @property
    def timing(self) -> _Timing: ...


def make_controller(
    source: ScenarioLike | str,
    *,
    name: str | None = None,
    robot: Robot | None = None,
    path: HandPath | None = None,
    scene: Scene | None = None,
    params: ControllerParams | None = None,
    index: IndexParams | None = None,
    potential: Potential | None = None,
    seed: Seed = None,
    frame: float | None = None,
    dt: float | None = None,
    search_factory: SearchFactory | None = None,
    planning: str = "inline",
    background: BackgroundOptions | None = None,
    worker_compute: Compute | None = None,
    sensing: Sensing | None = None,
) -> Controller:
    """A controller to step from your own loop: ``qdot = ctrl.step(q, t)``.

    Two forms::

        make_controller(scenario)                                   # everything from the scenario
        make_controller("multi", robot=robot, path=path, scene=scene, params=..., seed=0)

    With a scenario, every keyword given replaces the scenario's part (``name="gradient"`` runs
    another mode in the same scene).

    Args:
        source: a scenario (:func:`previewctl.load_scenario`) or a controller name, one of
            :data:`~previewctl.control.params.CONTROLLER_NAMES`.
        name: the controller name, with a scenario (default: the scenario's).
        robot: the arm (its search geometry: convex or capsules); required without a scenario.
        path: the desired hand path; required without a scenario.
        scene: the obstacles (default: none).
        params: gains and settings (default: :class:`ControllerParams`\\ ``()``).
        index: AMSI parameters of the searches' AMSIP (default: the paper's).
        potential: obstacle potential of the AMSIP (default: :class:`Potential`\\ ``()``).
        seed: randomness of the GA searches: an ``int``, or a ``numpy.random.Generator`` used as
            given; ``None``: the scenario's seed, or 0 without a scenario (runs are reproducible
            by default). See the module docstring.
        frame: camera frame period [s] (one GA generation per frame; default: the scenario's or 33 ms).
        dt: control period [s] assumed at the first step (default: the scenario's or 10 ms).
        search_factory: ``factory(i, rng_i)`` building the search of imaginary arm ``i`` (tests
            and experiments); default: a :class:`~previewctl.search.ga.OneStepGA` each. Picklable with
            ``planning="background"``.
        planning: ``inline`` (default) or ``background``: the searches and the planner in a worker process beside
            the loop (:mod:`previewctl.control.background`; close the controller, or use it as a context manager,
            to end the worker).
        background: validity of the worker's results and worker settings (default
            :class:`~previewctl.control.background.BackgroundOptions`\\ ``()``).
        worker_compute: ``compute(side, q, t)`` the worker (the searches' worker, when a route's plans run in a
            worker of their own) runs per state instead of :func:`~previewctl.control.background.answer` (tests: a
            stand-in that blocks); picklable.
        sensing: observe obstacles instead of reading their motion (:class:`~previewctl.sensing.options.Sensing`;
            default: the scenario's ``[sensing]`` table, else none): the obstacles it names leave the scene until
            first observed (``ctrl.observe``), and a change of the set rebuilds the law and the execution
            (:mod:`previewctl.control.controller`).

    Raises:
        UnknownNameError: an unknown controller name (the message lists the valid ones).
        ParameterError: ``source`` neither a scenario nor a name, a missing ``robot``/``path``,
            a bad ``frame``/``dt``/``seed``, settings the controller cannot honour (see :func:`compose`), or
            background planning for a controller that cannot do it or with ``plan_latency = "measured"``.

    Warns:
        IgnoredSettingWarning: a setting the controller does not read (see :func:`compose`).
    """
    base = _defaults(source, name)
    robot = base.robot if robot is None else robot
    path = base.path if path is None else path
    if robot is None or path is None:
        missing = " and ".join(k for k, v in (("robot=", robot), ("path=", path)) if v is None)
        raise ParameterError(f"make_controller({source!r}) needs {missing} (or a scenario instead of the name)")
    if base.name not in CONTROLLER_NAMES:
        raise UnknownNameError("controller", base.name, CONTROLLER_NAMES)
    if planning not in PLANNING_MODES:
        raise UnknownNameError("planning", planning, PLANNING_MODES)
    scene = (base.scene or Scene()) if scene is None else scene
    index = base.index if index is None else index
    potential = base.potential if potential is None else potential
    sensing = base.sensing if sensing is None else sensing
    spatial = None if robot.task == "planar" or robot.planar is not None else robot.name  # as check_dimensions
    world = None if sensing is None else World(scene, sensing, spatial=spatial)
    if world is not None:
        scene = world.scene  # without the observed obstacles until they are observed
    evaluator = Evaluator(robot, scene, index, potential)
    rng = _generator(base.seed if seed is None else seed)
    spec = ControllerSpec(base.name, base.params if params is None else params)
    if planning == "background" and spec.params.plan_latency == MEASURED:
        raise ParameterError("plan_latency = 'measured' stands in for planning beside the loop in an inline run; with "
                             "planning='background' the plans arrive when the worker has made them: leave "
                             "plan_latency out, or use planning='inline'")
    frame = positive_period(base.frame if frame is None else frame, "frame")
    beside = BackgroundPlanning(background or BackgroundOptions(), frame) if planning == "background" else None
    worker_rng = copy.deepcopy(rng)  # the worker's searches draw the streams inline ones would
    parts = compose(spec, robot, scene, evaluator, rng, search_factory=search_factory, beside=beside)
    _log.info("controller %s", parts.composition)
    if parts.composition.ignored:
        warnings.warn(f"controller {spec.name!r} does not use {'; '.join(parts.composition.ignored)}: ignored",
                      IgnoredSettingWarning, stacklevel=2)
    if beside is not None:
        build: Callable[[], Any] = partial(planning_side, spec, robot, path, scene, index, potential, worker_rng,
                                           frame, search_factory)
        if world is not None:  # the worker rebuilds its side on each new set of observed obstacles
            build = partial(ObservedSide, partial(_side_on, spec, robot, path, index, potential, worker_rng, frame,
                                                  search_factory), scene)
        beside.start(build, worker_compute or answer)
    observed = None if world is None else Observed(world, partial(_rebuild, spec, robot, index, potential, rng,
                                                                  search_factory, beside))
    return Controller(parts.law, parts.execution, robot, path, spec.params, parts.composition,
                      frame=frame, dt=base.dt if dt is None else dt, planning=beside, observed=observed)


def _rebuild(spec: ControllerSpec, robot: Robot, index: IndexParams | None, potential: Potential | None,
             rng: np.random.Generator, search_factory: SearchFactory | None, beside: BackgroundPlanning | None,
             scene: Scene) -> tuple[ControlLaw, Execution]:
    """The law and the execution of ``spec`` composed on ``scene`` (an observed world that changed): new searches
    drawing on from ``rng``, a new planner; with background planning, no result in use until the worker answers a state
    posted with the new scene (:meth:`~previewctl.control.background.BackgroundPlanning.rescene`)."""
    parts = compose(spec, robot, scene, Evaluator(robot, scene, index, potential), rng, search_factory=search_factory,
                    beside=beside)
    if beside is not None:
        beside.rescene()
    return parts.law, parts.execution


def planning_side(spec: ControllerSpec, robot: Robot, path: HandPath, scene: Scene, index: IndexParams | None,
                  potential: Potential | None, rng: np.random.Generator, frame: float,
                  search_factory: SearchFactory | None) -> PlanningSide:
    """The background worker's parts (run in the worker): the inline parts that ``spec`` names, composed as
    :func:`make_controller` composes them, and the policy or planner of them that the worker runs."""
    parts = compose(spec, robot, scene, Evaluator(robot, scene, index, potential), rng, search_factory=search_factory)
    law = parts.law
    if isinstance(law, (SinglePreview, MultiPreview)):
        local = law.local if isinstance(law.local, AmsipGradient) else None
        return PlanningSide(law.policy, robot, path, frame, local)
    if isinstance(law, Reach):
        return PlanningSide(law, robot, path, frame)
    if isinstance(law, (Horizon, Oracle)):
        return PlanningSide(law.planner, robot, path, frame)
    raise _no_background(spec.name)


def _side_on(spec: ControllerSpec, robot: Robot, path: HandPath, index: IndexParams | None,
             potential: Potential | None, rng: np.random.Generator, frame: float,
             search_factory: SearchFactory | None, scene: Scene) -> PlanningSide:
    """:func:`planning_side` on ``scene``, the argument that changes last."""
    return planning_side(spec, robot, path, scene, index, potential, rng, frame, search_factory)


def _no_background(name: str) -> ParameterError:
    """The error for background planning asked of controller ``name``, which cannot do it."""
    return ParameterError(f"controller {name!r} cannot plan in the background; valid: "
                          f"{', '.join(BACKGROUND_CONTROLLERS)} (or planning='inline')")


@dataclass(frozen=True)
class _Defaults:
    """What :func:`make_controller` uses for the parts not given: a scenario's, or the library's."""

    name: str
    params: ControllerParams
    seed: int
    frame: float
    dt: float
    robot: Robot | None = None
    path: HandPath | None = None
    scene: Scene | None = None
    index: IndexParams | None = None
    potential: Potential | None = None
    sensing: Sensing | None = None


def _defaults(source: object, name: str | None) -> _Defaults:
    """The defaults of a scenario, or of a bare controller name (no robot, no path, seed 0)."""
    if isinstance(source, str):
        if name is not None:
            raise ParameterError(f"the controller name is given twice: {source!r} and name={name!r}")
        return _Defaults(source, ControllerParams(), 0, FRAME_PERIOD, CONTROL_PERIOD)
    if isinstance(source, ScenarioLike):
        return _Defaults(
            name or source.controller.name, source.controller.params, source.seed, source.timing.frame,
            source.timing.dt, source.robot, source.path, source.scene, source.index, source.potential,
            getattr(source, "sensing", None),  # a scenario's [sensing] table (optional for a ScenarioLike)
        )
    raise ParameterError(
        f"make_controller takes a scenario or a controller name ({', '.join(CONTROLLER_NAMES)}), got {source!r}"
    )


def _generator(seed: int | np.random.Generator) -> np.random.Generator:
    """``seed`` as a generator: a ``Generator`` as is, an ``int`` through ``np.random.default_rng``."""
    if isinstance(seed, np.random.Generator):
        return seed
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ParameterError(f"seed must be an int >= 0 or a numpy.random.Generator, got {seed!r}")
    return np.random.default_rng(int(seed))


@dataclass(frozen=True)
class Parts:
    """What :func:`compose` builds: the law, its execution, and the record of what was chosen."""

    law: ControlLaw
    execution: Execution
    composition: Composition


def compose(
    spec: ControllerSpec,
    robot: Robot,
    scene: Scene,
    evaluator: Evaluator,
    rng: np.random.Generator,
    *,
    search_factory: SearchFactory | None = None,
    beside: BackgroundPlanning | None = None,
) -> Parts:
    """The parts of the controller ``spec`` names, on ``robot`` in ``scene`` (the table of the module docstring).

    Args:
        spec: name and parameters.
        robot: the arm (the search robot: convex geometry).
        scene: the obstacles (the QP execution's dampers).
        evaluator: AMSIP evaluator for the gradient, the searches and the planner.
        rng: random generator; each imaginary arm gets an independent child stream.
        search_factory: ``factory(i, rng_i)`` building the search of imaginary arm ``i``; default: a
            :class:`previewctl.search.ga.OneStepGA` over :func:`previewctl.search.maps.redundancy_map`.
        beside: background planning: it stands in for the imaginary-arm policy or the window planner, which run
            in its worker; ``None``: inline.

    Raises:
        ParameterError: ``imaginary_arms = "route"`` for ``multi`` on an arm the window planner does not cover, or
            ``beside`` for a controller not in :data:`BACKGROUND_CONTROLLERS`.

    A setting the controller does not read is recorded in the composition's ``ignored``
    (:func:`make_controller` warns about it).
    """
    name, params = spec.name, spec.params
    if beside is not None and name not in BACKGROUND_CONTROLLERS:
        raise _no_background(name)
    execution_name = execution_of(name, params)
    execution: Execution = (QPExecution(robot, scene, params) if execution_name == "qp"
                            else PseudoInverseExecution(robot, params))
    read = set(SETTING_GROUPS["tracking"]) | (set(SETTING_GROUPS["qp"]) if execution_name == "qp" else set())
    if params.execution == execution_name:
        read.add("execution")
    law: ControlLaw
    policy: str | None = None
    planner: str | None = None
    if name == "none":
        law = Tracking(robot.nv)
    elif name == "qp":
        law = QPBaseline(robot.nv)
    elif name == "gradient":
        law = Gradient(AmsipGradient(robot, evaluator, params))
        read |= set(SETTING_GROUPS["gradient"])
    elif name == "oracle":
        window = WindowPlanner(robot, evaluator, PlanTiming())
        law, planner = Oracle(robot, params, window if beside is None else beside.planner(window)), window.kind
        read.add("gain")
    elif name == "horizon":
        window = WindowPlanner(robot, evaluator, PlanTiming.of(params))
        law, planner = Horizon(robot, params, window if beside is None else beside.planner(window)), window.kind
        read |= {*SETTING_GROUPS["preview"], *SETTING_GROUPS["plan"]}
    else:
        law, policy, planner = _preview(spec, robot, evaluator, rng, search_factory, beside)
        read |= _preview_reads(name, params, policy, planner)
    ignored = _ignored(params, read)
    composition = Composition(name, type(law).__name__, execution.name, policy, planner, ignored,
                              "inline" if beside is None else beside.name)
    return Parts(law, execution, composition)


def _preview(spec: ControllerSpec, robot: Robot, evaluator: Evaluator, rng: np.random.Generator,
             search_factory: SearchFactory | None,
             beside: BackgroundPlanning | None) -> tuple[ControlLaw, str | None, str | None]:
    """The laws with imaginary arms (``single``, ``multi``, ``reach``): ``(law, imaginary-arm policy, planner)``."""
    name, params = spec.name, spec.params
    planar = robot.planar is not None
    covered = not planar or robot.nq <= 4  # the window planner's reach: the sampled search, or the DP's grid
    weights = (1.0,) if name == "single" else params.weights
    factory = search_factory or _ga_factory(robot, evaluator, params)
    streams = rng.spawn(len(weights))
    searches = [factory(i, streams[i]) for i in range(len(weights))]
    if name == "reach":
        arms = ImaginaryArms(robot, searches, params.preview_time)
        keep = (robot.nv - 1,) if params.coherent and planar else ()
        if params.coherent and covered:
            peak_planner = _peak_planner(robot, evaluator, params)
            kind = peak_planner.planner.kind
            if beside is not None:
                arms, peak_planner = beside.reach(arms, peak_planner)
            return Reach(robot, params, arms, peak_planner, keep=keep), None, kind
        if beside is not None:
            raise ParameterError(f"reach plans in the background only with its planner toward the peaks (coherent, "
                                 f"on an arm the window planner covers); {robot.name!r} with coherent = "
                                 f"{params.coherent} takes straight sweeps: use planning='inline'")
        sweeps = SweepRoutes(robot, params, evaluator, redundancy_map(robot), keep=keep)
        return Reach(robot, params, arms, sweeps, keep=keep), None, "sweeps"
    policy = _policy_name(spec, robot, covered)
    local = AmsipGradient(robot, evaluator, params) if params.with_gradient else None
    arm_policy: ArmPolicy
    planner: str | None = None
    if policy == "route":
        peak_planner = _peak_planner(robot, evaluator, params)
        arm_policy = RoutePoints(robot, ImaginaryArms(robot, searches, params.preview_time), peak_planner,
                                 params.settle_frames)
        planner = peak_planner.planner.kind
    elif policy == "peaks":
        branches = PlanarRedundancy(robot) if planar else None
        arm_policy = TrackedPeaks(robot, ImaginaryArms(robot, searches, params.preview_time, branches), params)
    else:
        arm_policy = ArgmaxArms(ImaginaryArms(robot, searches, params.preview_time))
    law_class = SinglePreview if name == "single" else MultiPreview
    if beside is not None:
        arm_policy = beside.arms(arm_policy)
    term = local if beside is None or local is None else beside.gradient(local)
    return law_class(robot, params, arm_policy, weights, term), policy, planner


def _preview_reads(name: str, params: ControllerParams, policy: str | None, planner: str | None) -> set[str]:
    """The settings ``single``, ``multi`` and ``reach`` read, besides eq. 19's and the execution's."""
    read = {"gain", "preview_time", "coherent", *SETTING_GROUPS["ga"]}
    if name != "single":
        read |= {"weights", "previews"}
    if name == "multi" and params.coherent:
        read.add("imaginary_arms")
    if name != "reach":
        read.add("with_gradient")
        if params.with_gradient:
            read |= set(SETTING_GROUPS["gradient"])
    if policy == "peaks":
        read |= set(SETTING_GROUPS["peaks"])
    if (name == "reach" and params.coherent) or policy == "route":  # the routes toward the peaks
        read |= {"hysteresis", "track_radius", "settle_frames"}
    if planner in ("dp", "sampled"):
        read |= set(SETTING_GROUPS["plan"])
    return read


def _policy_name(spec: ControllerSpec, robot: Robot, covered: bool) -> str:
    """``argmax``, ``peaks`` or ``route`` for ``single`` or ``multi`` (see the module docstring).

    Raises:
        ParameterError: ``imaginary_arms = "route"`` on an arm the window planner does not cover.
    """
    params = spec.params
    if not params.coherent:
        return "argmax"
    if spec.name == "single":
        return "peaks"
    if params.imaginary_arms == "route" and not covered:
        raise ParameterError(
            f"imaginary_arms = 'route' needs an arm the window planner covers (a spatial arm, or a planar arm of at "
            f"most 4 joints); {robot.name!r} is planar with {robot.nq} joints: use imaginary_arms = 'peaks', or leave "
            "it out (the default picks 'peaks' there)")
    return params.imaginary_arms or ("route" if covered else "peaks")


def _peak_planner(robot: Robot, evaluator: Evaluator, params: ControllerParams) -> PeakPlanner:
    """The window planner toward the imaginary arms' peaks of coherent ``reach`` and ``multi`` on the route."""
    return PeakPlanner(robot, WindowPlanner(robot, evaluator, PlanTiming.of(params)), hysteresis=params.hysteresis,
                       track_radius=params.track_radius)


def _ignored(params: ControllerParams, read: set[str]) -> tuple[str, ...]:
    """The settings of ``params`` set to other than their default that are not in ``read``, as ``field = value``."""
    ignored = []
    for f in fields(ControllerParams):
        default = f.default if f.default is not MISSING else f.default_factory()  # type: ignore[misc,operator]
        value = getattr(params, f.name)
        if f.name not in read and value != default:
            ignored.append(f"{f.name} = {value!r}")
    return tuple(ignored)


def _ga_factory(robot: Robot, evaluator: Evaluator, params: ControllerParams) -> SearchFactory:
    """The default search factory: one 1-step GA per imaginary arm, all on one redundancy map."""
    redundancy = redundancy_map(robot)
    options: Mapping[str, Any] = dict(params.ga_options)

    def factory(i: int, rng: np.random.Generator) -> SearchLike:  # the options were checked by ControllerParams
        return OneStepGA(robot, evaluator, redundancy, rng,
                         population=params.population, elite=params.elite, top_k=params.top_k, **options)

    return factory
