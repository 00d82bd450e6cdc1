"""The planar redundancy map: genes (q1 .. q(n-2)) and an elbow branch, the last two joints in closed form."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from previewctl.errors import ConfigurationError
from previewctl.robot.model import Robot
from previewctl.search.redundancy import check_genes, fit_limits, parse_target, wrap_angle
from previewctl.types import Array


class PlanarRedundancy:
    """Closed-form redundancy map of a planar arm (see the module docstring).

    Args:
        robot: a planar arm (``robot.planar`` set) with at least 2 joints.
        reach_tolerance: slack [m] on the two-link annulus test (for targets exactly on its border).

    Attributes:
        gene_lower, gene_upper: ``(n - 2,)`` gene bounds [rad]: ``[-pi, pi)`` for joints that turn a full
            circle within their limits, else the joint limits.
        periodic: ``(n - 2,)`` whether each gene wraps.
        branches: 2 (elbow branches, ``beta >= 0`` and ``beta < 0``).
        link_lengths: ``(l_1, l_2)`` of the last two links [m].
    """

    branches: int = 2

    def __init__(self, robot: Robot, *, reach_tolerance: float = 1e-9) -> None:
        if robot.planar is None:
            raise ConfigurationError(f"robot {robot.name!r} is not a planar chain; use NewtonRedundancy")
        if robot.nq < 2:
            raise ConfigurationError(f"robot {robot.name!r} has {robot.nq} joint(s); the planar map needs >= 2")
        self.robot = robot
        self.chain = robot.planar
        self.n = robot.nq
        self.g = self.n - 2
        a = np.asarray(self.chain.offsets[self.n - 1], float)
        b = np.asarray(self.chain.tip_offset, float)
        self.l1, self.l2 = float(np.hypot(*a)), float(np.hypot(*b))
        if min(self.l1, self.l2) < 1e-9:
            raise ConfigurationError(
                f"robot {robot.name!r}: the last two links must have non-zero length, got {self.l1}, {self.l2} m"
            )
        self.alpha1, self.alpha2 = float(np.arctan2(a[1], a[0])), float(np.arctan2(b[1], b[0]))
        self.link_lengths = (self.l1, self.l2)
        self.reach_tolerance = float(reach_tolerance)
        self.lower, self.upper = robot.lower_limits, robot.upper_limits  # planar: q and v coincide
        self._covers_circle = bool(np.all(self.lower <= -np.pi) and np.all(self.upper >= np.pi))
        self.periodic = robot.joints.full_turn[: self.g].copy()
        self.gene_lower = np.where(self.periodic, -np.pi, self.lower[: self.g])
        self.gene_upper = np.where(self.periodic, np.pi, self.upper[: self.g])
        self.max_reach = float(np.sum(np.hypot(*self.chain.offsets[1:].T)) + self.l2)

    def wrist(self, genes: Array) -> tuple[Array, Array]:
        """Origin of joint ``n - 1`` ``(B, 2)`` [m] and the absolute angle ``theta_{n-2}`` ``(B,)`` [rad]."""
        B = genes.shape[0]
        theta = np.zeros(B)
        point = np.broadcast_to(self.chain.offsets[0], (B, 2)).copy()
        for k in range(self.g):
            theta = theta + genes[:, k]
            dx, dy = self.chain.offsets[k + 1]
            c, s = np.cos(theta), np.sin(theta)
            point[:, 0] += c * dx - s * dy
            point[:, 1] += s * dx + c * dy
        return point, theta

    def wrist_grid(self, axes: tuple[Array, ...]) -> tuple[Array, Array]:
        """:meth:`wrist` over the grid ``axes[0] x axes[1] x ...`` (up to 2 genes), with trig tables.

        Returns:
            The wrist ``(n_1, ..., n_g, 2)`` [m] and ``theta_{n-2}`` ``(n_1, ..., n_g)`` [rad]. Only the
            ``n_k`` cosines and sines of each axis are computed; the sums of angles use the addition
            formulas, which saves most of the trigonometry of a 259,200-point grid.
        """
        if len(axes) != self.g or self.g > 2:
            raise ConfigurationError(f"wrist_grid needs {self.g} axes (and at most 2 genes), got {len(axes)}")
        shape = tuple(len(a) for a in axes)
        point = np.broadcast_to(self.chain.offsets[0], (*shape, 2)).copy()
        theta = np.zeros(shape)
        c, s = np.ones(shape), np.zeros(shape)
        for k, axis in enumerate(axes):
            view = [1] * len(axes)
            view[k] = len(axis)
            ck, sk = np.cos(axis).reshape(view), np.sin(axis).reshape(view)
            c, s = c * ck - s * sk, s * ck + c * sk
            theta = theta + np.asarray(axis).reshape(view)
            dx, dy = self.chain.offsets[k + 1]
            point[..., 0] += c * dx - s * dy
            point[..., 1] += s * dx + c * dy
        return point, theta

    def two_link(self, wrist: Array, theta_w: Array, target: object) -> tuple[Array, NDArray[np.bool_]]:
        """The last two joint angles for both branches.

        Args:
            wrist: ``(..., 2)`` origins of joint ``n - 1`` [m].
            theta_w: ``(...)`` absolute angle ``theta_{n-2}`` of the link before it [rad].
            target: hand position.

        Returns:
            ``(branches, ..., 2)`` angles ``(q_{n-1}, q_n)`` [rad], wrapped to ``[-pi, pi)`` (not yet fitted
            to the joint limits), and ``reachable`` ``(...)`` (the annulus test and the target's z).
        """
        goal = parse_target(target, self.robot)
        dx, dy = goal.position[0] - wrist[..., 0], goal.position[1] - wrist[..., 1]
        dist = np.hypot(dx, dy)
        l1, l2 = self.l1, self.l2
        reachable = (dist <= l1 + l2 + self.reach_tolerance) & (dist >= abs(l1 - l2) - self.reach_tolerance)
        reachable &= abs(goal.position[2]) <= self.reach_tolerance
        cos_beta = np.clip((dist * dist - (l1 * l1 + l2 * l2)) / (2.0 * l1 * l2), -1.0, 1.0)
        beta = np.arccos(cos_beta)
        gamma = np.arctan2(l2 * np.sqrt(1.0 - cos_beta * cos_beta), l1 + l2 * cos_beta)
        base = np.arctan2(dy, dx) - self.alpha1 - theta_w
        out = np.empty((2, *dist.shape, 2))
        out[0, ..., 0], out[1, ..., 0] = base - gamma, base + gamma
        out[0, ..., 1], out[1, ..., 1] = beta, -beta
        out[..., 1] += self.alpha1 - self.alpha2
        return wrap_angle(out), reachable

    def _finish(self, Q: Array, reachable: NDArray[np.bool_]) -> tuple[Array, NDArray[np.bool_]]:
        if self._covers_circle:
            return Q, reachable
        Q, within = fit_limits(Q, self.lower, self.upper)
        return Q, reachable & within

    def solve(
        self, genes: Array, branch: NDArray[np.int_], target: object, q_seed: Array | None = None
    ) -> tuple[Array, NDArray[np.bool_]]:
        """Configurations for genes ``(B, n - 2)`` [rad] and elbow branches ``(B,)`` in {0, 1}.

        Args:
            genes: the first ``n - 2`` joint angles [rad].
            branch: 0 (``beta >= 0``) or 1 (``beta < 0``), broadcast to ``(B,)``.
            target: hand position ``(2,)`` [m] (or ``(3,)`` with ``z = 0``: another z is unreachable).
            q_seed: ignored (the map is closed form).

        Returns:
            ``Q`` ``(B, n)`` [rad] wrapped to ``[-pi, pi)`` (or shifted by 2 pi into the limits) and
            ``reachable`` ``(B,)``.
        """
        del q_seed
        G, br = check_genes(genes, branch, self.g, self.branches)
        w, theta_w = self.wrist(G)
        last, reachable = self.two_link(w, theta_w, target)
        Q = np.empty((G.shape[0], self.n))
        Q[:, : self.g] = wrap_angle(G)
        Q[:, self.g :] = np.where((br == 0)[:, None], last[0], last[1])
        return self._finish(Q, reachable)

    def solve_grid(self, axes: tuple[Array, ...], target: object) -> tuple[Array, NDArray[np.bool_]]:
        """:meth:`solve` over every branch and the grid of gene ``axes`` (at most 2 genes).

        Returns:
            ``Q`` ``(branches * n_1 * ... * n_g, n)`` in branch-major then C order of the axes, and
            ``reachable`` of the same length; equal to :meth:`solve` on the same candidates.
        """
        w, theta_w = self.wrist_grid(axes)
        last, reachable = self.two_link(w, theta_w, target)
        cells = int(np.prod([len(a) for a in axes]))
        Q = np.empty((2, cells, self.n))
        if self.g:
            mesh = np.meshgrid(*axes, indexing="ij")
            for k in range(self.g):
                Q[:, :, k] = wrap_angle(mesh[k].ravel())
        Q[:, :, self.g :] = last.reshape(2, cells, 2)
        return self._finish(Q.reshape(2 * cells, self.n), np.tile(reachable.ravel(), 2))

    def genes_of(self, Q: Array) -> tuple[Array, NDArray[np.int_]]:
        """Genes (the first ``n - 2`` angles, wrapped to ``[-pi, pi)``) and branch of ``(B, n)`` configurations."""
        Qb, _ = self.robot.check_configurations(Q)
        beta = wrap_angle(Qb[:, self.g + 1] + self.alpha2 - self.alpha1)
        genes = Qb[:, : self.g]
        genes = np.where(self.periodic, wrap_angle(genes), genes)
        return genes, (beta < 0).astype(int)
