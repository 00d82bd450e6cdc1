"""What flows through one control cycle: the state, a law's null-space input, eq. 19's reference, the execution.

One cycle of :class:`~previewctl.control.controller.Controller` is a pipeline of parts::

    ControlState --law--> NullInput --tracking.reference--> Reference --execution--> Executed
                                                                     \\---------------> ControlInfo (all of it)

* a *control law* (:mod:`previewctl.control.laws`, one class per controller name) turns the state into the
  null-space input ``v`` of eq. 19 and the imaginary arms it steered toward (:class:`NullInput`);
* the tracking reference (:func:`previewctl.control.tracking.reference`) is eq. 19 for that ``v``: the task term
  ``J#(ṙ_d + K_p e)``, the projected ``N v`` and the task-priority budget (:class:`Reference`);
* an *execution* (:mod:`previewctl.control.execution`: the pseudo-inverse with clamping and saturation, or the
  constrained QP) turns the reference into the joint velocity that is applied (:class:`Executed`).

A law never holds another law and never executes its command; the controller composes the parts.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
import pinocchio as pin

from previewctl.errors import PlanningWorkerError
from previewctl.kinematics import Kinematics
from previewctl.path import HandPath
from previewctl.scene.shapes import Obstacle
from previewctl.types import Array


@dataclass(frozen=True)
class ControlState:
    """What the parts of a control cycle see.

    Attributes:
        q: the arm's configuration ``(nq,)``.
        t: time [s] on the path's clock.
        kin: kinematics of ``q`` (batch of one), computed once per cycle.
        path: the desired hand path.
        dt: how long the command will be applied [s] (the position limits keep ``q + q̇ dt`` inside).
        frame_due: whether a camera frame arrives at this cycle (GA-based laws run a generation).
        data: a Pinocchio ``Data`` of the arm for predictions (``None``: one is made when needed).
        joint_data: the Pinocchio ``Data`` that ``kin`` was computed in: its joint placements and world joint
            Jacobians are those at ``q`` (``computeJointJacobians``), for the parts to read instead of computing them
            again (``None``: not at hand).
    """

    q: Array
    t: float
    kin: Kinematics
    path: HandPath
    dt: float
    frame_due: bool
    data: pin.Data | None = None
    joint_data: pin.Data | None = None


@dataclass(frozen=True)
class NullInput:
    """A control law's output: the null-space input of eq. 19 and what it steered toward.

    Attributes:
        v: the null-space input [rad/s], ``(nv,)`` (before the joint-limit avoidance is added).
        targets: the imaginary arms ``q̃_i``, ``(p, nq)`` (laws that steer toward configurations), else ``None``.
        target_amsip: their AMSIP values ``(p,)``, else ``None``.
    """

    v: Array
    targets: Array | None = None
    target_amsip: Array | None = None


@dataclass(frozen=True)
class Reference:
    """Eq. 19 for a null-space input: ``q̇ = J#(ṙ_d + K_p e) + N v`` and its parts.

    Attributes:
        desired_position: ``r_d(t)`` [m], ``(3,)`` (z = 0 for planar paths).
        desired_velocity: ``ṙ_d(t)`` [m/s], ``(3,)``.
        hand_position: the hand ``r`` at ``q`` [m], ``(3,)``.
        task_error: the task error ``e`` fed back (``(m,)``: [m], and [rad] for the pose rows).
        J: the task Jacobian ``(m, nv)``.
        xdot: the task velocity ``ṙ_d + K_p e`` with eq. 19's step correction [m/s, rad/s], ``(m,)``.
        v: the null-space input with the joint-limit avoidance [rad/s], ``(nv,)``.
        qdot_task: ``J# xdot`` [rad/s], ``(nv,)``.
        qdot_null: ``N v`` [rad/s], ``(nv,)``; ``J qdot_null = 0``.
        budget: the largest ``α`` in [0, 1] with ``qdot_task + α qdot_null`` within the speed limits (task
            priority, :func:`~previewctl.control.tracking.null_space_budget`).
        damping: the damping ``λ`` of ``J#`` [m/rad].
    """

    desired_position: Array
    desired_velocity: Array
    hand_position: Array
    task_error: Array
    J: Array
    xdot: Array
    v: Array
    qdot_task: Array
    qdot_null: Array
    budget: float
    damping: float


@dataclass(frozen=True)
class Executed:
    """What an execution applied.

    Attributes:
        qdot: the joint velocity applied [rad/s], ``(nv,)``, within the joint speed and position limits.
        requested: the command the execution started from, before the limits [rad/s], ``(nv,)``.
        null_scale: the factor in [0, 1] on the null-space term (1 under the QP).
        scale: the task scaling ``s`` in [0, 1] of the saturation (1 = the whole task velocity; 1 under the QP).
        clamped: whether a joint was held at a position or speed bound.
        dt: the period the limits were computed for [s].
        execution: ``pseudoinverse`` or ``qp`` (:mod:`previewctl.control.execution`).
        dampers: collision damper rows of the QP (pairs within the influence distance).
        active_dampers: how many of them bind at the solution.
        slack: the largest damper slack [m/s] (0: every damper held; > 0: the constraints were infeasible).
    """

    qdot: Array
    requested: Array
    null_scale: float
    scale: float
    clamped: bool
    dt: float
    execution: str
    dampers: int = 0
    active_dampers: int = 0
    slack: float = 0.0


@dataclass(frozen=True)
class PlanningStatus:
    """How the planning beside the loop stands at one cycle (:mod:`previewctl.control.background`).

    Attributes:
        plan_age: ``t − t0`` [s] of the result in use, ``t0`` the state time it was computed from; ``None``: no
            result yet.
        fallback: the result is missing or older than it is valid for: the cycle runs the ``qp`` law (``v = 0``).
        worker_error: why the worker gives no result (crashed, failed or not answering), else ``None``.
    """

    plan_age: float | None
    fallback: bool
    worker_error: PlanningWorkerError | None = None


class Planning(Protocol):
    """Planning beside the loop, as the controller drives it: one exchange per cycle, and an end."""

    name: str

    def exchange(self, state: ControlState, observed: tuple[Obstacle, ...] | None = None) -> PlanningStatus:
        """Post ``state`` (and the observed obstacles, whose tracks the worker predicts from) and take the worker's
        latest result, without waiting."""
        ...

    def rehearse(self) -> None:
        """Run the code of an exchange without posting or taking anything (``Controller.rehearse``)."""
        ...

    def close(self) -> None:
        """Stop the worker; no child process is left."""
        ...


@dataclass(frozen=True)
class ControlInfo:
    """What one control cycle computed: the law's input, eq. 19's reference and what was executed.

    Attributes:
        reference: eq. 19 for the law's null-space input.
        executed: what the execution applied.
        frame_due: whether this cycle started a camera frame (the searches ran one generation).
        targets: the imaginary arms ``q̃_i``, ``(p, nq)``, or ``None``.
        target_amsip: their AMSIP values ``(p,)``, or ``None``.
        plan_age: background planning: the age [s] of the result in use (:class:`PlanningStatus`); ``None``
            inline or before the first result.
        fallback: background planning: this cycle ran the ``qp`` law for want of a valid result (always
            ``False`` inline).
        worker_error: background planning: why the worker gives no result, else ``None``.
        obstacles_added: observed obstacles added since the previous step (``Controller.observe``).
        obstacles_dropped: observed obstacles forgotten or timed out since the previous step.
        late_observations: late observations ignored so far (older than their obstacle's last), in total.
    """

    reference: Reference
    executed: Executed
    frame_due: bool
    targets: Array | None = None
    target_amsip: Array | None = None
    plan_age: float | None = None
    fallback: bool = False
    worker_error: PlanningWorkerError | None = None
    obstacles_added: tuple[str, ...] = ()
    obstacles_dropped: tuple[str, ...] = ()
    late_observations: int = 0

    @property
    def hand_error(self) -> float:
        """``|r_d − r|`` [m] over the task's position rows (the orientation error of a pose task is not in it)."""
        return float(np.linalg.norm(self.reference.task_error[:3]))


@dataclass(frozen=True)
class Composition:
    """What a controller is made of, as the factory chose it (:func:`~previewctl.control.factory.compose`).

    Attributes:
        controller: the controller name.
        law: the law's class (:mod:`previewctl.control.laws`).
        execution: ``pseudoinverse`` or ``qp``.
        imaginary_arms: the imaginary-arm policy (``argmax``, ``peaks`` or ``route``), or ``None``.
        planner: ``dp`` (the reachability DP), ``sampled`` (the sampled search), ``sweeps`` (straight sweeps between
            peaks), or ``None``.
        planning: ``inline`` (the searches and the planner run inside ``Controller.step``) or ``background`` (in a
            worker process beside the loop, :mod:`previewctl.control.background`).
        ignored: the settings given that the controller does not read, as ``name = value``.
    """

    controller: str
    law: str
    execution: str
    imaginary_arms: str | None = None
    planner: str | None = None
    ignored: tuple[str, ...] = ()
    planning: str = "inline"

    def __str__(self) -> str:
        parts = [f"{self.controller} ({self.law})", f"execution {self.execution}"]
        if self.imaginary_arms is not None:
            parts.append(f"imaginary arms {self.imaginary_arms}")
        if self.planner is not None:
            parts.append(f"planner {self.planner}")
        if self.planning != "inline":
            parts.append(f"planning {self.planning}")
        if self.ignored:
            parts.append(f"ignored: {'; '.join(self.ignored)}")
        return ", ".join(parts)


@runtime_checkable
class ControlLaw(Protocol):
    """One controller name: the null-space input of eq. 19 from a :class:`ControlState`."""

    name: str

    def null_input(self, state: ControlState) -> NullInput:
        """The null-space input ``v`` [rad/s] ``(nv,)`` for the state, and the imaginary arms it steers toward."""
        ...


@runtime_checkable
class Execution(Protocol):
    """Turns eq. 19's reference into the joint velocity applied (:mod:`previewctl.control.execution`)."""

    name: str

    def __call__(self, state: ControlState, reference: Reference) -> Executed:
        """The joint velocity [rad/s] to apply for ``state`` and ``reference``."""
        ...
