"""Planning beside the loop: the searches and the planner in a worker process, the loop reading their latest result.

With ``make_controller(..., planning="background")`` the slow parts of a controller, its imaginary arms' GA searches
(one generation per camera frame per arm) and its window planner, run in a
:class:`~previewctl.control.worker.PlanningWorker` (a process at a lower OS priority), and
:meth:`Controller.step <previewctl.control.controller.Controller.step>` never waits for them:

* at each camera frame the loop posts its state ``(q, t)``; the worker, when idle, takes the latest one, runs the
  parts as inline planning would at that state (:class:`PlanningSide`) and answers with a :class:`PlanningResult`:
  the imaginary arms' targets (``argmax`` and ``peaks`` policies) or the plan being followed (``horizon``,
  ``oracle``), the state time ``t0`` it was computed from, and its compute time;
* a part with both searches and a planner toward their peaks (the ``route`` policy, ``reach``) runs in two workers,
  so that a plan (hundreds of ms on a spatial arm) stops no generation: the searches' worker (:class:`Searches`)
  answers every state with one generation, the best candidates and the positive peaks; the loop relays the latest
  peaks with each state it posts to the plans' worker (:class:`Plans`, :class:`PlanNews`), which answers with a
  plan when one is due (and ``reach``'s goal). The plan's age decides the fallback, as with one worker;
* a plan delivered at ``t1`` is followed from where the arm is at ``t1``
  (:meth:`WindowPlanner.follow <previewctl.control.planner.WindowPlanner.follow>`): read at the present time,
  moved to start at the arm, and faded back into itself over one replan period;
* with ``with_gradient`` (``single``, ``multi``) the worker also computes the local term's ``∇_q S`` at each state
  posted (:class:`BackgroundGradient`): about 2 ms on the Panda, too much for a 4 ms cycle. The loop applies
  ``K_g ∇_q S(q0, t0)``, the gradient at the state ``(q0, t0)`` posted last, while it is at most ``arms_valid_frames``
  frames old, and no local term after that. A stale gradient is the slope where the arm was up to that long ago
  (``|q̇| · age`` away: up to about 0.1 rad at 1 rad/s): it shapes the null-space motion only, while the QP's
  dampers, computed at every cycle from the present distances, keep the links clear;
* a result is valid while its age ``t − t0`` is at most ``arms_valid_frames`` frames (targets) or
  ``plan_valid_periods`` replan periods (plans; a plan over the whole future, ``oracle``'s, stays valid). With no
  valid result, or a worker (either of two) that crashed, failed or stopped answering, the cycle runs the ``qp`` law
  (``v = 0``; the QP execution still guards) and ``last_info`` says so (``plan_age``, ``fallback``,
  ``worker_error``). The searches' worker of two runs ``search_niceness`` lower than the plans' worker.

With observed obstacles (:mod:`previewctl.sensing`) the worker predicts from the same observations as the loop: each
state posted carries the observed obstacles (their tracks: a predictor's mean, covariance and time, a few hundred
bytes each), and the worker's :class:`ObservedSide` takes their states, or rebuilds its parts when the set of obstacles
changed.

Inline planning stays the default everywhere: it is deterministic, and a background run is not (it depends on how
fast the worker is).
"""

from __future__ import annotations

import contextlib
import math
import os
import struct
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from functools import partial
from typing import Annotated

import numpy as np
from pydantic import Field

from previewctl.control.base import ControlState, PlanningStatus
from previewctl.control.imaginary import ArmPolicy, ImaginaryArms, RoutePoints, Targets, plan_points
from previewctl.control.laws import Reach
from previewctl.control.nullspace import AmsipGradient
from previewctl.control.planner import PeakPlanner, WindowPlanner
from previewctl.control.worker import Compute, PlanningWorker
from previewctl.errors import ConfigurationError, PlanningWorkerError
from previewctl.kinematics import kinematics, kinematics_reader
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.scene.shapes import Obstacle, Scene
from previewctl.search.reachability import ReachMotion
from previewctl.sensing.track import Track
from previewctl.types import Array
from previewctl.validation import Checked, Integer, Positive

