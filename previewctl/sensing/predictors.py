"""Predictors: an obstacle's future position and its uncertainty, from its observations.

A predictor (:class:`Predictor`) takes the observations of one obstacle in time order (``update``) and answers, for
any times, the predicted position (``predict``) and the standard deviation of each coordinate of that position
(``sigma``), isotropic. Three are built in; the axes are independent, each with the same covariance:

* :class:`ConstantVelocityKalman`: a Kalman filter per axis on the state ``(x, v)`` with white-noise
  acceleration of spectral density ``q`` [m²/s³] and position measurements of standard deviation ``r`` [m]. Between
  observations ``Δt`` apart the state moves by ``F = [[1, Δt], [0, 1]]`` and its covariance grows by
  ``Q = q [[Δt³/3, Δt²/2], [Δt²/2, Δt]]``. The prediction at look-ahead ``τ = t − t_last`` from the last observation
  is ``x + v τ`` with

      σ(τ)² = P_xx + 2 τ P_xv + τ² P_vv + q τ³ / 3        (τ >= 0; σ(τ) = σ(0) before the last observation)

  (the position entry of ``F P Fᵀ + Q`` for ``Δt = τ``).
* :class:`ManoeuvreKalman` (the default): an interacting multiple model (IMM) filter of two such Kalman filters,
  one cruising (small ``q``: a velocity that hardly drifts, so a prediction seconds ahead stays close on a straight)
  and one manoeuvring (large ``q``: it follows a turn, a stop or a speed-up within a few observations), each model
  held for a mean time before it switches (``P(switch over Δt) = 1 − exp(−Δt / T_j)``). At each observation each filter
  starts from the mixture of both states, weighted by ``P(model i before | model j now)`` (the spread of the means,
  averaged over the axes, added to the covariance, which stays the same on every axis), takes the observation,
  and the model probabilities ``μ_j`` are reweighted by how likely each filter found it (the Gaussian density of
  its innovation). The prediction is ``m(τ) = Σ_j μ_j m_j(τ)`` and

      σ(τ)² = Σ_j μ_j (σ_j(τ)² + |m_j(τ) − m(τ)|² / 3)

  the mixture's variance per coordinate. On a straight the cruising model holds almost all the probability and σ
  stays small; through a turn the manoeuvring one takes over and σ says so.
* :class:`Stationary`: the obstacle stays where it is, up to a random walk of velocity spectral density ``q``
  [m²/s]: per axis a Kalman filter on ``x`` alone; the prediction is ``x`` and ``σ(τ)² = P + q τ``. With ``q = 0`` its
  estimate is the mean of the observations (a batch least-squares estimate).

A predictor must be picklable (with background planning its state is sent to the worker at every exchange).
"""

from __future__ import annotations

from collections.abc import Iterable
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
        self.log_likelihood = 0.0
        """The log-likelihood of the last observation under the filter's prediction (0 for the first)."""

    def update(self, t: float, position: Array, velocity: Array | None = None) -> None:
        """Predict the state to ``t`` [s], then correct it with the position ``(3,)`` [m] (and velocity ``(3,)``
        [m/s]); the first observation starts the filter at it."""
        self.log_likelihood = 0.0
        if self.t is None:
            self.x, self.v = np.array(position, dtype=float), np.zeros(3)
            self.P = np.diag([self.r ** 2, self.initial_speed ** 2])
        else:
            dt = t - self.t
            self.x = self.x + self.v * dt
            self.P = self._propagated(dt)
            self._correct(0, np.asarray(position, dtype=float) - self.x, self.r)
        if velocity is not None:  # a second measurement, H = [0, 1]
            self._correct(1, np.asarray(velocity, dtype=float) - self.v, self.velocity_noise)
        self.t = float(t)

    def _correct(self, row: int, innovation: Array, noise: float) -> None:
        """The Kalman correction by a measurement of the state's ``row`` (0: position, 1: velocity) on every axis,
        ``innovation`` ``(3,)`` its difference from the prediction, ``noise`` its standard deviation; adds the
        measurement's log-likelihood ``Σ_axes log N(innovation; 0, H P Hᵀ + noise²)`` to :attr:`log_likelihood`."""
        spread = self.P[row, row] + noise ** 2
        gain = self.P[:, row] / spread  # K = P Hᵀ / (H P Hᵀ + noise²)
        self.x, self.v = self.x + gain[0] * innovation, self.v + gain[1] * innovation
        self.P = self.P - np.outer(gain, self.P[row])
        self.log_likelihood -= 0.5 * float(innovation @ innovation / spread + 3 * np.log(2 * np.pi * spread))

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


