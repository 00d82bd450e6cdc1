"""The simulator's sensor: it observes the true motion of a scenario's observed obstacles and feeds the controller.

With a scenario's ``[sensing]`` table (:class:`~previewctl.sensing.options.Sensing`), every obstacle it observes
(:meth:`~previewctl.sensing.options.Sensing.observed`) is sampled at ``t_obs = k / rate`` [s] over the run, from
``k = −⌊history · rate⌋`` (``history``: how long the sensor already runs before ``t = 0``): its true position (the
only place besides the exact check where the simulator reads the true motion), plus Gaussian noise of standard
deviation ``noise`` [m] per coordinate (x and y on a planar arm, whose observations have 2 entries); each sample is
dropped with probability ``dropout``. The rest are delivered at ``t_obs + latency``: the loop calls
``controller.observe(name, position, t_obs, rotation=..., shape=...)`` for every observation due by a step's time,
before that step (:func:`~previewctl.sim.loop.simulate`). The noise and the dropouts are drawn from
``np.random.default_rng(seed)`` when the sensor is made, obstacle by obstacle in scene order, so a run replays.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from previewctl.control.controller import Controller
from previewctl.scene.shapes import Obstacle, Scene
from previewctl.sensing.options import Sensing
from previewctl.types import Array

DUE_SLACK = 1e-9
"""Round-off [s] allowed when an observation is due at a step's time exactly."""


@dataclass(frozen=True)
class Observation:
    """One observation the sensor delivers.

    Attributes:
        due: when it is delivered, ``t + latency`` [s].
        t: when it was made [s] (the path's clock).
        obstacle: the observed obstacle (its name, shape and true motion).
        position: the noisy position, shape (2,) on a planar arm, else (3,) [m].
    """

    due: float
    t: float
    obstacle: Obstacle
    position: Array


class Sensor:
    """The observations of one run (module docstring), made in advance and delivered by :meth:`deliver`.

    Args:
        scene: the scenario's scene, with the true motions.
        sensing: which obstacles are observed, and ``rate``, ``noise``, ``latency``, ``dropout``, ``seed``.
        duration: how long the run lasts [s]: observations are made over ``[−history, duration]``.
        planar: whether the arm is planar (observations of 2 entries).

    Attributes:
        delivered: the observations delivered so far.
    """

    def __init__(self, scene: Scene, sensing: Sensing, duration: float, planar: bool) -> None:
        rng = np.random.default_rng(sensing.seed)
        first = -math.floor(sensing.history * sensing.rate + DUE_SLACK)
        times = np.arange(first, math.floor(duration * sensing.rate + DUE_SLACK) + 1) / sensing.rate
        dims = 2 if planar else 3
        observed = set(sensing.observed(scene))
        queue: list[Observation] = []
        lost: list[Array] = []
        for obstacle in scene.obstacles:
            if obstacle.name not in observed:
                continue
            positions = obstacle.motion.positions(times)[:, :dims] + rng.normal(0.0, sensing.noise, (times.size, dims))
            kept = rng.random(times.size) >= sensing.dropout
            lost.append(times[~kept] + sensing.latency)
            queue += [Observation(float(t) + sensing.latency, float(t), obstacle, p)
                      for t, p in zip(times[kept], positions[kept], strict=True)]
        queue.sort(key=lambda o: (o.due, o.t))  # stable: obstacles in scene order at equal times
        self._queue = queue
        self._lost = np.sort(np.concatenate(lost)) if lost else np.zeros(0)
        self.delivered = 0

    def dropped_by(self, t: float) -> int:
        """How many observations that were due by ``t`` [s] were dropped."""
        return int(np.searchsorted(self._lost, t + DUE_SLACK, side="right"))

    def deliver(self, controller: Controller, t: float) -> int:
        """Hand ``controller`` every observation due by ``t`` [s] not delivered yet, oldest first; how many."""
        count = 0
        while self.delivered + count < len(self._queue) and self._queue[self.delivered + count].due <= t + DUE_SLACK:
            seen = self._queue[self.delivered + count]
            rotation = seen.obstacle.motion.placement(seen.t)[1]
            controller.observe(seen.obstacle.name, seen.position, seen.t, rotation=rotation, shape=seen.obstacle.shape)
            count += 1
        self.delivered += count
        return count