APART_CORES = 4
"""The cores from which a route's searches and plans run in two workers by default (the loop, two workers and the
simulator's or the robot's own processes)."""


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity, which a container's limit sets; else the machine's)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def _loop_core(cores: set[int]) -> int:
    """The core left to the loop among ``cores`` (those the process may run on): the lowest-numbered."""
    return min(cores)


def worker_cores() -> frozenset[int] | None:
    """The cores the workers may run on so as to leave the loop one: all this process may run on but the
    lowest-numbered; for a loop pinned to one core (``os.sched_setaffinity``), every other core of the machine.
    ``None`` (no restriction) on a one-core machine or where the OS sets no CPU affinity."""
    if not hasattr(os, "sched_getaffinity"):
        return None
    loop = os.sched_getaffinity(0)
    others = loop - {_loop_core(loop)} if len(loop) >= 2 else set(range(os.cpu_count() or 1)) - loop
    return frozenset(others) or None


@contextlib.contextmanager
def on_the_loop_core() -> Iterator[None]:
    """Run the calling thread on the core :func:`worker_cores` leaves to the loop (its lowest), then restore its CPU
    affinity; nothing where the OS sets none or on one core. A loop on every core is woken on whichever is free,
    the workers' included (docs/speed.md, "A core for the loop")."""
    if not hasattr(os, "sched_getaffinity") or len(before := os.sched_getaffinity(0)) < 2:
        yield
        return
    os.sched_setaffinity(0, {_loop_core(before)})
    try:
        yield
    finally:
        os.sched_setaffinity(0, before)


LOOP_PRIORITY = 50
"""The real-time priority (``SCHED_FIFO``, 1-99) :func:`real_time_priority` asks for: mid-range, as ``ros2_control``'s
control loop does, below the kernel's own real-time threads."""


@contextlib.contextmanager
def real_time_priority(priority: int = LOOP_PRIORITY) -> Iterator[bool]:
    """Run the calling thread in Linux's real-time class (``SCHED_FIFO`` at ``priority``), where no ordinary process
    preempts it, then restore its policy; a process it starts meanwhile (a worker) starts in the ordinary class
    (``SCHED_RESET_ON_FORK``). Yields whether the OS granted it: without the permission (``CAP_SYS_NICE``, or an
    ``rtprio`` limit in ``/etc/security/limits.conf``) or off Linux, the thread runs as before. The loop sleeps to
    each deadline, so it leaves the core between cycles (docs/speed.md, "A real-time priority for the loop")."""
    if not hasattr(os, "SCHED_RESET_ON_FORK"):  # Linux's: elsewhere a worker would inherit the class
        yield False
        return
    policy, param = os.sched_getscheduler(0), os.sched_getparam(0)
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO | os.SCHED_RESET_ON_FORK, os.sched_param(priority))
    except OSError:
        yield False
        return
    try:
        yield True
    finally:
        os.sched_setscheduler(0, policy, param)


WAKE_LATENCY_FILE = "/dev/cpu_dma_latency"
"""Linux's PM QoS request for the CPUs' wake-up latency: an int32 [µs] written to it holds while the file is open."""


@contextlib.contextmanager
def prompt_wake_up(path: str = WAKE_LATENCY_FILE) -> Iterator[bool]:
    """Keep every core out of its deep idle states until the context ends: a PM QoS request for a 0 µs wake-up
    latency, written to ``path`` and held open, as ``cyclictest`` does. A loop that sleeps to each deadline then finds
    its core polling instead of halted (on a virtual machine, handed back to the hypervisor): on
    the 2-core host of docs/speed.md it lowered the step's p99 and the missed deadlines in every round measured ("Cores
    kept awake"). The idle cores poll meanwhile, which costs their power. Yields whether the OS took the request: the
    file is root's (mode 600), and there is none off Linux."""
    try:
        fd = os.open(path, os.O_WRONLY)
    except OSError:
        yield False
        return
    try:
        granted = os.write(fd, struct.pack("i", 0)) == 4
    except OSError:
        granted = False
    try:
        yield granted
    finally:
        os.close(fd)


FIFO_REFUSED = ("the loop runs in the ordinary scheduling class: the OS refused SCHED_FIFO (it needs CAP_SYS_NICE or "
                "an rtprio limit), so other processes may delay its cycles")
"""What a loop says when :func:`real_time_loop` was not granted the real-time class."""

