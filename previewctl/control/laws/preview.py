"""``single`` (eq. 20) and ``multi`` (eq. 21): the arm is pulled toward imaginary arms at future times.

``v = K_v Σ_i k_i r_i (q̃_i ⊖ q)`` (:func:`~previewctl.control.nullspace.preview_pull`), with the imaginary arms
``q̃_i`` and the ramps ``r_i`` of a policy (:mod:`previewctl.control.imaginary`): each frame's argmax (the paper's
literal rule), tracked peaks, or the points of a route planned toward the peaks (``multi`` only). With
``with_gradient`` the local ascent ``K_g ∇_q S`` is added: the pull heads for optima that on a spatial arm may lie
radians away, and the local term keeps the current configuration clear of an obstacle meanwhile.
"""

from __future__ import annotations

import numpy as np

from previewctl.control.base import ControlState, NullInput
from previewctl.control.imaginary import ArmPolicy
from previewctl.control.nullspace import LocalTerm, gain_vector, preview_pull
from previewctl.control.params import ControllerParams
from previewctl.errors import ConfigurationError
from previewctl.robot.model import Robot


class _Preview:
    """Eqs. 20/21 on a policy's imaginary arms (module docstring).

    Args:
        robot: the arm.
        params: ``gain`` (``K_v`` [1/s]).
        policy: the imaginary arms and which configuration each stands for.
        weights: the ``k_i``, one per imaginary arm.
        local: the AMSIP gradient term added to the pull (:class:`~previewctl.control.nullspace.AmsipGradient`, or
            its background stand-in), or ``None``.

    Raises:
        ConfigurationError: not one imaginary arm per weight.
    """

    name = "preview"

    def __init__(self, robot: Robot, params: ControllerParams, policy: ArmPolicy, weights: tuple[float, ...],
                 local: LocalTerm | None = None) -> None:
        if len(policy.arms) != len(weights):
            raise ConfigurationError(f"{self.name} needs {len(weights)} imaginary arms (one per weight k_i), "
                                     f"got {len(policy.arms)}")
        self.robot, self.policy, self.local = robot, policy, local
        self.weights = np.array(weights)
        self._gain = gain_vector(params.gain, robot.nv, "gain")

    def null_input(self, state: ControlState) -> NullInput:
        """The pull toward the policy's targets (plus the local term)."""
        targets = self.policy.targets(state)
        v = self._gain * preview_pull(self.robot, state.q, targets.q, self.weights * targets.ramp, keep=targets.keep)
        if self.local is not None:
            v = v + self.local(state.q, state.t)
        return NullInput(v, targets.q.copy(), targets.S.copy())


class SinglePreview(_Preview):
    """``single`` (eq. 20): ``v = K_v r (q̃(t + t̃) ⊖ q)``, one imaginary arm (argmax or tracked peak)."""

    name = "single"


class MultiPreview(_Preview):
    """``multi`` (eq. 21): ``v = K_v Σ k_i r_i (q̃(t + i t̃) ⊖ q)`` (argmax, tracked peaks or route points)."""

    name = "multi"
