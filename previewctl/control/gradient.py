"""The ``gradient`` controller: local null-space ascent of the AMSIP, ``v = K_g grad_q S``."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from previewctl.control.base import ControlInfo, ControlState
from previewctl.control.params import ControllerParams
from previewctl.control.tracking import gain_vector, track
from previewctl.index.evaluator import Evaluator
from previewctl.robot.model import Robot
from previewctl.types import Array


class GradientController:
    """``gradient``: ``v = K_g ∇_q S`` -- local null-space ascent of the AMSIP.

    ``∇S`` is taken in the tangent space by central differences,
    ``∂S/∂q_j ≈ (S(q ⊕ h e_j) − S(q ⊖ h e_j)) / 2h``, all ``2 nv`` configurations evaluated in one batch
    with the scene at time ``t``.
    """

    name = "gradient"

    def __init__(self, robot: Robot, evaluator: Evaluator, params: ControllerParams | None = None) -> None:
        self.robot, self.evaluator = robot, evaluator
        self.params = params or ControllerParams()
        self._gain = gain_vector(self.params.gradient_gain, robot.nv, "gradient_gain")

    def gradient(self, q: Array, t: float) -> Array:
        """``∇_q S`` at ``q`` ``(nq,)`` and time ``t`` [s], shape ``(nv,)`` [1/rad]."""
        h, nv, model = self.params.fd_step, self.robot.nv, self.robot.model
        steps = np.concatenate([np.eye(nv), -np.eye(nv)]) * h
        batch = np.stack([pin.integrate(model, q, d) for d in steps])
        S = self.evaluator(batch, t).S
        return np.asarray((S[:nv] - S[nv:]) / (2.0 * h))

    def null_space_input(self, q: Array, t: float) -> Array:
        """``v = K_g ∇_q S`` ``(nv,)`` [rad/s]."""
        return np.asarray(self._gain * self.gradient(q, t))

    def command(self, t: float, q: Array, state: ControlState) -> tuple[Array, ControlInfo]:
        """Joint velocity [rad/s] for time ``t`` [s]."""
        return track(self.robot, t, q, state, self.null_space_input(q, t), self.params)