class ManoeuvreKalman:
    """Two constant-velocity Kalman filters, cruising and manoeuvring, mixed by an interacting multiple model (IMM)
    filter (module docstring).

    Args:
        q_cruise: the cruising filter's ``q`` [m²/s³]: a velocity that drifts little.
        q_manoeuvre: the manoeuvring filter's ``q`` [m²/s³]: turns, stops and speed-ups.
        cruise_time: the mean time [s] an obstacle cruises before it manoeuvres.
        manoeuvre_time: the mean time [s] a manoeuvre lasts.
        r: standard deviation of a position measurement [m].
        velocity_noise: standard deviation of a velocity measurement [m/s].
        initial_speed: standard deviation of the velocity before any velocity is known [m/s].

    Attributes:
        models: the two filters, ``(cruising, manoeuvring)``.
        probabilities: ``(2,)`` the probability of each model given the observations.
    """

    def __init__(self, q_cruise: float = 1e-4, q_manoeuvre: float = 0.1, cruise_time: float = 2.0,
                 manoeuvre_time: float = 0.5, r: float = 0.005, velocity_noise: float = 0.05,
                 initial_speed: float = 1.0) -> None:
        self.models = tuple(ConstantVelocityKalman(q, r, velocity_noise, initial_speed)
                            for q in (q_cruise, q_manoeuvre))
        self.times = np.array([cruise_time, manoeuvre_time])
        self.probabilities = np.array([0.5, 0.5])

    @property
    def t(self) -> float | None:
        """Time [s] of the last observation, ``None`` before the first."""
        return self.models[0].t

    def update(self, t: float, position: Array, velocity: Array | None = None) -> None:
        """Mix the two filters' states by the chance of a switch since the last observation, update each with the
        observation at ``t`` [s], and weigh them by how well each foresaw it (module docstring)."""
        if self.t is not None:
            self._mix(t - self.t)
        for model in self.models:
            model.update(t, position, velocity)
        log = np.log(np.maximum(self.probabilities, 1e-300)) + [model.log_likelihood for model in self.models]
        weights = np.exp(log - log.max())
        self.probabilities = weights / weights.sum()

    def _mix(self, dt: float) -> None:
        """Each filter starts the step from the mixture of both states, weighted by ``P(was i | is j)``."""
        leave = 1.0 - np.exp(-dt / self.times)  # (2,) the chance that each model switched over dt
        switch = np.array([[1.0 - leave[0], leave[0]], [leave[1], 1.0 - leave[1]]])  # [i, j]: from i to j
        joint = self.probabilities[:, None] * switch
        prior = joint.sum(axis=0)
        given = joint / np.maximum(prior, 1e-300)  # [i, j]: P(was i | is j)
        states = [np.stack([m.x, m.v]) for m in self.models]  # (2, 3) each
        covariances = [m.P for m in self.models]
        mixed = []
        for j in range(2):
            mean = sum(given[i, j] * states[i] for i in range(2))
            P = sum(given[i, j] * (covariances[i] + (states[i] - mean) @ (states[i] - mean).T / 3) for i in range(2))
            mixed.append((mean, P))
        for model, (mean, P) in zip(self.models, mixed, strict=True):
            model.x, model.v, model.P = mean[0], mean[1], P
        self.probabilities = prior

    def _mixed(self, parts: Iterable[Array]) -> Array:
        """``Σ_j μ_j part_j``: the mixture of one value per model, in the models' order."""
        return sum(mu * part for mu, part in zip(self.probabilities, parts, strict=True))

    def predict(self, times: ArrayLike) -> Array:
        """``Σ_j μ_j (x_j + v_j τ)`` ``(T, 3)`` [m] at times ``(T,)`` [s]."""
        return self._mixed(model.predict(times) for model in self.models)

    def sigma(self, times: ArrayLike) -> Array:
        """The mixture's ``σ(τ)`` ``(T,)`` [m] at times ``(T,)`` [s] (module docstring)."""
        means = [model.predict(times) for model in self.models]
        mean = self._mixed(means)
        return np.sqrt(self._mixed(model.sigma(times) ** 2 + ((m - mean) ** 2).sum(axis=1) / 3
                                   for model, m in zip(self.models, means, strict=True)))


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
