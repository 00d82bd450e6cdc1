"""AMSIP ``S = E + U`` (paper eq. 18): the AMSI lowered by a potential from true obstacle and self distances.

The potential (our design; the paper defers it to its ref. [8]). With ``d_i`` the minimum distance
[m] between guarded link ``i`` and every obstacle, ``d_0`` the influence distance, ``g`` the gain,
``s`` the smallest distance [m] between the arm's self pairs (:mod:`previewctl.robot.self_pairs`) and ``d_s``
the self influence distance,

    phi(d; r) = g * clip((r - d) / r, 0, 1)^2                    (0 beyond r, g at contact)
    S         = E * prod_i (1 - phi(d_i; d_0)) * (1 - phi(s; d_s))  when nothing collides,
    S         = collision_value (< 0)                          when some d_i <= 0 or s <= 0,
    U         = S - E <= 0.

So ``S >= 0`` for every collision-free configuration and ``S < 0`` exactly when the arm collides with
an obstacle or with itself (and, in the redundancy search, when the hand target is out of reach). The
ramp is C^1 at its influence distance; with ``g = 1`` it brings S continuously to 0 at contact. Defaults
suit planar4 in metres: links of 0.75 m, influence distance 0.15 m; self influence 0.05 m. An arm without
self pairs (planar4: its shipped SRDF disables them all) has no self factor at all: its S is bit for bit
what it was before self pairs existed.

Self distances come from bounding-sphere tests first (:mod:`previewctl.scene.self_clearance`): exact below
``d_s``, a lower bound (at least ``d_s``) above it. Obstacle distances are exact unless a call asks for fewer
(the ``exact_below`` of a call to :class:`Evaluator`): then they are screened the same way (:meth:`Clearance.screened
<previewctl.scene.clearance.Clearance.screened>`), exact below ``max(exact_below, d_0)`` and a lower bound above it,
which leaves ``S`` the same bit for bit (the potential is 0 beyond ``d_0``) at a fraction of the Coal calls.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, fields
from typing import Literal

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from previewctl.errors import ParameterError
from previewctl.index.amsi import IndexParams, amsi_from_kinematics
from previewctl.index.planar import PlanarArm
from previewctl.index.potential import Potential
from previewctl.kinematics import kinematics, kinematics_reader
from previewctl.planar import kernels as planar_kernels
from previewctl.planar.distance import planar_kernel
from previewctl.robot.model import Robot
from previewctl.scene.clearance import Clearance
from previewctl.scene.motion import Static, Uncertain, margin_at
from previewctl.scene.shapes import Scene
from previewctl.types import Array
from previewctl.validation import real_scalar, validate

Method = Literal["auto", "planar", "general"]

POTENTIAL_ONLY = 0.0
"""The ``exact_below`` [m] of a call that reads only ``S`` and the collisions: its obstacle distances are exact within
the potential's influence distance and bounds beyond it, the same ``S`` at a fraction of the Coal calls."""


@dataclass(frozen=True)
class Evaluation:
    """AMSIP of a batch of configurations (every array has leading dimension ``B``).

    Attributes:
        S: AMSIP (dimensionless); negative exactly in collision.
        amsi: AMSI ``E``.
        U: potential ``S - E`` (<= 0).
        min_distance: smallest link-obstacle distance [m] (``inf`` without obstacles).
        link_distances: ``(B, L)`` per guarded link [m].
        collision: whether some guarded link touches an obstacle.
        tip_position: ``(B, 3)`` hand position [m].
        self_distance: smallest distance between the arm's self pairs [m]: exact below the potential's
            ``self_influence_distance``, else a lower bound at least that (``inf`` without self pairs).
        self_collision: whether two of the arm's own links touch (``self_distance <= 0``).
        self_pair: index of the nearest self pair in ``robot.self_pairs`` (a geometry pair; its links:
            ``robot.self_pairs.pair_names(k)``), ``-1`` without self pairs.
    """

    S: Array
    amsi: Array
    U: Array
    min_distance: Array
    link_distances: Array
    collision: NDArray[np.bool_]
    tip_position: Array
    self_distance: Array
    self_collision: NDArray[np.bool_]
    self_pair: NDArray[np.int64]