WAKE_REFUSED = (f"the cores may sleep deeply between the loop's cycles: the OS refused the request for a 0 µs wake-up "
                f"latency ({WAKE_LATENCY_FILE} is root's), so each cycle may start on a cold core")
"""What a loop says when :func:`real_time_loop` could not keep the cores awake."""


@dataclass(frozen=True)
class RealTimeGrants:
    """What the OS granted a :func:`real_time_loop`.

    Attributes:
        fifo: the real-time class (:func:`real_time_priority`).
        awake: the cores kept out of deep idle states (:func:`prompt_wake_up`).
    """

    fifo: bool
    awake: bool

    @property
    def refusals(self) -> tuple[str, ...]:
        """A warning per request the OS refused."""
        return (() if self.fifo else (FIFO_REFUSED,)) + (() if self.awake else (WAKE_REFUSED,))


@contextlib.contextmanager
def real_time_loop() -> Iterator[RealTimeGrants]:
    """The calling thread as a real-time loop beside its workers, until the context ends: on the core they leave
    free (:func:`on_the_loop_core`), in the real-time class (:func:`real_time_priority`) and with the cores kept awake
    (:func:`prompt_wake_up`) if the OS grants them (it yields what it granted)."""
    with on_the_loop_core(), real_time_priority() as fifo, prompt_wake_up() as awake:
        yield RealTimeGrants(fifo=fifo, awake=awake)


@dataclass(frozen=True)
class BackgroundOptions(Checked):
    """How long the worker's results stay valid, and how the worker runs.

    Attributes:
        arms_valid_frames: the imaginary arms' targets are valid for this many camera frames after the state they
            were computed from (a GA generation per frame: a few frames late is still the same peak).
        plan_valid_periods: a plan is valid for this many replan periods after the state it was made from (the
            worker makes the next one meanwhile); a plan over the whole future (``oracle``) stays valid.
        timeout: wall time [s] a posted state may stay unanswered before the worker counts as hung (its start, the
            import of the package and the rebuild of the parts, falls within the first).
        niceness: how much the worker lowers its OS priority below the loop's (``os.nice``, 0-19).
        search_niceness: with the searches and the plans in two workers, how much further the searches' worker
            lowers its priority below the plans' (0-19): when the cores are short, the plan the loop follows goes
            before a generation (docs/speed.md, "Plans in a worker of their own").
        plans_apart: run a part's searches and plans in two workers (``False``: one worker runs both, one process
            fewer beside the loop, and no generation while it makes a plan). Default: two workers when the process
            may run on at least :data:`APART_CORES` cores (:func:`available_cores`); on two shared cores one
            worker kept the real-time Panda runs' plans fresher (docs/speed.md, "Plans in a worker of their own").
        loop_core: keep the workers off one core, the lowest-numbered this process may run on (:func:`worker_cores`),
            so that the loop always finds it free. Without it the OS places a worker, woken by the loop's message,
            on the loop's core, and the loop's step waits (docs/speed.md, "A core for the loop"). No effect on one
            core; ``False``: the workers run on every core this process may.
    """

    arms_valid_frames: Positive = 3.0
    plan_valid_periods: Positive = 3.0
    timeout: Positive = 20.0
    niceness: Annotated[Integer, Field(ge=0, le=19)] = 5
    search_niceness: Annotated[Integer, Field(ge=0, le=19)] = 3
    plans_apart: bool = field(default_factory=lambda: available_cores() >= APART_CORES)
    loop_core: bool = True


@dataclass(frozen=True)
class PlanningResult:
    """What the worker hands back for one state.

    Attributes:
        made: the state time ``t0`` [s] the result was computed from (a plan's: the time it starts at).
        compute: the wall time [s] the worker spent on that state.
        targets: the imaginary arms' targets (``argmax`` and ``peaks`` policies), else ``None``.
        motion: a new plan to follow (``route`` policy, ``reach``, ``horizon``, ``oracle``), else ``None``.
        best: ``reach``: the imaginary arms' best candidates and their AMSIP at the last frame, else ``None``.
        goal: ``reach``: the peak the plan heads for, ``(level, configuration, S)``, or ``None``.
        local: ``(t0, ∇_q S)``: the AMSIP gradient ``(nv,)`` [1/rad] at the state posted at ``t0`` [s] (laws
            ``with_gradient``), else ``None``.
        peaks: the searches' positive peaks at the last frame, ``(t_i [s], nodes (K, nq), S (K,))`` per preview
            time, when the searches and the plans run in two workers (:class:`Searches`), else ``None``.
        frames: the generations the searches have run (with ``peaks``).
    """

    made: float
    compute: float
    targets: Targets | None = None
    motion: ReachMotion | None = None
    best: tuple[Array, Array] | None = None
    goal: tuple[int, Array, float] | None = None
    local: tuple[float, Array] | None = None
    peaks: list[tuple[float, Array, Array]] | None = None
    frames: int = 0


