"""The gene space shared by exploration and the GA: Halton samples, periodic genes, distinct peaks, candidates."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from previewctl.errors import ConfigurationError, UnreachableTargetError
from previewctl.robot.model import Robot
from previewctl.search.planar import PlanarRedundancy
from previewctl.search.redundancy import RedundancyMap, parse_target, wrap_angle
from previewctl.types import Array


@dataclass(frozen=True)
class Candidate:
    """One point of the redundancy space, solved and scored.

    Attributes:
        genes: ``(g,)`` the map's genes of ``q`` [rad] (``genes_of(q)``; periodic genes wrapped to
            ``[-pi, pi)``), so that ``solve(genes, branch)`` returns ``q``.
        branch: the discrete branch (planar elbow: 0 for ``q_n >= 0``, 1 for ``q_n < 0``).
        q: ``(nq,)`` configuration [rad].
        S: AMSIP (``collision_value`` < 0 when colliding or unreachable).
    """

    genes: Array
    branch: int
    q: Array
    S: float


_PRIMES = (2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53, 59, 61, 67, 71, 73, 79, 83, 89, 97)


# ---------------------------------------------------------------------------------- utilities


def halton(count: int, dim: int, rng: np.random.Generator | None = None) -> Array:
    """``count`` points of the ``dim``-dimensional Halton sequence in ``[0, 1)^dim``.

    With ``rng`` the sequence gets a random shift modulo 1 (Cranley-Patterson rotation), which keeps
    its low discrepancy and makes independent replicas.
    """
    if dim > len(_PRIMES):
        raise ConfigurationError(f"halton supports up to {len(_PRIMES)} dimensions, got {dim}")
    index = np.arange(1, count + 1)
    out = np.zeros((count, dim))
    for k in range(dim):
        base, i, f = _PRIMES[k], index.copy(), np.ones(count)
        while np.any(i > 0):
            f /= base
            out[:, k] += f * (i % base)
            i //= base
    if rng is not None:
        out = (out + rng.random(dim)) % 1.0
    return out


def joint_distance(A: Array, B: Array, periodic: NDArray[np.bool_]) -> Array:
    """Distances ``(a, b)`` [rad] between joint-angle vectors ``A (a, nv)`` and ``B (b, nv)``
    (``periodic``: the coordinates compared modulo ``2 pi``, e.g. ``robot.joints.full_turn``)."""
    diff = A[:, None, :] - B[None, :, :]
    diff = np.where(periodic, wrap_angle(diff), diff)
    return np.sqrt(np.add.reduce(diff * diff, axis=-1))


def distinct(angles: Array, periodic: NDArray[np.bool_], radius: float, k: int, block: int = 256) -> list[int]:
    """Greedy: walk the rows of ``angles`` in order and keep those at least ``radius`` [rad] away from
    every kept one (up to ``k``).

    The rows are taken in blocks (most walks end in the first one); each kept row suppresses its
    neighbours in the block with one vectorised distance computation.
    """
    kept: list[int] = []
    for start in range(0, angles.shape[0], block):
        rows = angles[start : start + block]
        alive = np.ones(rows.shape[0], dtype=bool)
        if kept:
            alive = joint_distance(rows, angles[kept], periodic).min(axis=1) >= radius
        while len(kept) < k:
            first = int(alive.argmax())
            if not alive[first]:
                break
            kept.append(start + first)
            alive &= joint_distance(rows[first : first + 1], rows, periodic)[0] >= radius
            alive[first] = False
        if len(kept) == k:
            break
    return kept


def gene_periodic(redundancy: RedundancyMap) -> NDArray[np.bool_]:
    """The map's ``periodic`` flags; all ``False`` for a map that does not declare them."""
    g = int(np.asarray(redundancy.gene_lower).size)
    return np.asarray(getattr(redundancy, "periodic", np.zeros(g, dtype=bool)), dtype=bool).reshape(g)


def candidates(
    genes: Array, branch: NDArray[np.int_], Q: Array, S: Array, rows: list[int], periodic: NDArray[np.bool_]
) -> list[Candidate]:
    """The individuals ``rows`` of a population as candidates (periodic genes wrapped)."""
    chosen = genes[rows]
    chosen = np.where(periodic, wrap_angle(chosen), chosen)
    return [Candidate(chosen[j], int(branch[i]), Q[i].copy(), float(S[i])) for j, i in enumerate(rows)]


def check_positive_int(name: str, value: object, minimum: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ConfigurationError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def reach_check(redundancy: RedundancyMap, target: object, robot: Robot) -> None:
    """Raise :class:`UnreachableTargetError` for a planar target beyond the arm's total reach."""
    if isinstance(redundancy, PlanarRedundancy):
        goal = parse_target(target, robot)
        base = np.asarray(redundancy.chain.offsets[0])
        dist = float(np.hypot(*(goal.position[:2] - base)))
        if dist > redundancy.max_reach + redundancy.reach_tolerance or abs(goal.position[2]) > 1e-9:
            raise UnreachableTargetError(
                f"target {np.round(goal.position, 4).tolist()} [m] is out of reach of robot {robot.name!r}: "
                f"{dist:.4f} m from the base, reach {redundancy.max_reach:.4f} m (in the plane z = 0)"
            )
