"""The controller you step from your own loop: ``qdot = ctrl.step(q, t)``.

Like pink's ``solve_ik`` and mink's ``Configuration``, previewctl leaves the loop to you: you read
``q`` from your robot (or integrate it yourself), ask for a joint velocity, and apply it for as long
as you like::

    ctrl = previewctl.make_controller(scenario)      # or make_controller("multi", robot=..., path=...)
    q, dt = scenario.q0, 0.004                       # any rate: 250 Hz here
    for k in range(2500):
        t = k * dt
        qdot = ctrl.step(q, t)                       # [rad/s]
        q = previewctl.integrate(robot, q, qdot, dt)
        print(ctrl.last_info.hand_error)             # what the cycle computed (ControlInfo)

Per call, :meth:`Controller.step` validates ``q``, computes its kinematics once, decides from ``t``
whether a camera frame is due, and runs the parts (:mod:`previewctl.control.base`): the law's null-space input,
eq. 19's reference for it (:func:`~previewctl.control.tracking.reference`) and the execution
(:mod:`previewctl.control.execution`: the constrained QP, the default, or eq. 19 with clamping and saturation,
the paper's). ``ctrl.describe()`` says which parts were chosen.

Camera frames: the GA searches of the preview modes run one generation per frame of period
``frame`` (33 ms by default), whatever the rate of your loop. A frame is due at the first call and
whenever ``floor(t / frame)`` differs from its value at the previous call; between frames the
imaginary arms' last optima are kept. A loop slower than the frame rate thus runs one generation
per call, never a backlog.

Planning beside the loop (``make_controller(..., planning="background")``,
:mod:`previewctl.control.background`): the searches and the planner run in a worker process, :meth:`Controller.step`
posts its state and uses the latest valid result without waiting, and runs the ``qp`` law when there is none.
Close such a controller when done (``ctrl.close()``, or ``with make_controller(...) as ctrl:``) to end its worker.

Observed obstacles (``make_controller(..., sensing=Sensing(...))``, :mod:`previewctl.sensing`): hand the controller
observations with :meth:`Controller.observe` (and :meth:`~Controller.forget`, :meth:`~Controller.forget_all`); it
predicts those obstacles from them and never reads their true motion. At each step the obstacles not observed for
longer than the timeout are dropped; when the set of obstacles changes (or a shape), the law and the execution are
rebuilt on the new scene (:class:`Observed`), which resets what they hold: the GA populations and tracked peaks of the
imaginary arms, the planner's plan, and, with background planning, the result in use (the step runs the ``qp`` law
until the worker, rebuilt on the same scene, answers).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from types import TracebackType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from previewctl.control.base import Composition, ControlInfo, ControlLaw, ControlState, Execution, NullInput, Planning
from previewctl.control.params import ControllerParams
from previewctl.control.tracking import Tracking
from previewctl.errors import ConfigurationError, ObservationError, ParameterError, PreviewctlError
from previewctl.kinematics import kinematics, kinematics_reader
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.scene.shapes import Scene, Shape
from previewctl.sensing.world import World
from previewctl.types import Array
from previewctl.validation import real_scalar

FRAME_PERIOD = 0.033
"""Default camera frame period [s]: one GA generation per frame (the paper's 30 Hz camera)."""
CONTROL_PERIOD = 0.01
"""Default control period [s]: the ``dt`` of the first call (see :meth:`Controller.step`)."""


def frame_index(t: float, frame: float) -> int:
    """Camera frame number of time ``t`` [s] for frame period ``frame`` [s] (robust to rounding)."""
    return math.floor(t / frame + 1e-9)


def positive_period(value: object, name: str) -> float:
    """``value`` as a finite time > 0 [s]; :class:`ParameterError` naming ``name`` otherwise."""
    period = real_scalar(value, name, ParameterError)
    if period <= 0.0:
        raise ParameterError(f"{name} must be a time > 0 [s], got {period!r}")
    return period


Rebuild = Callable[[Scene], tuple[ControlLaw, Execution]]
"""``rebuild(scene)``: the law and the execution, composed as the factory composed them, on another scene."""


@dataclass(frozen=True)
class Observed:
    """A controller's observed obstacles: the world and how the parts are rebuilt when its set of obstacles changes.

    Attributes:
        world: the observed obstacles (:class:`~previewctl.sensing.world.World`).
        rebuild: the factory's rebuild of the law and the execution on a scene.
    """

    world: World
    rebuild: Rebuild


class Controller:
    """A control law, its execution, and the per-call bookkeeping: kinematics, camera frames, the last cycle.

    Build it with :func:`previewctl.make_controller`.

    Args:
        law: the controller's law (:mod:`previewctl.control.laws`).
        execution: what turns eq. 19's reference into the joint velocity applied.
        robot: the arm the law was built for.
        path: the desired hand path ``r_d(t)``.
        params: eq. 19's gains and limits (the law's settings too).
        composition: what the factory chose (:meth:`describe`).
        frame: camera frame period [s].
        dt: control period [s] assumed at the first call (later calls use the time elapsed).
        planning: the searches and the planner beside the loop, or ``None`` (inline, inside the law).
        observed: the observed obstacles, or ``None`` (every obstacle's motion is known).

    Raises:
        ParameterError: ``frame`` or ``dt`` not a time > 0.
    """

    def __init__(
        self,
        law: ControlLaw,
        execution: Execution,
        robot: Robot,
        path: HandPath,
        params: ControllerParams,
        composition: Composition,
        *,
        frame: float = FRAME_PERIOD,
        dt: float = CONTROL_PERIOD,
        planning: Planning | None = None,
        observed: Observed | None = None,
    ) -> None:
        self.law, self.execution, self.robot, self.path, self.params = law, execution, robot, path, params
        self._composition = composition
        self.frame = positive_period(frame, "frame")
        self.dt = positive_period(dt, "dt")
        self._reader = kinematics_reader(robot)  # built once: each step only reads through it
        self._tracking = Tracking(robot, params)
        self._scratch = robot.model.createData()  # predictions (eq. 19's step correction)
        self._last_frame: int | None = None
        self._last_t: float | None = None
        self._last_info: ControlInfo | None = None
        self._last_cycle: tuple[ControlState, NullInput] | None = None  # what rehearse() computes again
        self.planning = planning
        self.observed = observed

    @property
    def name(self) -> str:
        """The controller name: one of :data:`~previewctl.control.params.CONTROLLER_NAMES`."""
        return self.law.name

    def describe(self) -> Composition:
        """Which law, imaginary-arm policy, planner and execution run, and which settings are ignored."""
        return self._composition

    @property
    def last_info(self) -> ControlInfo:
        """What the last :meth:`step` computed: targets, errors, limits, imaginary arms.

        Raises:
            PreviewctlError: no step yet.
        """
        if self._last_info is None:
            raise PreviewctlError("no control cycle yet: call step(q, t) first")
        return self._last_info

    def observe(self, name: str, position: ArrayLike, t: float, *, rotation: ArrayLike | None = None,
                velocity: ArrayLike | None = None, shape: Shape | None = None) -> None:
        """Take an observation of obstacle ``name``; it counts from the next :meth:`step`.

        Args:
            name: the obstacle; a name not observed yet adds it (``shape`` needed unless the scenario knows it).
            position: where it was ``(3,)`` [m] (2 entries: planar, ``z = 0``).
            t: when it was observed [s], on the path's clock (not when the observation was delivered). One older than
                the obstacle's last is ignored and counted (``last_info.late_observations``).
            rotation: its rotation matrix ``(3, 3)`` (default: the last one observed, the identity at first).
            velocity: its measured velocity ``(3,)`` [m/s] (2 entries: planar), if any.
            shape: its shape (:class:`~previewctl.scene.shapes.Sphere`, ``Box``, ``Cylinder``, ...).

        Raises:
            ObservationError: a bad value, named: not finite, a wrong shape, an unknown shape type, a new name without
                a shape, a static obstacle of the scene, or ``t`` before the obstacle's last observation by more than
                the timeout; or a controller made without ``sensing``.
        """
        self._world().observe(name, position, t, rotation=rotation, velocity=velocity, shape=shape)

    def forget(self, name: str) -> None:
        """Drop observed obstacle ``name`` now (e.g. a ROS marker's DELETE).

        Raises:
            UnknownNameError: ``name`` is not observed (the message lists those that are).
            ObservationError: a controller made without ``sensing``.
        """
        self._world().forget(name)

    def forget_all(self) -> None:
        """Drop every observed obstacle now (e.g. a ROS marker's DELETEALL).

        Raises:
            ObservationError: a controller made without ``sensing``.
        """
        self._world().forget_all()

    def _world(self) -> World:
        if self.observed is None:
            raise ObservationError(f"controller {self.name!r} observes nothing: make it with "
                                   "make_controller(..., sensing=previewctl.Sensing()) or a scenario's [sensing] table")
        return self.observed.world

    def frame_due(self, t: float) -> bool:
        """Whether a :meth:`step` at time ``t`` [s] would start a camera frame (nothing changes)."""
        return frame_index(t, self.frame) != self._last_frame

    def step(self, q: Array, t: float, dt: float | None = None) -> Array:
        """Joint velocity for configuration ``q`` at time ``t``: eq. 19 with the mode's null-space input.

        Args:
            q: the arm's configuration ``(nq,)`` [rad] (not modified).
            t: time [s] on the path's clock; the camera frames follow it (see the module docstring).
            dt: how long you will apply the result [s]; the position limits keep ``q + q̇ dt`` inside
                them. Default: the time elapsed since the previous call, or the constructor's ``dt``
                at the first call (and when ``t`` did not advance).

        Returns:
            ``q̇`` [rad/s], shape ``(nv,)``, within the joint speed and position limits.
            :attr:`last_info` holds the rest of the cycle (:class:`~previewctl.control.base.ControlInfo`).

        Raises:
            ConfigurationError: ``q`` of the wrong length, a batch, or not finite.
            ParameterError: ``t`` not a finite number or ``dt`` not a time > 0.
        """
        Q, single = self.robot.check_configurations(q)
        if not single:
            raise ConfigurationError(f"step takes one configuration ({self.robot.nq},), got a batch of shape {Q.shape}")
        now = real_scalar(t, "t", ParameterError)
        period = self._period(now, dt)
        frame = frame_index(now, self.frame)
        changes = None
        observed = self.observed
        if observed is not None:
            changes = observed.world.advance(now)
            if changes.changed:
                self.law, self.execution = observed.rebuild(observed.world.scene)
        kin = kinematics(self.robot, Q, reader=self._reader)
        state = ControlState(Q[0], now, kin, self.path, period, frame_due=frame != self._last_frame,
                             data=self._scratch, joint_data=self._reader.data)
        if self.planning is None:
            null = self.law.null_input(state)
            status = None
        else:  # never waits; without a valid result the qp law
            status = self.planning.exchange(state, None if observed is None else observed.world.observed_obstacles())
            null = NullInput(np.zeros(self.robot.nv)) if status.fallback else self.law.null_input(state)
        ref = self._tracking(state, null.v)
        executed = self.execution(state, ref)
        extra: dict[str, Any] = {}  # one ControlInfo: a dataclass replace() costs as much as the law
        if status is not None:
            extra.update(plan_age=status.plan_age, fallback=status.fallback, worker_error=status.worker_error)
        if changes is not None:
            extra.update(obstacles_added=changes.added, obstacles_dropped=changes.dropped,
                         late_observations=changes.late)
        self._last_info = ControlInfo(ref, executed, state.frame_due, null.targets, null.target_amsip, **extra)
        self._last_frame, self._last_t = frame, now
        self._last_cycle = (state, null)
        return executed.qdot

    def rehearse(self) -> None:
        """Compute the last :meth:`step` again and discard it, changing nothing: its kinematics, eq. 19's reference
        and the execution, and, if that step used the background worker's result, also the law (which then only reads
        that result); no state is posted, no observation read, no search run. Nothing before the first step.

        For a real-time loop that waits for its deadline: called shortly before it, it brings the step's code and data
        back into the core's caches, which a shared host's other work evicts during the wait (on the 2-core host of
        this project's measurements a paced planar step cost 2-2.5x an unpaced one: the Speed page). The next
        :meth:`step` returns the same bits with or without it. With background planning it also runs the code of the
        worker's messages without sending or taking any (the pickling of the last state posted, the unpickling of the
        last answer, a poll of the pipe).
        """
        if self._last_cycle is None:
            return
        if self.planning is not None:
            self.planning.rehearse()
        last, null = self._last_cycle
        state = replace(last, kin=kinematics(self.robot, last.kin.q, reader=self._reader), frame_due=False)
        if self.planning is not None and not self.last_info.fallback:  # the law only reads the worker's result
            null = self.law.null_input(state)
        self.execution(state, self._tracking(state, null.v))

    def close(self) -> None:
        """End the planning worker, if any (no child process is left); idempotent. Stepping after it falls back."""
        if self.planning is not None:
            self.planning.close()

    def __enter__(self) -> Controller:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 trace: TracebackType | None) -> None:
        self.close()

    def _period(self, t: float, dt: float | None) -> float:
        if dt is not None:
            return positive_period(dt, "dt")
        if self._last_t is not None and t > self._last_t:
            return t - self._last_t
        return self.dt

    def __repr__(self) -> str:
        return (f"Controller({self.name!r}, robot={self.robot.name!r}, frame={self.frame}, dt={self.dt}, "
                f"execution={self.execution.name!r})")