class PlanningSide:
    """The worker's side: the inline parts of the controller, run at each state the loop posts.

    Every state posted starts a camera frame (the loop posts once per frame): the searches run one generation, and
    the planner plans when due. A policy or law that has both, searches and a planner toward their peaks
    (``route`` points, ``reach``), runs them in two workers (:meth:`searches` in one, :meth:`plans` in the other), so
    that a plan, which takes many frames, stops no generation; the others run in one (the call).

    Args:
        part: the imaginary-arm policy (``single``, ``multi``), the law (``reach``: its searches and its planner
            toward their peaks) or the window planner (``horizon``, ``oracle``).
        robot: the arm.
        path: the desired hand path.
        frame: camera frame period [s].
        local: the law's AMSIP gradient term, whose ``∇_q S`` each result carries, or ``None``.
    """

    def __init__(self, part: ArmPolicy | Reach | WindowPlanner, robot: Robot, path: HandPath, frame: float,
                 local: AmsipGradient | None = None) -> None:
        self.part, self.robot, self.path, self.frame, self.local = part, robot, path, frame, local
        self._reader = kinematics_reader(robot)
        self._data = robot.model.createData()
        self._sent: ReachMotion | None = None
        # a process's first compiled call loads numba's registries (about 0.3 s): here, while the worker starts, not
        # at its first state (the loop then went without a generation for 14-22 frames)
        kinematics(robot, robot.random_configurations(np.random.default_rng(0), 1),
                   reader=kinematics_reader(robot, compiled=True))

    def __call__(self, q: Array, t: float) -> PlanningResult | None:
        """The result for the state ``(q, t)``; ``None`` when it holds nothing new (the same plan as before).

        Raises:
            ConfigurationError: a part with searches and a planner (:func:`split_parts`): :meth:`searches` and
                :meth:`plans` run it.
        """
        start = time.perf_counter()
        part = self.part
        if split_parts(part) is not None:
            raise ConfigurationError("searches and a planner toward their peaks run in two workers: searches() and "
                                     "plans() answer for them")
        state = self._state(q, t)
        if isinstance(part, WindowPlanner):
            if part.due(t):
                part.plan(state)
            part.arrive(t)
            motion = part.motion
        elif isinstance(part, Reach):
            raise ConfigurationError("reach plans in the background only with its planner toward the peaks")
        else:
            targets = part.targets(state)
            return PlanningResult(t, time.perf_counter() - start, targets=targets, local=self._local(q, t))
        if motion is None or motion is self._sent:
            return None
        self._sent = motion
        return PlanningResult(float(motion.times[0]), time.perf_counter() - start, motion=motion)

    def searches(self, q: Array, t: float) -> PlanningResult:
        """One generation of the searches at the state ``(q, t)``: their best candidates and peaks, and the gradient
        (the searches' worker of a part with both, :func:`split_parts`)."""
        start = time.perf_counter()
        arms = self._split()[0]
        arms.update(self._state(q, t))
        return PlanningResult(t, time.perf_counter() - start, best=arms.best, local=self._local(q, t),
                              peaks=arms.levels(), frames=arms.frames)

    def plans(self, q: Array, t: float, peaks: list[tuple[float, Array, Array]], frames: int) -> PlanningResult | None:
        """The planner toward ``peaks`` (the searches' latest, after ``frames`` generations) at the state ``(q, t)``:
        a new plan when one is due, else ``None`` (the plans' worker of a part with both, :func:`split_parts`)."""
        start = time.perf_counter()
        _, route, settle = self._split()
        route.peaks = peaks
        route.update(self._state(q, t), settled=frames >= settle)
        motion = route.planner.motion
        if motion is None or motion is self._sent:
            return None
        self._sent = motion
        return PlanningResult(float(motion.times[0]), time.perf_counter() - start, motion=motion, goal=route.goal)

    def _split(self) -> tuple[ImaginaryArms, PeakPlanner, int]:
        parts = split_parts(self.part)
        if parts is None:
            raise ConfigurationError(f"{type(self.part).__name__} has no searches and planner to run apart: the call "
                                     "answers for it")
        return parts

    def _state(self, q: Array, t: float) -> ControlState:
        """The state ``(q, t)`` at a camera frame."""
        kin = kinematics(self.robot, q[None], reader=self._reader)
        return ControlState(q, t, kin, self.path, self.frame, frame_due=True, data=self._data)

    def _local(self, q: Array, t: float) -> tuple[float, Array] | None:
        """``(t, ∇_q S(q, t))`` of the law's gradient term, or ``None`` without one."""
        return None if self.local is None else (t, self.local.gradient(q, t))


