"""The loaded arm: a reduced Pinocchio model with its task, control points, guarded links, self pairs and joint
facts."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from previewctl.errors import ConfigurationError
from previewctl.robot.joints import JointFacts
from previewctl.robot.planar import PlanarChain
from previewctl.robot.self_pairs import SelfPairs

Task = Literal["planar", "position", "pose"]
Geometry = Literal["convex", "capsules", "mesh"]
GEOMETRY_CHOICES: tuple[Geometry, ...] = ("convex", "capsules", "mesh")
TASK_ROWS: dict[str, slice] = {"planar": slice(0, 2), "position": slice(0, 3), "pose": slice(0, 6)}
MAX_COORDINATE = 1e6
"""Largest ``|q|`` entry accepted [rad or m]: beyond it angles lose their precision and positions overflow."""
UNIT_PAIR_TOLERANCE = 1e-6
"""How far from 1 the norm of a continuous joint's (cos, sin) pair may be."""


@dataclass(frozen=True, eq=False)
class Robot:
    """A loaded arm. Build it with :func:`load_robot`.

    Attributes:
        name: the source it was loaded from.
        model: the (reduced) Pinocchio model; ``q`` has ``model.nq`` entries.
        collision_model: the arm's collision geometry (after the ``geometry`` choice).
        tip_frame: the hand frame whose position (or pose) is the task.
        task: ``"planar"``, ``"position"`` or ``"pose"``.
        control_points: joint-frame names whose origins are the avoidance control points.
        guarded_links: body names whose geometry counts for clearance and collision.
        structural_ranks: generic rank of each control point's avoidance matrix ``M_i``.
        planar: the closed-form chain when the arm is planar, else ``None``.
        self_pairs: the pairs of its own links checked against each other (link names, the self geometry in the
            robot's geometry choice, where they come from; :mod:`previewctl.robot.self_pairs`). Empty by default.
        joints: the per-coordinate joint facts of ``model`` (full turns, limits, index maps), computed
            once here; every joint rule reads them.
    """

    name: str
    model: pin.Model
    collision_model: pin.GeometryModel
    tip_frame: str
    task: Task
    control_points: tuple[str, ...]
    guarded_links: tuple[str, ...]
    structural_ranks: tuple[int, ...]
    planar: PlanarChain | None
    self_pairs: SelfPairs = field(default_factory=SelfPairs)
    joints: JointFacts = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "joints", JointFacts.of(self.model))

    @property
    def nq(self) -> int:
        """Number of configuration entries."""
        return int(self.model.nq)

    @property
    def nv(self) -> int:
        """Number of joint velocities (degrees of freedom)."""
        return int(self.model.nv)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of the movable joints, in ``q`` order."""
        return tuple(self.model.names[1:])

    @property
    def frame_names(self) -> tuple[str, ...]:
        """Names of every frame of the model."""
        return tuple(f.name for f in self.model.frames)

    @property
    def hand_links(self) -> tuple[str, ...]:
        """Guarded links that move with the hand (their geometry hangs on the tip frame's joint)."""
        joint = self.model.frames[self.tip_frame_id].parentJoint
        return tuple(dict.fromkeys(str(self.model.frames[g.parentFrame].name)
                                   for g in self.collision_model.geometryObjects if g.parentJoint == joint))

    @cached_property
    def tip_frame_id(self) -> int:
        """Pinocchio id of the tip frame (looked up once: a control cycle reads it several times)."""
        return int(self.model.getFrameId(self.tip_frame))

    @property
    def control_frame_ids(self) -> tuple[int, ...]:
        """Pinocchio ids of the control-point frames."""
        return tuple(int(self.model.getFrameId(n)) for n in self.control_points)

    @property
    def task_rows(self) -> slice:
        """Rows of the 6-D frame Jacobian that make the task Jacobian ``J_n``."""
        return TASK_ROWS[self.task]

    @property
    def point_rows(self) -> slice:
        """Rows of the frame Jacobian that make a control-point Jacobian ``J_i``."""
        return TASK_ROWS["planar"] if self.task == "planar" else TASK_ROWS["position"]

    @property
    def lower_limits(self) -> NDArray[np.float64]:
        """Lower joint position limits [rad or m], shape ``(nq,)``."""
        return np.array(self.model.lowerPositionLimit, dtype=float)

    @property
    def upper_limits(self) -> NDArray[np.float64]:
        """Upper joint position limits [rad or m], shape ``(nq,)``."""
        return np.array(self.model.upperPositionLimit, dtype=float)

    @property
    def velocity_limits(self) -> NDArray[np.float64]:
        """Joint speed limits [rad/s or m/s], shape ``(nv,)`` (a fresh copy of ``joints.velocity``)."""
        return self.joints.velocity.copy()

    def neutral(self) -> NDArray[np.float64]:
        """The model's neutral configuration, shape ``(nq,)``."""
        return np.array(pin.neutral(self.model), dtype=float)

    def random_configurations(self, rng: np.random.Generator, count: int) -> NDArray[np.float64]:
        """``count`` configurations drawn uniformly within the joint limits, shape ``(count, nq)``."""
        lo, hi = self._finite_limits()
        return self.configurations_from_angles(rng.uniform(lo, hi, size=(count, self.nv)))

    def configuration_from_angles(self, angles: NDArray[np.float64]) -> NDArray[np.float64]:
        """Map one vector of ``nv`` joint coordinates [rad or m] to a configuration ``(nq,)``.

        Identical for ordinary joints; a continuous joint becomes its (cos, sin) pair.
        """
        return np.asarray(pin.integrate(self.model, pin.neutral(self.model), np.asarray(angles, float)))

    def configurations_from_angles(self, angles: NDArray[np.float64]) -> NDArray[np.float64]:
        """:meth:`configuration_from_angles` of each row of ``(B, nv)`` [rad or m]: ``(B, nq)`` (a fresh array)."""
        rows = np.array(angles, dtype=float)
        if self.nq == self.nv:
            return rows
        return np.stack([self.configuration_from_angles(a) for a in rows])

    def angles_of(self, Q: NDArray[np.float64]) -> NDArray[np.float64]:
        """Joint coordinates ``(B, nv)`` [rad or m] of configurations ``(B, nq)``, the inverse of
        :meth:`configurations_from_angles` (a continuous joint's angle in ``[-pi, pi]``)."""
        if self.nq == self.nv:
            return np.array(Q, dtype=float)
        neutral = pin.neutral(self.model)
        return np.stack([pin.difference(self.model, neutral, q) for q in Q])

    def _finite_limits(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Per-velocity-coordinate limits [rad or m] with missing (infinite) ones replaced by +-pi, and none
        beyond :data:`MAX_COORDINATE`."""
        lower, upper = self.joints.lower, self.joints.upper
        lower, upper = np.where(np.isfinite(lower), lower, -np.pi), np.where(np.isfinite(upper), upper, np.pi)
        return np.maximum(lower, -MAX_COORDINATE), np.minimum(upper, MAX_COORDINATE)

    def check_configurations(self, q: object) -> tuple[NDArray[np.float64], bool]:
        """Validate ``q`` of shape ``(nq,)`` or ``(B, nq)``.

        Returns:
            A fresh ``(B, nq)`` float array and whether the input was a single configuration.

        Raises:
            ConfigurationError: wrong shape, a non-finite entry, an entry beyond :data:`MAX_COORDINATE`, or a
                continuous joint's (cos, sin) pair off the unit circle (:data:`UNIT_PAIR_TOLERANCE`).
        """
        try:
            arr = np.array(q, dtype=float)
        except (TypeError, ValueError) as exc:
            raise ConfigurationError(f"q must be numbers, got {q!r}") from exc
        single = arr.ndim == 1
        batch = arr[None, :] if single else arr
        if batch.ndim != 2 or batch.shape[1] != self.nq:
            raise ConfigurationError(
                f"q has shape {arr.shape}; robot {self.name!r} needs ({self.nq},) or (B, {self.nq}) "
                f"for joints {', '.join(self.joint_names)}"
            )
        if not (np.abs(batch) <= MAX_COORDINATE).all():  # one test for both (false for a NaN); then which it is
            self._refuse_entry(batch)
        pairs = self.joints.unit_pairs
        if pairs.size:
            norms = np.hypot(batch[:, pairs[:, 0]], batch[:, pairs[:, 1]])
            off = np.abs(norms - 1.0) > UNIT_PAIR_TOLERANCE
            if off.any():
                row, k = np.argwhere(off)[0]
                c, s = pairs[k]
                raise ConfigurationError(
                    f"q[{row}, {c}:{s + 1}] = ({batch[row, c]:g}, {batch[row, s]:g}) of continuous joint "
                    f"{self.joint_names_by_q()[c]!r} must be a (cos, sin) pair: cos^2 + sin^2 = 1 to "
                    f"{UNIT_PAIR_TOLERANCE:g}, got norm {norms[row, k]:.6g}"
                )
        return batch, single

    def _refuse_entry(self, batch: NDArray[np.float64]) -> None:
        """The :class:`ConfigurationError` of :meth:`check_configurations` for ``batch``'s first non-finite entry, or
        else its first entry beyond :data:`MAX_COORDINATE`."""
        bad = ~np.isfinite(batch)
        if bad.any():
            row, col = np.argwhere(bad)[0]
            raise ConfigurationError(
                f"q[{row}, {col}] = {batch[row, col]} (joint {self.joint_names_by_q()[col]!r}) is not finite"
            )
        row, col = np.argwhere(np.abs(batch) > MAX_COORDINATE)[0]
        raise ConfigurationError(f"q[{row}, {col}] = {batch[row, col]:g} (joint {self.joint_names_by_q()[col]!r}) "
                                 f"is out of range; valid: |q| <= {MAX_COORDINATE:g} [rad or m]")

    def check_limits(self, q: NDArray[np.float64]) -> None:
        """Raise :class:`ConfigurationError` naming the first joint of ``q`` ``(nq,)`` outside its position
        limits (to 1e-9; continuous joints have none)."""
        coordinates = self.angles_of(np.asarray(q, dtype=float)[None])[0]
        lower, upper = self.joints.lower, self.joints.upper
        outside = np.flatnonzero((coordinates < lower - 1e-9) | (coordinates > upper + 1e-9))
        if outside.size:
            i = int(outside[0])
            name = self.model.names[int(self.joints.q_joint[self.joints.q_index[i]])]
            raise ConfigurationError(f"joint {name!r} = {coordinates[i]:.6g} is outside its limits; valid: "
                                     f"[{lower[i]:.6g}, {upper[i]:.6g}] [rad or m]")

    def joint_names_by_q(self) -> tuple[str, ...]:
        """For each configuration entry, the name of the joint it belongs to."""
        return tuple(str(self.model.names[int(j)]) for j in self.joints.q_joint)
