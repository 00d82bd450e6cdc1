"""Building a controller: :func:`make_controller` (from a scenario or from parts) and :func:`build_law`.

The names: ``none``, ``qp``, ``gradient``, ``single``, ``multi``, ``reach``, ``horizon`` (the reachability DP
over the preview window, replanned) and ``oracle`` (non-causal: it follows the reachability DP's best motion
over the whole future, a reference for the others; on spatial arms both plan by the sampled search of
:mod:`previewctl.search.roadmap`). Every one is
executed through the constrained QP unless ``params.execution = "pseudoinverse"``; ``qp`` always is.

Coherent ``multi`` with ``imaginary_arms = "route"`` (the default) is built as
:class:`~previewctl.control.reach.ReachController` with ``blend=True`` wherever that plans its moves (spatial arms,
planar arms of up to 4 joints): eq. 21 on the planned route's configurations.

Randomness: the GA searches of ``single``, ``multi`` and ``reach`` draw from a
``numpy.random.Generator``, never from numpy's global state. ``seed`` is an ``int`` (the generator is
``np.random.default_rng(seed)``) or a ``Generator`` you own; each imaginary arm gets its own child
stream (``Generator.spawn``), so the arms are independent and the same seed gives the same run.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from previewctl.control.base import ControlLaw
from previewctl.control.controller import CONTROL_PERIOD, FRAME_PERIOD, Controller
from previewctl.control.execution import QPExecution
from previewctl.control.gradient import GradientController
from previewctl.control.oracle import OracleController
from previewctl.control.params import CONTROLLER_NAMES, ControllerParams, ControllerSpec
from previewctl.control.preview import PreviewController, SearchFactory, SearchLike
from previewctl.control.reach import ReachController
from previewctl.control.tracking import TrackingController
from previewctl.errors import ParameterError, UnknownNameError
from previewctl.index.amsi import IndexParams
from previewctl.index.evaluator import Evaluator
from previewctl.index.potential import Potential
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.scene.shapes import Scene
from previewctl.search.ga import OneStepGA
from previewctl.search.maps import redundancy_map

Seed = int | np.random.Generator | None
"""An ``int`` seed, a ``numpy.random.Generator``, or ``None`` (see :func:`make_controller`)."""


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
) -> Controller:
    """A controller to step from your own loop: ``qdot = ctrl.step(q, t)``.

    Two forms::

        make_controller(scenario)                                   # everything from the scenario
        make_controller("multi", robot=robot, path=path, scene=scene, params=..., seed=0)

    With a scenario, every keyword given replaces the scenario's part (``name="gradient"`` runs
    another mode in the same scene).

    Args:
        source: a scenario (:func:`previewctl.load_scenario`) or a controller name: ``none``,
            ``gradient``, ``single``, ``multi`` or ``reach``.
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
            and experiments); default: a :class:`~previewctl.search.ga.OneStepGA` each.

    Raises:
        UnknownNameError: an unknown controller name (the message lists the valid ones).
        ParameterError: ``source`` neither a scenario nor a name, a missing ``robot``/``path``,
            or a bad ``frame``/``dt``/``seed``.
    """
    base = _defaults(source, name)
    robot = base.robot if robot is None else robot
    path = base.path if path is None else path
    if robot is None or path is None:
        missing = " and ".join(k for k, v in (("robot=", robot), ("path=", path)) if v is None)
        raise ParameterError(f"make_controller({source!r}) needs {missing} (or a scenario instead of the name)")
    if base.name not in CONTROLLER_NAMES:
        raise UnknownNameError("controller", base.name, CONTROLLER_NAMES)
    scene = (base.scene or Scene()) if scene is None else scene
    evaluator = Evaluator(
        robot,
        scene,
        base.index if index is None else index,
        base.potential if potential is None else potential,
    )
    rng = _generator(base.seed if seed is None else seed)
    spec = ControllerSpec(base.name, base.params if params is None else params)
    law = build_law(spec, robot, evaluator, rng, search_factory=search_factory)
    execution = QPExecution(robot, scene, spec.params) if uses_qp(spec) else None
    return Controller(law, robot, path, frame=base.frame if frame is None else frame,
                      dt=base.dt if dt is None else dt, execution=execution)


def uses_qp(spec: ControllerSpec) -> bool:
    """Whether the controller ``spec`` names is executed by the constrained QP (``qp`` always is)."""
    return spec.name == "qp" or spec.params.execution == "qp"


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


def build_law(
    spec: ControllerSpec,
    robot: Robot,
    evaluator: Evaluator,
    rng: np.random.Generator,
    *,
    search_factory: SearchFactory | None = None,
) -> ControlLaw:
    """The control law ``spec`` names, without the loop bookkeeping of :class:`Controller`.

    Args:
        spec: name and parameters.
        robot: the arm (the search robot: convex geometry).
        evaluator: AMSIP evaluator for the gradient and the searches.
        rng: random generator; each imaginary arm gets an independent child stream.
        search_factory: ``factory(i, rng_i)`` building the search of preview ``i``; default: a
            :class:`previewctl.search.ga.OneStepGA` over :func:`previewctl.search.maps.redundancy_map`.
    """
    params = spec.params
    if spec.name in ("none", "qp"):
        return TrackingController(robot, params, spec.name)
    if spec.name == "gradient":
        return GradientController(robot, evaluator, params)
    if spec.name == "oracle":  # non-causal reference: plans over the whole future at its first command
        return OracleController(robot, params, evaluator)
    if spec.name == "horizon":  # causal: replans over the preview window [t, t + p t̃]
        return OracleController.horizon(robot, params, evaluator)
    mode = "multi" if spec.name == "reach" else spec.name
    count = len(params.preview_weights(mode))
    factory = search_factory or _ga_factory(robot, evaluator, params, spec.name)
    streams = rng.spawn(count)
    searches = [factory(i, streams[i]) for i in range(count)]
    routed = spec.name == "multi" and params.imaginary_arms == "route" and ReachController.plans(robot, params)
    if spec.name == "reach" or routed:
        return ReachController(robot, params, evaluator, searches, redundancy_map(robot), blend=spec.name == "multi")
    return PreviewController(robot, params, spec.name, searches, evaluator)


def _ga_factory(robot: Robot, evaluator: Evaluator, params: ControllerParams, mode: str) -> SearchFactory:
    """The default search factory: one 1-step GA per imaginary arm."""
    redundancy = redundancy_map(robot)
    options: Mapping[str, Any] = dict(params.ga_options)

    def factory(i: int, rng: np.random.Generator) -> SearchLike:  # the options were checked by ControllerParams
        return OneStepGA(robot, evaluator, redundancy, rng,
                         population=params.population, elite=params.elite, top_k=params.top_k, **options)

    return factory