def split_parts(part: object) -> tuple[ImaginaryArms, PeakPlanner, int] | None:
    """``(imaginary arms, planner toward their peaks, settle frames)`` of a part that has both (``route`` points, a
    ``reach`` law with its planner toward the peaks), else ``None``."""
    if isinstance(part, RoutePoints):
        return part.arms, part.planner, part.settle_frames
    if isinstance(part, Reach) and isinstance(part.route, PeakPlanner):
        return part.arms, part.route, part.params.settle_frames
    return None


class ObservedSide:
    """The worker's side with observed obstacles: a :class:`PlanningSide` on the base scene and the loop's observed
    obstacles, rebuilt when their set (or a shape) changes, their tracks holding the loop's states.

    Args:
        build: ``build(scene)``, the planning side on a scene.
        scene: the obstacles that stay known (static, or not observed).
    """

    def __init__(self, build: Callable[[Scene], PlanningSide], scene: Scene) -> None:
        self.build, self.base = build, scene.obstacles
        self._key: tuple[tuple[str, object, bool], ...] = ()
        self._tracks: dict[str, Track] = {}
        self.side = build(scene)

    def sync(self, observed: tuple[Obstacle, ...]) -> None:
        """Take the loop's observed obstacles: their tracks' states, and a rebuild if the set changed."""
        key = tuple((o.name, o.shape, o.work_surface) for o in observed)
        if key != self._key:
            self._key = key
            self._tracks = {o.name: o.motion for o in observed if isinstance(o.motion, Track)}
            self.side = self.build(Scene(self.base + observed))
            return
        for o in observed:
            if isinstance(o.motion, Track):
                self._tracks[o.name].take(o.motion)

    def __call__(self, q: Array, t: float) -> PlanningResult | None:
        """The planning side's result for the state ``(q, t)``."""
        return self.side(q, t)


def answer(side: PlanningSide | Searches | Plans, q: Array, t: float) -> PlanningResult | None:
    """The worker's default computation: ``side(q, t)``."""
    return side(q, t)


class _SplitSide:
    """A worker's side of a part with searches and a planner (:func:`split_parts`): the planning side it runs.

    Args:
        build: ``build()``, the planning side (a :class:`PlanningSide` or an :class:`ObservedSide`).
    """

    def __init__(self, build: Callable[[], PlanningSide | ObservedSide]) -> None:
        self.side = build()

    @property
    def inner(self) -> PlanningSide:
        """The planning side, on the observed obstacles' latest scene if there are any."""
        return self.side.side if isinstance(self.side, ObservedSide) else self.side

    def _observe(self, observed: tuple[Obstacle, ...]) -> None:
        """Take the loop's observed obstacles (:meth:`ObservedSide.sync`)."""
        if isinstance(self.side, ObservedSide):
            self.side.sync(observed)


class Searches(_SplitSide):
    """The searches' worker's side: one generation per state (:meth:`PlanningSide.searches`)."""

    def sync(self, observed: tuple[Obstacle, ...]) -> None:
        """Take the loop's observed obstacles."""
        self._observe(observed)

    def __call__(self, q: Array, t: float) -> PlanningResult | None:
        """One generation at the state ``(q, t)``."""
        return self.inner.searches(q, t)


