"""One benchmark run as a plain, picklable task: its spec, its key, and the function a worker runs.

A :class:`RunSpec` holds only names and numbers; the worker builds the robot, the scenario and the
controller itself (:func:`run`), caching per process what several runs share: the robots
(:func:`~previewctl.bench.scenes.cached_robot`) and the last scenarios built. Pinocchio and Coal
objects never cross a process boundary.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import math
import statistics
import time
from dataclasses import dataclass
from typing import Any, cast

from previewctl.bench.metrics import run_metrics
from previewctl.bench.pink import BARRIER_GAINS, PinkExecution, make_pink_controller
from previewctl.bench.robots import cached_robot, profile, urdf_digest
from previewctl.bench.scenes import BenchScene
from previewctl.bench.settings import SceneSettings
from previewctl.control.base import ControlLaw
from previewctl.control.factory import make_controller
from previewctl.control.laws import Oracle
from previewctl.control.params import MEASURED, ControllerSpec, ExecutionMode
from previewctl.control.planner import WindowPlanner
from previewctl.errors import shared_settings
from previewctl.index.evaluator import Evaluator
from previewctl.search.reachability import ReachMotion
from previewctl.sensing.options import Sensing
from previewctl.sensing.predictors import ManoeuvreKalman
from previewctl.sim.log import RunResult
from previewctl.sim.loop import simulate
from previewctl.sim.scenario import Scenario, scenario_from_dict

KEY_FIELDS = ("robot", "scene", "seed", "controller", "execution", "settings", "latency", "sensing")
"""The fields of a run's key: a result line with the same values is the same run."""

INLINE = "none"
LATENCIES = (INLINE, MEASURED)
"""When a run's plans take effect: ``none``, as the scene's settings say (within the cycle that makes them), or
``measured``, after each plan's own CPU time (``plan_latency = "measured"``,
:data:`~previewctl.control.params.PlanLatency`): what planning beside the loop costs, in a run that depends on the
host's speed."""
LATENCY_CONTROLLERS = ("multi", "reach", "horizon")
"""The controllers whose plans a measured latency delays (the window planner's, replanned); the others run once,
inline (the ``oracle`` makes one plan, followed at once)."""

KNOWN = "none"
OBSERVED = "observed"
SENSINGS = (KNOWN, OBSERVED)
"""What the controller knows of the moving obstacles: ``none`` (no sensing), their true motion, perfect foresight;
``observed``, only observations of it (:data:`OBSERVED_SENSING`, :mod:`previewctl.sim.sensor`)."""
OBSERVED_SENSING = Sensing(rate=30.0, noise=0.005, latency=0.05, dropout=0.0)
"""The sensing of an observed run: 30 Hz, 5 mm noise, 50 ms latency, no dropout (issue 33's targets); its ``seed`` is
the scene's index, so every controller of a scene gets the same observations."""
FORESIGHT_CONTROLLERS = ("none", "oracle", *BARRIER_GAINS)
"""The controllers that run with perfect foresight only: ``none`` reads no obstacle, the ``oracle`` follows the
witness's plan of the true future (what was possible), and the pink baselines place the true obstacles (pink has
no observed-obstacle interface)."""

GENERATOR_VERSION = 2
"""Bumped when :mod:`previewctl.bench.scenes` draws differently: old results no longer match."""


@dataclass(frozen=True)
class RunSpec:
    """One run of the sweep matrix.

    Attributes:
        robot: robot name.
        scene: scene index.
        seed: the controller's random seed (GA stream).
        controller: controller name.
        execution: execution mode (``ControllerParams.execution``).
        settings: :func:`settings_hash` of the scene settings and scene seed.
        scene_seed: the seed the scene was drawn with.
        latency: one of :data:`LATENCIES`.
        sensing: one of :data:`SENSINGS`.
    """

    robot: str
    scene: int
    seed: int
    controller: str
    execution: str
    settings: str
    scene_seed: int = 0
    latency: str = INLINE
    sensing: str = KNOWN

    @property
    def key(self) -> tuple[Any, ...]:
        """The run's identity in the results file."""
        return tuple(getattr(self, name) for name in KEY_FIELDS)


