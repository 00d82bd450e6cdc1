"""A track: an observed obstacle's motion, as its predictor foresees it (a :class:`~previewctl.scene.motion.Motion`).

Every part of a controller that reads an obstacle's motion (the AMSIP of the imaginary arms at future times, the
planner, the QP dampers' obstacle velocity) reads the track unchanged: ``positions(times)`` is the prediction. The
distance computations also read its :meth:`Track.margin` (it is :class:`~previewctl.scene.motion.Uncertain`): the
obstacle is inflated by

    m(t) = min(cap, k σ(t))        [m]

with ``σ(t)`` the predictor's standard deviation of each coordinate at ``t`` (for the Kalman filter,
``σ(τ)² = P_xx + 2 τ P_xv + τ² P_vv + q τ³ / 3`` at look-ahead ``τ``, :mod:`previewctl.sensing.predictors`), ``k``
the confidence and ``cap`` the largest inflation (:class:`~previewctl.sensing.options.Sensing`). So the imaginary arms
and the planner, which look ahead, keep further from an obstacle the further ahead they look, up to ``cap``, and the
QP, at the present, keeps its clearance from the current estimate inflated by its present uncertainty.

The rotation is the last observed one (no rotation is predicted).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from previewctl.errors import SceneError
from previewctl.sensing.predictors import Predictor
from previewctl.types import Array
from previewctl.validation import check_finite, real_array, real_scalar


class Track:
    """An observed obstacle's motion (module docstring): the prediction of ``predictor``, inflated by a margin.

    Args:
        predictor: the obstacle's predictor, fed by :meth:`update`.
        confidence: ``k`` of the margin (≥ 0).
        cap: the largest margin [m] (≥ 0).

    Attributes:
        revision: how many observations the track has taken (it changes with every prediction).
        last: time [s] of the last observation, ``None`` before the first.
    """

    def __init__(self, predictor: Predictor, confidence: float, cap: float) -> None:
        self.predictor, self.confidence, self.cap = predictor, confidence, cap
        self.rotation = np.eye(3)
        self.revision = 0
        self.last: float | None = None

    def update(self, t: float, position: Array, rotation: Array | None = None, velocity: Array | None = None) -> None:
        """Take a validated observation at ``t`` [s] (not before :attr:`last`): position ``(3,)`` [m], rotation
        ``(3, 3)`` and velocity ``(3,)`` [m/s] if given."""
        self.predictor.update(t, position, velocity)
        if rotation is not None:
            self.rotation = np.array(rotation, dtype=float)
        self.last = t
        self.revision += 1

    def take(self, other: Track) -> None:
        """Hold ``other``'s state (a copy of this track sent from another process): predictor, rotation, revision."""
        self.predictor, self.rotation, self.revision, self.last = (other.predictor, other.rotation, other.revision,
                                                                   other.last)

    def positions(self, times: ArrayLike) -> NDArray[np.float64]:
        """The predicted positions ``(T, 3)`` [m] at times ``(T,)`` [s]."""
        return np.array(self.predictor.predict(_times(times)), dtype=float).reshape(-1, 3)

    def placement(self, t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(position (3,) [m], rotation (3, 3))`` at time ``t`` [s]: the prediction and the last rotation."""
        return self.positions(np.array([real_scalar(t, "t", SceneError)]))[0], self.rotation.copy()

    def margin(self, times: ArrayLike) -> NDArray[np.float64]:
        """``min(cap, k σ(t))`` ``(T,)`` [m] at times ``(T,)`` [s] (module docstring)."""
        sigma = np.asarray(self.predictor.sigma(_times(times)), dtype=float)
        return np.minimum(self.cap, self.confidence * sigma)

    def __repr__(self) -> str:
        return f"Track({type(self.predictor).__name__}, last={self.last}, revision={self.revision})"


def _times(times: ArrayLike) -> Array:
    """Times ``(T,)`` [s], finite."""
    array = real_array(times, "times", SceneError).reshape(-1)
    check_finite(array, "times", SceneError)
    return array