class Together(_SplitSide):
    """The one worker's side when the plans do not run apart (``plans_apart = False``): at each state one generation,
    then the planner toward its peaks."""

    def __init__(self, build: Callable[[], PlanningSide | ObservedSide]) -> None:
        super().__init__(build)
        self._plan: PlanningResult | None = None  # the last plan made

    def sync(self, observed: tuple[Obstacle, ...]) -> None:
        """Take the loop's observed obstacles."""
        self._observe(observed)

    def __call__(self, q: Array, t: float) -> PlanningResult | None:
        """The searches' answer at the state ``(q, t)``, dated by the plan in use (with it if new); ``None`` before
        the first plan."""
        side = self.inner
        searched = side.searches(q, t)
        plan = side.plans(q, t, searched.peaks or [], searched.frames)
        self._plan = plan or self._plan
        if self._plan is None:
            return None
        return replace(searched, made=self._plan.made, compute=searched.compute + (plan.compute if plan else 0.0),
                       motion=None if plan is None else plan.motion, goal=self._plan.goal, peaks=None)


@dataclass(frozen=True)
class PlanNews:
    """What the loop hands the plans' worker with each state: the searches' latest peaks and the observed obstacles.

    Attributes:
        peaks: the searches' positive peaks, ``(t_i [s], nodes (K, nq), S (K,))`` per preview time (none yet: empty).
        frames: the generations the searches had run then.
        observed: the loop's observed obstacles, or ``None`` (no observed world).
    """

    peaks: list[tuple[float, Array, Array]]
    frames: int
    observed: tuple[Obstacle, ...] | None


class Plans(_SplitSide):
    """The plans' worker's side: the planner toward the searches' latest peaks, which the loop relays
    (:meth:`PlanningSide.plans`)."""

    def __init__(self, build: Callable[[], PlanningSide | ObservedSide]) -> None:
        super().__init__(build)
        self.news = PlanNews([], 0, None)

    def sync(self, news: PlanNews) -> None:
        """Take the searches' latest peaks, and the loop's observed obstacles."""
        self.news = news
        if news.observed is not None:
            self._observe(news.observed)

    def __call__(self, q: Array, t: float) -> PlanningResult | None:
        """The planner's new plan at the state ``(q, t)``, or ``None``."""
        return self.inner.plans(q, t, self.news.peaks, self.news.frames)


class Follower(WindowPlanner):
    """A window planner that makes no plans: it follows those the worker delivers
    (:meth:`~previewctl.control.planner.WindowPlanner.follow`)."""

    def due(self, t: float) -> bool:
        """Never: the worker plans."""
        return False


class RemoteArms(ImaginaryArms):
    """``reach``'s imaginary arms in the loop: they run no generation (the worker does); their best candidates and
    frames are the worker's."""

    def update(self, state: ControlState) -> bool:
        """Never runs a generation here: ``False``."""
        return False

    def best_from(self, best: tuple[Array, Array]) -> None:
        """Hold the worker's best candidates ``((p, nq), (p,))``."""
        self._best = best


class RemotePeaks(PeakPlanner):
    """``reach``'s planner toward the peaks in the loop: it follows the worker's plans and goals."""

    def update(self, state: ControlState, *, settled: bool) -> None:
        """Nothing to plan here: the worker does (its goal arrives with its results)."""


