"""The controller interface: the state a controller reads, the command it returns, and what it reports."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from previewctl.kinematics import Kinematics
from previewctl.path import HandPath
from previewctl.scene.shapes import Scene
from previewctl.types import Array


@dataclass(frozen=True)
class ControlState:
    """What a controller sees at one control cycle.

    Attributes:
        kin: kinematics of the current configuration (batch of one).
        path: the desired hand path.
        scene: the obstacles (query their placement at ``t`` or any future time).
        dt: control period [s].
        frame_due: whether a camera frame arrives at this cycle (GA controllers run a generation).
    """

    kin: Kinematics
    path: HandPath
    scene: Scene
    dt: float
    frame_due: bool


@dataclass(frozen=True)
class ControlInfo:
    """What a controller computed at one cycle.

    Attributes:
        desired_position: ``r_d(t)`` [m], shape ``(3,)`` (z = 0 for planar paths).
        desired_velocity: ``ṙ_d(t)`` [m/s], shape ``(3,)``.
        task_error: the task error fed back (``(m,)``: [m], and [rad] for the pose rows).
        v: the null-space input, shape ``(nv,)``.
        qdot_task: ``J#(ṙ_d + K_p e)`` [rad/s], shape ``(nv,)``.
        qdot_null: ``N v`` [rad/s], shape ``(nv,)``; ``J qdot_null = 0``.
        qdot_requested: ``qdot_task + null_scale · qdot_null``, before the limits [rad/s].
        null_scale: the factor ``α`` in [0, 1] on the null-space term (task priority, see the module docstring).
        scale: the uniform velocity-limit scaling ``s`` in (0, 1].
        clamped: whether a position limit clamped some joint velocity.
        damping: the damping ``λ`` used [m/rad].
        targets: the imaginary arms ``q̃_i``, ``(p, nq)`` (preview modes), else ``None``.
        target_amsip: their AMSIP values ``(p,)`` (preview modes), else ``None``.
    """

    desired_position: Array
    desired_velocity: Array
    task_error: Array
    v: Array
    qdot_task: Array
    qdot_null: Array
    qdot_requested: Array
    null_scale: float
    scale: float
    clamped: bool
    damping: float
    targets: Array | None = None
    target_amsip: Array | None = None


@runtime_checkable
class Controller(Protocol):
    """A joint-velocity controller."""

    name: str

    def command(self, t: float, q: Array, state: ControlState) -> tuple[Array, ControlInfo]:
        """Joint velocity ``q̇`` [rad/s] ``(nv,)`` for time ``t`` [s] and configuration ``q`` ``(nq,)``."""
        ...