def run_latency(name: str, latency: str) -> str:
    """The latency controller ``name`` runs with when ``latency`` is asked: itself for the controllers of
    :data:`LATENCY_CONTROLLERS`, ``none`` for the others (a measured latency changes nothing in their runs)."""
    return latency if name in LATENCY_CONTROLLERS else INLINE


def run_sensing(name: str, sensing: str) -> str:
    """The sensing controller ``name`` runs with when ``sensing`` is asked: itself, but ``none`` for the
    :data:`FORESIGHT_CONTROLLERS`."""
    return KNOWN if name in FORESIGHT_CONTROLLERS else sensing


_KEY_DEFAULTS = {"latency": INLINE, "sensing": KNOWN}
"""What a result line written before its key had these fields ran with: inline plans, perfect foresight."""


def record_key(record: dict[str, Any]) -> tuple[Any, ...]:
    """The key of a result line (see :data:`KEY_FIELDS`; a line written before runs had a latency is inline, one
    written before they had a sensing ran with perfect foresight)."""
    return tuple(record.get(name, _KEY_DEFAULTS.get(name)) for name in KEY_FIELDS)


_ADDED_DEFAULTS = (("motions", "constant"), ("history", 0.0))
"""Settings added after results were recorded, at their defaults: left out of the hash, so that those results keep
their key."""


def settings_hash(robot: str, scene_seed: int, settings: SceneSettings) -> str:
    """12 hex digits that change with anything that changes a run of ``robot`` but its key's other fields (a URDF
    file's content among them)."""
    drawn = {k: v for k, v in dataclasses.asdict(settings).items() if (k, v) not in _ADDED_DEFAULTS}
    described = {"robot": robot, "scene_seed": scene_seed, "settings": drawn,
                 "profile": dataclasses.asdict(profile(robot)), "generator": GENERATOR_VERSION}
    digest = urdf_digest(robot)
    if digest is not None:
        described["urdf"] = digest
    return hashlib.sha256(json.dumps(described, sort_keys=True).encode()).hexdigest()[:12]


@functools.lru_cache(maxsize=4)
def _scenario(document: str) -> Scenario:
    """The scenario of a scene document (JSON text), built once per process for its runs."""
    data = json.loads(document)
    return scenario_from_dict(data, source=data["name"])


def simulate_spec(spec: RunSpec, scene: BenchScene) -> tuple[Scenario, RunResult, dict[str, Any]]:
    """Simulate ``spec`` on ``scene``: the run's scenario (the scene with the spec's controller, execution, latency
    and sensing), its log (exact check on the robot's mesh geometry) and what its result line adds for this
    controller: the CPU times of its window planner's plans (:func:`plan_costs`), or for a pink baseline
    (:mod:`previewctl.bench.pink`) the cycles where it found no solution and its own time per cycle
    (:meth:`~previewctl.bench.pink.PinkExecution.record`).
    An ``oracle`` follows the scene's
    :attr:`~BenchScene.oracle_plan` when it has one: the plan it would make (a test checks the runs are the same),
    made once per scene by the witness, so this run's CPU time leaves the planning out."""
    base = _scenario(json.dumps(scene.document, sort_keys=True))
    execution = cast(ExecutionMode, spec.execution)  # ControllerParams checks the value
    params = dataclasses.replace(base.controller.params, execution=execution)
    if spec.latency == MEASURED:
        params = dataclasses.replace(params, plan_latency=MEASURED)
    sensing = (dataclasses.replace(OBSERVED_SENSING, seed=spec.scene, history=scene.history)
               if spec.sensing == OBSERVED else None)
    exact = Evaluator(cached_robot(spec.robot, "mesh"), base.scene, base.index, base.potential)
    if spec.controller in BARRIER_GAINS:  # perfect foresight only (run_sensing)
        scenario = dataclasses.replace(base, controller=ControllerSpec(base.controller.name, params))
        pink = make_pink_controller(spec.controller, scenario.robot, scenario.path, scenario.scene, params,
                                    scenario.timing.dt)
        result = simulate(scenario, controller=pink, exact_evaluator=exact)
        return scenario, result, cast(PinkExecution, pink.execution).record()
    scenario = dataclasses.replace(base, controller=ControllerSpec(spec.controller, params), sensing=sensing)
    with shared_settings():  # every controller gets the profile's one table
        controller = make_controller(scenario, seed=spec.seed)
    if isinstance(controller.law, Oracle) and scene.oracle_plan:
        controller.law.planner.motion = ReachMotion.from_json(scene.oracle_plan)
    result = simulate(scenario, controller=controller, exact_evaluator=exact)
    planner = window_planner(controller.law)
    return scenario, result, plan_costs([] if planner is None else planner.costs)