class BackgroundPlanning:
    """The loop's side: it stands in for the slow parts when :func:`~previewctl.control.factory.compose` builds the
    law (:meth:`arms`, :meth:`planner`), then exchanges states and results with the worker once per cycle.

    Args:
        options: validity and worker settings.
        frame: camera frame period [s].
    """

    name = "background"

    def __init__(self, options: BackgroundOptions, frame: float) -> None:
        self.options, self.frame = options, frame
        self.result: PlanningResult | None = None
        self.searched: PlanningResult | None = None  # the searches' latest answer, when the plans are apart
        self.follower: Follower | None = None
        self.worker: PlanningWorker | None = None
        self.plans: PlanningWorker | None = None  # the plans' worker of a part with searches and a planner
        self._split = False  # whether the part has both (arms(), reach()): start() starts the plans' worker
        self._valid = options.arms_valid_frames * frame  # [s]; for plans, set by _follower_of()
        self._posting = self._posting_plans = False
        # the answer to the state in flight was computed on an old set of obstacles (searches', plans' worker)
        self._stale = self._stale_plans = False
        self._arms: RemoteArms | None = None  # reach's stand-ins (reach())
        self._peaks: RemotePeaks | None = None

    def arms(self, policy: ArmPolicy) -> ArmPolicy:
        """The loop's stand-in for ``policy``, whose searches (and planner) run in the worker."""
        if isinstance(policy, RoutePoints):
            self.follower = self._follower_of(policy.planner.planner)
            self._split = True
        return BackgroundArms(policy.name, policy.arms, self)

    def reach(self, arms: ImaginaryArms, route: PeakPlanner) -> tuple[RemoteArms, RemotePeaks]:
        """The loop's stand-ins for ``reach``'s imaginary arms and planner toward their peaks."""
        self.follower = self._follower_of(route.planner)
        self._split = True
        self._arms = RemoteArms(arms.robot, arms.searches, arms.preview_time)
        self._peaks = RemotePeaks(route.robot, self.follower, hysteresis=route.hysteresis,
                                  track_radius=route.track_radius)
        return self._arms, self._peaks

    def planner(self, planner: WindowPlanner) -> Follower:
        """The loop's stand-in for ``planner``: it follows the worker's plans."""
        self.follower = self._follower_of(planner)
        return self.follower

    def gradient(self, local: AmsipGradient) -> BackgroundGradient:
        """The loop's stand-in for the law's gradient term ``local``, whose ``∇_q S`` the worker computes."""
        return BackgroundGradient(local.gain, self)

    @property
    def latest_searches(self) -> PlanningResult | None:
        """The searches' latest answer: :attr:`searched` for a part with searches and a planner, else the latest
        result (the searches answer every state)."""
        return self.result if self.searched is None else self.searched

    def local_gradient(self, t: float) -> Array | None:
        """The worker's latest ``∇_q S`` [1/rad] if it is at most ``arms_valid_frames`` frames old at ``t`` [s], else
        ``None``."""
        source = self.latest_searches
        local = None if source is None else source.local
        if local is None or t - local[0] > self.options.arms_valid_frames * self.frame + 1e-9:
            return None
        return local[1]

    def _follower_of(self, planner: WindowPlanner) -> Follower:
        timing = planner.timing
        self._valid = (math.inf if timing.window is None
                       else self.options.plan_valid_periods * timing.replan_period)
        return Follower(planner.robot, planner.evaluator, timing)

    def rescene(self) -> None:
        """The set of observed obstacles changed: no result is in use, the answer to a state sent before is dropped,
        and the next cycle posts its state (with the new set) at once."""
        self.result = self.searched = None
        self._posting = self._posting_plans = True
        self._stale = self.worker is not None and self.worker.busy
        self._stale_plans = self.plans is not None and self.plans.busy

    def start(self, build: Callable[[], PlanningSide | ObservedSide], compute: Compute = answer) -> None:
        """Start the worker, which runs ``compute(build(), q, t)`` for each state posted; for a part with searches
        and a planner, ``compute(Searches(build), q, t)``, and a second worker that makes the plans
        (:class:`Plans`)."""
        options = self.options
        side: Callable[[], object] = build
        niceness, cores = options.niceness, worker_cores() if options.loop_core else None
        if self._split and options.plans_apart:
            self.plans = PlanningWorker(partial(Plans, build), answer, timeout=options.timeout, niceness=niceness,
                                        cores=cores)
            side, niceness = partial(Searches, build), min(19, niceness + options.search_niceness)
        elif self._split:
            side = partial(Together, build)
        self.worker = PlanningWorker(side, compute, timeout=options.timeout, niceness=niceness, cores=cores)

    def exchange(self, state: ControlState, observed: tuple[Obstacle, ...] | None = None) -> PlanningStatus:
        """Post the state at a new frame (with the observed obstacles, if any), take the worker's answer if one came,
        and say whether it is valid."""
        worker, plans = self.worker, self.plans
        if worker is None:
            raise ConfigurationError("the planning worker was not started: start() starts it")
        self._posting = self._posting or state.frame_due
        if self._posting:
            worker.post(state.q, state.t, observed)
        for result in worker.exchange():
            if self._stale:
                self._stale = False
            elif result is not None and plans is not None:
                self._searched(result)
            elif result is not None:
                self._take(result, state)
        self._posting = self._posting and worker.waiting
        error = worker.error
        if plans is not None:
            error = error or self._exchange_plans(plans, state, observed)
        age = None if self.result is None else state.t - self.result.made
        unsearched = self._arms is not None and self.searched is None  # reach's arms have no candidates yet
        fallback = error is not None or age is None or age > self._valid + 1e-9 or unsearched
        return PlanningStatus(age, fallback, error)

    def _exchange_plans(self, plans: PlanningWorker, state: ControlState,
                        observed: tuple[Obstacle, ...] | None) -> PlanningWorkerError | None:
        """Post the state at a new frame to the plans' worker, with the searches' latest peaks, and take its new plan
        if one came; its error, if any."""
        self._posting_plans = self._posting_plans or state.frame_due
        if self._posting_plans:
            searched = self.searched
            news = (PlanNews([], 0, observed) if searched is None or searched.peaks is None
                    else PlanNews(searched.peaks, searched.frames, observed))
            plans.post(state.q, state.t, news)
        for result in plans.exchange():
            if self._stale_plans:
                self._stale_plans = False
            elif result is not None:
                self._take(result, state)
        self._posting_plans = self._posting_plans and plans.waiting
        return plans.error

    def _searched(self, result: PlanningResult) -> None:
        """Hold the searches' answer (the plans apart): their peaks go to the plans' worker, their best candidates to
        ``reach``'s stand-ins."""
        self.searched = result
        if self._arms is not None and result.best is not None:
            self._arms.best_from(result.best)

    def _take(self, result: PlanningResult, state: ControlState) -> None:
        """Hold ``result``; a plan is followed from now on, joined to the arm's configuration."""
        if result.motion is not None and self.follower is not None:
            self.follower.follow(result.motion, state.t, state.q)
        if self._peaks is not None and result.motion is not None:
            self._peaks.goal = result.goal
        if result.best is not None:  # the searches' answer too (plans not apart: Together)
            self._searched(result)
        self.result = result

    def targets(self, t: float, arms: ImaginaryArms) -> Targets:
        """The imaginary arms' targets at ``t`` [s]: the worker's, or the followed plan's points at the preview
        times."""
        result = self.result
        if result is None:
            raise ConfigurationError("no result from the planning worker yet: exchange() brings it")
        if result.targets is not None:
            return result.targets
        if self.follower is None:
            raise ConfigurationError("a plan came from the planning worker, but nothing follows plans here")
        return plan_points(self.follower, t, arms.preview_time, len(arms))

    def rehearse(self) -> None:
        """Run the code of the workers' exchanges without their messages (:meth:`PlanningWorker.rehearse`)."""
        for worker in (self.worker, self.plans):
            if worker is not None:
                worker.rehearse()

    def close(self) -> None:
        """Stop the workers; no child process is left."""
        for worker in (self.worker, self.plans):
            if worker is not None:
                worker.close()


