"""Coherent imaginary arms: each preview time keeps one peak's identity from frame to frame.

The paper's eq. 21 takes every imaginary arm's argmax afresh at each frame. Mirror configurations
(elbow up / elbow down) tie exactly when no obstacle breaks the tie, and near-ties between distinct
peaks are common, so the argmax jumps between peaks that the arm cannot move between, and the blend
``Σ k_i q̃_i`` of targets on different peaks lies on none of them. A :class:`PeakTracker` instead
follows one peak per imaginary arm:

* the tracked peak is the best individual of the imaginary arm's search within ``track_radius`` (in
  joint space) of the previous target. The controller seeds each search with its last target, so
  the tracked peak stays in the population, and with ``track_neighbours`` mutants of it, so that it
  climbs: on a spatial arm the population seldom holds another individual that close;
* the imaginary arms form a chain, as the sequences of the paper's Fig. 3: arm ``i`` (at ``t + i t̃``)
  must be reachable from arm ``i - 1`` (the real arm for ``i = 1``) within ``t̃`` at the joint speed
  limits, ``|Δq_j| ≤ q̇max_j t̃``. At the first frame each arm starts from the one before it, and a
  peak that is lost (no individual left within ``track_radius``) is replaced by the best individual
  within that reach of the arm before it, or, when none is, by the individual nearest to it (the
  individual nearest to the lost target could lie in a basin radians away);
* a better peak elsewhere never takes over: the pull of eq. 21 is a descent of the joint-space
  distance projected on the self-motion manifold, which stalls between basins. Changing basin
  deliberately is the job of a planned route (``reach``, and coherent ``multi`` where the route is
  planned: :mod:`previewctl.control.planner`), which checks the move;
* after every change of peak (and at the start) the pull is ramped in linearly over ``settle_frames``
  camera frames, so the arm does not lunge at a target the search has not settled on.

The search itself is kept on the arm's own family (the elbow branch of a planar arm, see
:attr:`previewctl.search.ga.OneStepGA.branch_lock`), so every candidate is on the arm's branch.

What each rule changed, measured: docs/guide/controllers.md#preview-control-coherent-imaginary-arms and
docs/decisions.md#mutants-of-the-tracked-peak-on-spatial-arms.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from previewctl.robot.model import Robot
from previewctl.search.genes import joint_distance
from previewctl.search.redundancy import wrap_angle
from previewctl.types import Array


def near(robot: Robot, reference: Array | None, nodes: Array, radius: float) -> NDArray[np.bool_]:
    """Which ``nodes`` ``(B, nq)`` lie within ``radius`` [rad] of ``reference`` ``(nq,)`` in joint space (full-turn
    joints compared modulo 2π): the peaks that keep ``reference``'s identity. None without a reference."""
    if reference is None or not len(nodes):
        return np.zeros(len(nodes), dtype=bool)
    angles = robot.angles_of(np.vstack([reference[None], nodes]))
    distance = joint_distance(angles[1:], angles[:1], robot.joints.full_turn)[:, 0]
    return np.asarray(distance <= radius)


@dataclass(frozen=True)
class TrackedPeak:
    """One imaginary arm's target after a frame.

    Attributes:
        q: ``(nq,)`` the target configuration [rad].
        S: its AMSIP.
        switched: whether the peak changed at this frame (the first frame, or the peak was lost).
        ramp: the pull factor in [0, 1] (0 right after a change, 1 once settled).
    """

    q: Array
    S: float
    switched: bool
    ramp: float


class PeakTracker:
    """Keeps the identity of one imaginary arm's peak between camera frames.

    Args:
        angles: maps configurations ``(B, nq)`` to joint angles ``(B, nv)`` [rad] for distances.
        periodic: ``(nv,)`` joints compared modulo 2π.
        track_radius: largest joint-space move [rad] of a peak between two frames for it to count as
            the same peak.
        settle_frames: frames over which the pull is ramped in after a change (``≥ 1``).
    """

    def __init__(
        self,
        angles: Callable[[Array], Array],
        periodic: NDArray[np.bool_],
        *,
        track_radius: float,
        settle_frames: int,
    ) -> None:
        self._angles = angles
        self._periodic = periodic
        self.track_radius, self.settle_frames = track_radius, settle_frames
        self._q: Array | None = None
        self._since_switch = 0

    def update(self, Q: Array, S: Array, before: Array, reach: Array) -> TrackedPeak | None:
        """Choose this frame's target among a search's individuals ``Q`` ``(B, nq)`` with AMSIP ``S`` ``(B,)``.

        The tracked peak is the best individual within ``track_radius`` of the last target (the local
        peak's current representative). At the first frame the "last target" is ``before``, the arm one
        preview step earlier in the chain (the real arm for the first imaginary arm), so each imaginary
        arm climbs the peak whose basin holds the arm before it. A lost peak is replaced by the best
        individual within ``reach`` of ``before``, or the one nearest to ``before`` when none is.

        Args:
            Q: the search's individuals ``(B, nq)``.
            S: their AMSIP ``(B,)``.
            before: ``(nq,)`` the configuration one preview step earlier in the chain.
            reach: ``(nv,)`` [rad] how far each joint can move in one preview step (``q̇max t̃``; may be inf).

        Returns:
            The target, or ``None`` if no individual has ``S > 0`` (the caller keeps its last target).
        """
        valid = np.flatnonzero(S > 0)
        if not valid.size:
            return None
        Qv, Sv = Q[valid], S[valid]
        first = self._q is None
        previous = np.asarray(before, dtype=float)
        last = previous if self._q is None else self._q
        to = self._angles(np.vstack([last[None], previous[None], Qv]))
        distance = joint_distance(to[2:], to[:1], self._periodic)[:, 0]
        near = distance <= self.track_radius
        if near.any():
            chosen, switched = int(np.flatnonzero(near)[np.argmax(Sv[near])]), first
        else:  # the peak was lost: the best within reach of the arm before, else the nearest to it
            step = to[2:] - to[1]
            step = np.where(self._periodic, wrap_angle(step), step)
            within = np.all(np.abs(step) <= reach, axis=1)
            chosen = (int(np.flatnonzero(within)[np.argmax(Sv[within])]) if within.any()
                      else int(np.argmin(joint_distance(to[2:], to[1:2], self._periodic)[:, 0])))
            switched = True
        self._since_switch = 0 if switched else self._since_switch + 1
        self._q = np.array(Qv[chosen], dtype=float)
        ramp = min(1.0, self._since_switch / self.settle_frames)
        return TrackedPeak(self._q.copy(), float(Sv[chosen]), bool(switched), ramp)