def window_planner(law: ControlLaw) -> WindowPlanner | None:
    """The window planner of a law: ``horizon``'s and ``oracle``'s own, coherent ``reach``'s route's, ``multi``'s
    on the route; ``None`` for a law without one."""
    part = getattr(law, "planner", None) or getattr(law, "route", None) or getattr(getattr(law, "policy", None),
                                                                                   "planner", None)
    part = getattr(part, "planner", part)  # a PeakPlanner holds its window planner
    return part if isinstance(part, WindowPlanner) else None


def plan_costs(costs: list[float]) -> dict[str, Any]:
    """A run's plan CPU times [s] in its result line: how many, median, p95 and max (nothing without plans)."""
    if not costs:
        return {}
    ordered = sorted(costs)
    p95 = ordered[min(len(ordered) - 1, math.ceil(0.95 * len(ordered)) - 1)]
    return {"plans": len(costs), "plan_cpu_p50": statistics.median(costs), "plan_cpu_p95": p95,
            "plan_cpu_max": ordered[-1]}


def sensing_summary(sensing: Sensing) -> str:
    """What an observed run was fed and predicted with, in one line (the result line's ``sensing_settings``)."""
    predictor = sensing.new_predictor()
    noise = (f"q = {predictor.models[0].q:g} cruising, {predictor.models[1].q:g} manoeuvring"
             if isinstance(predictor, ManoeuvreKalman) else f"q = {sensing.process_noise:g}")
    history = f", observed from {sensing.history:g} s before the start" if sensing.history else ""
    return (f"{sensing.rate:g} Hz, {sensing.noise * 1e3:g} mm noise, {sensing.latency * 1e3:g} ms latency, dropout "
            f"{sensing.dropout:g}{history}; predicted by {sensing.predictor}, {noise} m²/s³, margin "
            f"min({sensing.margin_cap * 1e2:g} cm, {sensing.confidence:g} σ)")


def run(spec: RunSpec, scene: BenchScene) -> dict[str, Any]:
    """Simulate ``spec`` on ``scene``: the result line (the spec's fields, the metrics, the wall and CPU time
    of the worker [s]; on a shared host the CPU time is the fairer cost; and its plans' CPU times, :func:`plan_costs`).

    The ``oracle`` run the scene's witness made (:attr:`BenchScene.oracle_run`) is this run when the execution
    and seed are its own: its line is made from it (with its times) instead of simulating it again."""
    made = scene.oracle_run
    if made is not None and spec.controller == "oracle" and (spec.execution, spec.seed) == (made["execution"],
                                                                                           made["seed"]):
        metrics = {k: v for k, v in made.items() if k not in ("execution", "seed")}
        return {**dataclasses.asdict(spec), "scenario": scene.document["name"], **metrics}
    start, cpu = time.perf_counter(), time.process_time()
    scenario, result, fields = simulate_spec(spec, scene)
    sensed = {} if scenario.sensing is None else {"sensing_settings": sensing_summary(scenario.sensing)}
    return {**dataclasses.asdict(spec), "scenario": scenario.name, **run_metrics(result), **fields, **sensed,
            "wall_time": time.perf_counter() - start, "cpu_time": time.process_time() - cpu}
