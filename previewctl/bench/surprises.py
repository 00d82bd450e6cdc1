"""Surprise scenes: the crossing obstacle of a bench scene turns, stops, changes speed or wanders instead of keeping
its velocity (``previewctl bench --motions surprise``), so that a constant-velocity prediction is wrong some of the
time (issue 33).

:func:`surprise` turns the constant-velocity crossing that :mod:`previewctl.bench.scenes` drew (start ``p0``, velocity
``v``, at the link at ``t_c``) into one of :data:`SURPRISES`, drawn uniformly from the scene's generator. The surprise
happens at ``t_s = t_c − U(0.5, 1.5) s`` (clipped at ``0.5 s``), while the obstacle is on its way to the arm:

* ``turn``: the velocity turns by ``±U(45°, 90°)`` at ``U(0.5, 2) rad/s`` (about z on a planar arm; about an axis
  across the velocity otherwise);
* ``stop``: it brakes to a halt over ``U(0.2, 1) s``;
* ``speed_change``: its speed is multiplied by ``U(0.3, 0.6)`` or ``U(1.5, 2.5)`` over ``U(0, 0.5) s``;
* ``random_walk``: from ``p0`` with velocity ``v`` it wanders smoothly (speed ``|v|``, correlation time 2 s) in a box
  centred on the crossing point, ``1.25 |p0 − crossing|`` half-wide per axis (at least ``4 × radius``), never
  leaving it.

The same generator state gives the same motion, so a surprise scene replays like any other.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from previewctl.types import Array

SURPRISES = ("turn", "stop", "speed_change", "random_walk")
"""The motion types a surprise scene draws from (:mod:`previewctl.scene.motion`)."""
WALK_CORRELATION = 2.0
"""Correlation time [s] of a surprise random walk's velocity."""


def _listed(vector: Array, dims: int) -> list[float]:
    return [float(v) for v in vector[:dims]]


def surprise(rng: np.random.Generator, start: Array, velocity: Array, point: Array, t_c: float, radius: float,
             duration: float, dims: int) -> dict[str, Any]:
    """The motion table of a surprise instead of the straight crossing ``start + velocity t`` through ``point`` at
    ``t_c`` [s] (vectors of shape (3,) [m], [m/s]; ``dims`` = 2 on a planar arm, 3 otherwise).

    Args:
        rng: the scene's generator (advanced).
        start: the obstacle's position at ``t = 0`` [m].
        velocity: its velocity [m/s].
        point: where it crosses the link [m].
        t_c: when [s].
        radius: the obstacle's radius [m].
        duration: the run's length [s] (a random walk walks 1 s longer).
        dims: 2 (planar) or 3.
    """
    kind = SURPRISES[int(rng.integers(len(SURPRISES)))]
    t_s = max(0.5, t_c - rng.uniform(0.5, 1.5))
    table: dict[str, Any] = {"type": kind, "position": _listed(start, dims), "velocity": _listed(velocity, dims)}
    if kind == "turn":
        axis = np.array([0.0, 0.0, 1.0])
        if dims == 3:
            axis = np.cross(velocity, rng.normal(size=3))
            axis /= np.linalg.norm(axis)
        sign = 1.0 if rng.random() < 0.5 else -1.0
        return {**table, "turn_time": t_s, "angle": sign * rng.uniform(math.pi / 4, math.pi / 2),
                "rate": rng.uniform(0.5, 2.0), "axis": [float(v) for v in axis]}
    if kind == "stop":
        return {**table, "stop_time": t_s, "braking_time": rng.uniform(0.2, 1.0)}
    if kind == "speed_change":
        factor = rng.uniform(0.3, 0.6) if rng.random() < 0.5 else rng.uniform(1.5, 2.5)
        return {**table, "change_time": t_s, "factor": factor, "ramp_time": rng.uniform(0.0, 0.5)}
    half = np.maximum(1.25 * np.abs(start - point), 4.0 * radius)[:dims]
    return {**table, "center": _listed(point, dims), "half_size": [float(v) for v in half],
            "speed": float(np.linalg.norm(velocity)), "seed": int(rng.integers(2**31)),
            "correlation_time": WALK_CORRELATION, "duration": duration + 1.0}
