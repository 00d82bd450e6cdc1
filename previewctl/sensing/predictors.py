"""Predictors: an obstacle's future position and its uncertainty, from its observations.

A predictor (:class:`Predictor`) takes the observations of one obstacle in time order (``update``) and answers, for
any times, the predicted position (``predict``) and the standard deviation of each coordinate of that position
(``sigma``), isotropic. Two are built in; the axes are independent, each with the same covariance:

* :class:`ConstantVelocityKalman` (the default): a Kalman filter per axis on the state ``(x, v)`` with white-noise
  acceleration of spectral density ``q`` [m²/s³] and position measurements of standard deviation ``r`` [m]. Between
  observations ``Δt`` apart the state moves by ``F = [[1, Δt], [0, 1]]`` and its covariance grows by
  ``Q = q [[Δt³/3, Δt²/2], [Δt²/2, Δt]]``. The prediction at look-ahead ``τ = t − t_last`` from the last observation
  is ``x + v τ`` with

      σ(τ)² = P_xx + 2 τ P_xv + τ² P_vv + q τ³ / 3        (τ >= 0; σ(τ) = σ(0) before the last observation)

  (the position entry of ``F P Fᵀ + Q`` for ``Δt = τ``).
* :class:`Stationary`: the obstacle stays where it is, up to a random walk of velocity spectral density ``q``
  [m²/s]: per axis a Kalman filter on ``x`` alone; the prediction is ``x`` and ``σ(τ)² = P + q τ``. With ``q = 0`` its
  estimate is the mean of the observations (a batch least-squares estimate).

A predictor must be picklable (with background planning its state is sent to the worker at every exchange).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike

from previewctl.types import Array


@runtime_checkable
class Predictor(Protocol):
    """One obstacle's prediction from its observations (module docstring)."""

    def update(self, t: float, position: Array, velocity: Array | None = None) -> None:
        """Take an observation: position ``(3,)`` [m] (and velocity ``(3,)`` [m/s], if measured) at time ``t`` [s],
        never earlier than the previous one (validated by the caller)."""
        ...

    def predict(self, times: ArrayLike) -> Array:
        """The predicted positions ``(T, 3)`` [m] at times ``(T,)`` [s]."""
        ...

    def sigma(self, times: ArrayLike) -> Array:
        """The standard deviation ``(T,)`` [m] of each coordinate of the predicted position at times ``(T,)`` [s]."""
        ...


class ConstantVelocityKalman:
    """A constant-velocity Kalman filter per axis (module docstring).

    Args:
        q: spectral density of the white-noise acceleration [m²/s³].
        r: standard deviation of a position measurement [m].
        velocity_noise: standard deviation of a velocity measurement [m/s] (an observation that carries one).
        initial_speed: standard deviation of the velocity before any velocity is known [m/s].
    """

    def __init__(self, q: float = 0.01, r: float = 0.005, velocity_noise: float = 0.05,
                 initial_speed: float = 1.0) -> None:
        self.q, self.r, self.velocity_noise, self.initial_speed = q, r, velocity_noise, initial_speed
        self.t: float | None = None  # time [s] of the last observation
        self.x = np.zeros(3)  # position [m]
        self.v = np.zeros(3)  # velocity [m/s]
        self.P = np.zeros((2, 2))  # covariance of (x, v) per axis [m², m²/s, m²/s²]

    def update(self, t: float, position: Array, velocity: Array | None = None) -> None:
        """Predict the state to ``t`` [s], then correct it with the position ``(3,)`` [m] (and velocity ``(3,)``
        [m/s]); the first observation starts the filter at it."""
        if self.t is None:
            self.x, self.v = np.array(position, dtype=float), np.zeros(3)
            self.P = np.diag([self.r ** 2, self.initial_speed ** 2])
        else:
            dt = t - self.t
            self.x = self.x + self.v * dt
            self.P = self._propagated(dt)
            gain = self.P[:, 0] / (self.P[0, 0] + self.r ** 2)  # K = P Hᵀ / (H P Hᵀ + r²), H = [1, 0]
            innovation = np.asarray(position, dtype=float) - self.x
            self.x, self.v = self.x + gain[0] * innovation, self.v + gain[1] * innovation
            self.P = self.P - np.outer(gain, self.P[0])
        if velocity is not None:  # a second measurement, H = [0, 1]
            gain = self.P[:, 1] / (self.P[1, 1] + self.velocity_noise ** 2)
            innovation = np.asarray(velocity, dtype=float) - self.v
            self.x, self.v = self.x + gain[0] * innovation, self.v + gain[1] * innovation
            self.P = self.P - np.outer(gain, self.P[1])
        self.t = float(t)

    def _propagated(self, dt: float) -> Array:
        """The covariance ``F P Fᵀ + Q`` after ``dt`` [s] (module docstring)."""
        F = np.array([[1.0, dt], [0.0, 1.0]])
        Q = self.q * np.array([[dt ** 3 / 3, dt ** 2 / 2], [dt ** 2 / 2, dt]])
        return F @ self.P @ F.T + Q

    def _ahead(self, times: ArrayLike) -> Array:
        """Look-ahead ``t − t_last`` [s] of each time ``(T,)``."""
        return np.asarray(times, dtype=float) - (self.t if self.t is not None else 0.0)

    def predict(self, times: ArrayLike) -> Array:
        """``x + v τ`` ``(T, 3)`` [m] at times ``(T,)`` [s]."""
        return self.x + self._ahead(times)[:, None] * self.v

    def sigma(self, times: ArrayLike) -> Array:
        """``σ(τ)`` ``(T,)`` [m] of the module docstring at times ``(T,)`` [s]."""
        tau = np.maximum(self._ahead(times), 0.0)
        P = self.P
        return np.sqrt(P[0, 0] + 2 * tau * P[0, 1] + tau ** 2 * P[1, 1] + self.q * tau ** 3 / 3)


class Stationary:
    """An obstacle that stays where it is, up to a random walk (module docstring).

    Args:
        q: spectral density of the random walk's velocity [m²/s].
        r: standard deviation of a position measurement [m].
    """

    def __init__(self, q: float = 0.01, r: float = 0.005) -> None:
        self.q, self.r = q, r
        self.t: float | None = None  # time [s] of the last observation
        self.x = np.zeros(3)  # position [m]
        self.P = 0.0  # variance of each coordinate [m²]

    def update(self, t: float, position: Array, velocity: Array | None = None) -> None:
        """Correct the position with the observed one ``(3,)`` [m] at ``t`` [s]; a velocity is not used."""
        if self.t is None:
            self.x, self.P = np.array(position, dtype=float), self.r ** 2
        else:
            prior = self.P + self.q * (t - self.t)
            gain = prior / (prior + self.r ** 2)
            self.x = self.x + gain * (np.asarray(position, dtype=float) - self.x)
            self.P = (1.0 - gain) * prior
        self.t = float(t)

    def predict(self, times: ArrayLike) -> Array:
        """The estimate ``(T, 3)`` [m] at every time ``(T,)`` [s]."""
        return np.tile(self.x, (np.asarray(times).shape[0], 1))

    def sigma(self, times: ArrayLike) -> Array:
        """``sqrt(P + q τ)`` ``(T,)`` [m] at times ``(T,)`` [s]."""
        tau = np.maximum(np.asarray(times, dtype=float) - (self.t if self.t is not None else 0.0), 0.0)
        return np.sqrt(self.P + self.q * tau)