class BackgroundArms:
    """An imaginary-arm policy whose searches run in the worker: the targets of :meth:`BackgroundPlanning.targets`.

    Args:
        name: the policy's name (``argmax``, ``peaks`` or ``route``).
        arms: the imaginary arms (their number and preview time).
        planning: the loop's side of the planning.
    """

    def __init__(self, name: str, arms: ImaginaryArms, planning: BackgroundPlanning) -> None:
        self.name, self.arms, self.planning = name, arms, planning

    def targets(self, state: ControlState) -> Targets:
        """The latest targets the worker's results give at the state's time."""
        return self.planning.targets(state.t, self.arms)


class BackgroundGradient:
    """The loop's AMSIP gradient term with planning in the background: ``v = K_g ∇_q S(q0, t0)``, the worker's
    gradient at the state posted last, while valid (module docstring); zero without one.

    Args:
        gain: ``K_g`` ``(nv,)`` [rad²/s per unit of S].
        planning: the loop's side of the planning.
    """

    def __init__(self, gain: Array, planning: BackgroundPlanning) -> None:
        self.gain, self.planning = gain, planning

    def __call__(self, q: Array, t: float) -> Array:
        """``K_g ∇_q S`` ``(nv,)`` [rad/s] from the worker's latest valid gradient (``q`` is not read), else zeros."""
        gradient = self.planning.local_gradient(t)
        return np.zeros_like(self.gain) if gradient is None else np.asarray(self.gain * gradient)
