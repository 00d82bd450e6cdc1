"""The control-law interface: the state a law reads, the command it returns, and what it reports.

A *control law* (one per mode: :class:`~previewctl.control.tracking.TrackingController`,
:class:`~previewctl.control.gradient.GradientController`,
:class:`~previewctl.control.preview.PreviewController`, :class:`~previewctl.control.reach.ReachController`)
turns a :class:`ControlState` into a joint velocity. It does no bookkeeping of its own: the
:class:`~previewctl.control.controller.Controller` that wraps it computes the kinematics once per
configuration and decides when a camera frame is due. Use the ``Controller`` (``ctrl.step(q, t)``);
call a law's ``command`` directly only to test it with a hand-made state.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
import pinocchio as pin

from previewctl.control.params import ControllerParams
from previewctl.kinematics import Kinematics
from previewctl.path import HandPath
from previewctl.types import Array


@dataclass(frozen=True)
class ControlState:
    """What a control law sees at one control cycle.

    Attributes:
        kin: kinematics of the current configuration (batch of one).
        path: the desired hand path.
        dt: how long the command will be applied [s] (the position limits keep ``q + q̇ dt`` inside).
        frame_due: whether a camera frame arrives at this cycle (GA-based laws run a generation).
        data: a Pinocchio ``Data`` of the arm the law may use for predictions (``None``: one is made when needed).
    """

    kin: Kinematics
    path: HandPath
    dt: float
    frame_due: bool
    data: pin.Data | None = None


@dataclass(frozen=True)
class ControlInfo:
    """What a controller computed at one cycle.

    Attributes:
        desired_position: ``r_d(t)`` [m], shape ``(3,)`` (z = 0 for planar paths).
        desired_velocity: ``ṙ_d(t)`` [m/s], shape ``(3,)``.
        hand_position: the hand ``r`` at the configuration given [m], shape ``(3,)``.
        task_error: the task error fed back (``(m,)``: [m], and [rad] for the pose rows).
        v: the null-space input, shape ``(nv,)``, joint-limit avoidance included.
        qdot_task: ``J#(ṙ_d + K_p e)`` [rad/s], shape ``(nv,)``.
        qdot_null: ``N v`` [rad/s], shape ``(nv,)``; ``J qdot_null = 0``.
        qdot_requested: ``qdot_task + null_scale · qdot_null``, before the limits [rad/s].
        null_scale: the factor in [0, 1] on the null-space term (task priority, see
            :mod:`previewctl.control.tracking`).
        scale: the task scaling ``s`` in [0, 1] of the joint-limit saturation (1 = the whole task velocity).
        clamped: whether a joint was saturated at a position or speed bound.
        damping: the damping ``λ`` used [m/rad].
        dt: the period the position limits were computed for [s].
        frame_due: whether this cycle started a camera frame (the searches ran one generation).
        targets: the imaginary arms ``q̃_i``, ``(p, nq)`` (preview modes), else ``None``.
        target_amsip: their AMSIP values ``(p,)`` (preview modes), else ``None``.
        execution: ``pseudoinverse`` (eq. 19 with clamping and scaling) or ``qp``
            (:mod:`previewctl.control.execution`); with ``qp``, ``scale`` is 1 and ``null_scale`` 1.
        dampers: collision damper rows of the QP (pairs within the influence distance).
        active_dampers: how many of them bind at the solution.
        slack: the largest damper slack [m/s] (0: every damper held; > 0: the constraints were infeasible).
    """

    desired_position: Array
    desired_velocity: Array
    hand_position: Array
    task_error: Array
    v: Array
    qdot_task: Array
    qdot_null: Array
    qdot_requested: Array
    null_scale: float
    scale: float
    clamped: bool
    damping: float
    dt: float
    frame_due: bool
    targets: Array | None = None
    target_amsip: Array | None = None
    execution: str = "pseudoinverse"
    dampers: int = 0
    active_dampers: int = 0
    slack: float = 0.0

    @property
    def hand_error(self) -> float:
        """``|r_d − r|`` [m] over the task's position rows (the orientation error of a pose task is not in it)."""
        return float(np.linalg.norm(self.task_error[:3]))


@runtime_checkable
class ControlLaw(Protocol):
    """One controller mode: a joint velocity from a :class:`ControlState`."""

    name: str
    params: ControllerParams

    def command(self, t: float, q: Array, state: ControlState) -> tuple[Array, ControlInfo]:
        """Joint velocity ``q̇`` [rad/s] ``(nv,)`` for time ``t`` [s] and configuration ``q`` ``(nq,)``."""
        ...
