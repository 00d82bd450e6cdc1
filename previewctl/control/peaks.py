"""Coherent imaginary arms: each preview time keeps one peak's identity from frame to frame.

The paper's eq. 21 takes every imaginary arm's argmax afresh at each frame. Mirror configurations
(elbow up / elbow down) tie exactly when no obstacle breaks the tie, and near-ties between distinct
peaks are common, so the argmax jumps between peaks that the arm cannot move between, and the blend
``Σ k_i q̃_i`` of targets on different peaks lies on none of them. A :class:`PeakTracker` instead
follows one peak per imaginary arm:

* the tracked peak is the best individual of the imaginary arm's search within ``track_radius`` (in
  joint space) of the previous target; if none is left, the peak is lost and the nearest surviving
  individual is taken. At the first frame the previous target is the real arm itself, so each
  imaginary arm starts on the peak whose basin holds the arm. The controller seeds each search with
  its last target, so the tracked peak stays in the population;
* a better peak elsewhere never takes over: the pull of eq. 21 is a descent of the joint-space
  distance projected on the self-motion manifold, which stalls between basins (measured on
  ``planar_free``: a switch to a peak twice as good across ``q2 = 0`` left the arm stuck at
  ``S ≈ 300``). Changing basin deliberately is the job of ``reach``, which checks the move;
* after every change of peak (and at the start) the pull is ramped in linearly over ``settle_frames``
  camera frames, so the arm does not lunge at a target the search has not settled on.

The search itself is kept on the arm's own family (the elbow branch of a planar arm, see
:attr:`previewctl.search.ga.OneStepGA.branch_lock`), so every candidate is on the arm's branch.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from previewctl.search.genes import joint_distance
from previewctl.types import Array


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

    def update(self, Q: Array, S: Array, start: Array) -> TrackedPeak | None:
        """Choose this frame's target among a search's individuals ``Q`` ``(B, nq)`` with AMSIP ``S`` ``(B,)``.

        The tracked peak is the best individual within ``track_radius`` of the last target (the local
        peak's current representative). At the first frame the "last target" is ``start`` (the real
        arm's configuration), so the imaginary arm climbs the peak whose basin the arm is in.

        Returns:
            The target, or ``None`` if no individual has ``S > 0`` (the caller keeps its last target).
        """
        valid = np.flatnonzero(S > 0)
        if not valid.size:
            return None
        Qv, Sv = Q[valid], S[valid]
        first = self._q is None
        last = np.asarray(start, dtype=float) if self._q is None else self._q
        to = self._angles(np.vstack([last[None], Qv]))
        distance = joint_distance(to[1:], to[:1], self._periodic)[:, 0]
        near = distance <= self.track_radius
        if near.any():
            chosen, switched = int(np.flatnonzero(near)[np.argmax(Sv[near])]), first
        else:  # the peak was lost: the nearest surviving individual
            chosen, switched = int(np.argmin(distance)), True
        self._since_switch = 0 if switched else self._since_switch + 1
        self._q = np.array(Qv[chosen], dtype=float)
        ramp = min(1.0, self._since_switch / self.settle_frames)
        return TrackedPeak(self._q.copy(), float(Sv[chosen]), bool(switched), ramp)