class Evaluator:
    """Evaluates AMSIP for one robot in one scene; holds the Pinocchio/Coal workspaces for reuse.

    Args:
        robot: the arm.
        scene: the obstacles.
        index: AMSI parameters.
        potential: potential parameters.
        method: ``"planar"`` (closed form, vectorised; planar arms with primitive obstacles and no self pairs),
            ``"general"`` (one Pinocchio pass per configuration) or ``"auto"`` (planar when possible). A planar
            arm with self pairs takes the general path: the closed form has no self distances.
    """

    def __init__(
        self,
        robot: Robot,
        scene: Scene | None = None,
        index: IndexParams | None = None,
        potential: Potential | None = None,
        method: Method = "auto",
    ) -> None:
        validate(Method, method, ParameterError, root="method")
        self.robot, self.scene = robot, scene or Scene()
        self.index, self.potential = index or IndexParams(), potential or Potential()
        self.method: Method = method
        self.data = robot.model.createData()
        self.clearance = Clearance(robot, self.scene)
        self._self = self.clearance.self_clearance
        # the reader also reads the placements of the joints that carry self or guarded geometry, for their bounds
        joints = sorted(set(self._self.joints) | set(self.clearance.joints))
        self._kinematics = kinematics_reader(robot, self.data, joints, compiled=True)
        self._self_slots = np.array([joints.index(j) for j in self._self.joints], dtype=int)
        self._guarded_slots = np.array([joints.index(j) for j in self.clearance.joints], dtype=int)
        self._planar_arm = (
            PlanarArm(robot.planar, robot.structural_ranks, self.index) if robot.planar is not None else None
        )
        hand = {robot.guarded_links.index(link) for link in robot.hand_links}
        self._hand_slots = [s for s, link in enumerate(robot.planar.link_index) if link in hand] if robot.planar else []
        # static obstacles: their planar kernels are built (and validated) once
        self._static_kernels = {
            i: planar_kernel(o, 0.0) for i, o in enumerate(self.scene.obstacles) if isinstance(o.motion, Static)
        } if robot.planar is not None else {}

    def _planar_kernels(self, t: float) -> list[planar_kernels.Kernel] | None:
        """One distance kernel per obstacle at time ``t`` [s], or ``None`` if the planar path cannot serve."""
        if self.robot.planar is None or len(self._self):
            return None
        kernels = []
        for i, obstacle in enumerate(self.scene.obstacles):
            kernel = self._static_kernels[i] if i in self._static_kernels else planar_kernel(obstacle, t)
            if kernel is None:
                return None
            kernels.append(kernel)
        return kernels

    @property
    def predicts(self) -> bool:
        """Whether some obstacle of the scene is a prediction (:class:`~previewctl.scene.motion.Uncertain`), inflated
        by its margin."""
        return self.clearance.predicts

    @contextmanager
    def without_margins(self) -> Iterator[None]:
        """Within the block, predicted obstacles count at their predicted size, not inflated by their margins (on both
        paths: the clearance's switch, which the planar path reads too); afterwards, as they were before it."""
        before = self.clearance.margins
        self.clearance.use_margins(False)
        try:
            yield
        finally:
            self.clearance.use_margins(before)

    def uses_planar_path(self, t: float = 0.0) -> bool:
        """Whether a call at time ``t`` [s] takes the vectorised planar path."""
        possible = self._planar_kernels(t) is not None
        if self.method == "planar" and not possible:
            raise ParameterError(
                f"the planar path needs a planar robot without self pairs and sphere/capsule/box/vertical-cylinder/"
                f"halfspace obstacles straddling its plane; robot {self.robot.name!r} ({len(self._self)} self "
                f"pairs) with obstacles {list(self.scene.names)} does not qualify"
            )
        return possible and self.method != "general"

    def __call__(self, q: object, t: float = 0.0, *, exact_below: float = np.inf) -> Evaluation:
        """AMSIP of a batch ``(B, nq)`` (or one ``(nq,)``, returned with ``B = 1``) at time ``t`` [s].

        Args:
            q: the configurations.
            t: the scene's time [s].
            exact_below: the obstacle distances [m] must be exact below this (and below the potential's influence
                distance, so ``S`` never changes); above it they may be lower bounds (module docstring). Default:
                exact everywhere.

        Raises:
            ConfigurationError: a bad ``q``.
            ParameterError: ``t`` not a finite number.
        """
        Q, _ = self.robot.check_configurations(q)
        t = real_scalar(t, "t", ParameterError)
        kernels = self._planar_kernels(t) if self.method != "general" else None
        if self.method == "planar" and kernels is None:
            self.uses_planar_path(t)  # raises the explanatory error
        if kernels is not None and self._planar_arm is not None:
            return self._planar(Q, t, self._planar_arm, kernels)
        return self._general(Q, t, max(float(exact_below), self.potential.influence_distance))

    def _general(self, Q: Array, t: float, exact_below: float) -> Evaluation:
        clearance = self.clearance
        clearance.set_time(t)
        rows: list[list[float]] = []

        def fill(data: pin.Data) -> None:
            rows.append(clearance.pair_distances(data))

        screen = not math.isinf(exact_below)
        measure = fill if len(clearance.pair_links) and not screen else None
        kin = kinematics(self.robot, Q, after_each=measure, reader=self._kinematics)
        if screen and len(clearance.pair_links):
            pairs = clearance.screened(Q, kin.joint_placements[:, self._guarded_slots], exact_below)
        else:
            pairs = np.array(rows).reshape(Q.shape[0], len(clearance.pair_links))
        distances = clearance.per_link(pairs)
        amsi = amsi_from_kinematics(self.robot, kin, self.index)
        if not len(self._self):
            return self._finish(amsi, distances, kin.tip_position)
        nearest = self._self.nearest(Q, kin.joint_placements[:, self._self_slots],
                                    self.potential.self_influence_distance)
        return self._finish(amsi, distances, kin.tip_position, nearest)

    def _planar(
        self, Q: Array, t: float, arm: PlanarArm, kernels: list[planar_kernels.Kernel], chunk: int = 16384
    ) -> Evaluation:
        if Q.shape[0] <= chunk:
            return self._planar_chunk(Q, t, arm, kernels)
        parts = [self._planar_chunk(Q[s : s + chunk], t, arm, kernels) for s in range(0, Q.shape[0], chunk)]
        return Evaluation(**{f.name: np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(Evaluation)})

    def _planar_chunk(self, Q: Array, t: float, arm: PlanarArm, kernels: list[planar_kernels.Kernel]) -> Evaluation:
        chain = arm.chain
        points, trig = arm.joint_origins(Q)
        _, amsi = arm.amsi(points)
        distances = np.full((Q.shape[0], len(self.robot.guarded_links)), np.inf)
        if self.scene.obstacles:
            a, b = arm.link_segments(points, trig)
            capsule_d = np.full((Q.shape[0], len(chain.link_index)), np.inf)
            inflate = self.clearance.margins  # off within without_margins()
            for kernel, obstacle in zip(kernels, self.scene.obstacles, strict=True):
                d = planar_kernels.apply(kernel, a, b, chain.link_radii)
                if inflate and isinstance(obstacle.motion, Uncertain):  # a predicted obstacle, inflated by its margin
                    d -= margin_at(obstacle.motion, t)
                if obstacle.work_surface:
                    d[:, self._hand_slots] = np.inf  # the hand may touch the object it works on
                np.minimum(capsule_d, d, out=capsule_d)
            for slot, link in enumerate(chain.link_index):
                np.minimum(distances[:, link], capsule_d[:, slot], out=distances[:, link])
        tip = np.zeros((Q.shape[0], 3))
        tip[:, :2] = points[:, -1].T
        return self._finish(amsi, distances, tip)

    def _finish(
        self, amsi: Array, distances: Array, tip: Array, nearest: tuple[Array, NDArray[np.int64]] | None = None
    ) -> Evaluation:
        """The evaluation from the AMSI, the per-link obstacle distances, the hand and ``nearest`` = (smallest self
        distance, its pair) per configuration (``None``: no self pairs)."""
        B = len(amsi)
        self_distance, self_pair = nearest if nearest is not None else (np.full(B, np.inf), np.full(B, -1))
        S, U, collision = self.potential.apply(amsi, distances, self_distance if nearest is not None else None)
        min_distance = distances.min(axis=1) if distances.shape[1] else np.full(B, np.inf)
        return Evaluation(S, amsi, U, min_distance, distances, collision, tip, self_distance,
                          np.asarray(self_distance <= 0.0, dtype=bool), np.asarray(self_pair, dtype=np.int64))


def evaluate(
    robot: Robot,
    scene: Scene | None,
    q: object,
    t: float = 0.0,
    *,
    index: IndexParams | None = None,
    potential: Potential | None = None,
    method: Method = "auto",
) -> Evaluation:
    """AMSIP of configuration(s) ``q`` (``(nq,)`` or ``(B, nq)``) with the scene at time ``t`` [s].

    A convenience wrapper building an :class:`Evaluator`; keep an ``Evaluator`` to evaluate many
    batches in the same scene.
    """
    return Evaluator(robot, scene, index, potential, method)(q, t)
