"""Global exploration (the paper's Table 3): a dense grid or Halton samples over the redundancy space."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from previewctl.errors import ConfigurationError, UnreachableTargetError
from previewctl.index.evaluator import Evaluator
from previewctl.robot.joints import FULL_TURN
from previewctl.robot.model import Robot
from previewctl.search.genes import (
    Candidate,
    check_positive_int,
    distinct,
    gene_periodic,
    halton,
    joint_distance,
    reach_check,
)
from previewctl.search.maps import redundancy_map
from previewctl.search.planar import PlanarRedundancy
from previewctl.search.redundancy import RedundancyMap, parse_target
from previewctl.search.scoring import Scored, score, score_configurations
from previewctl.types import Array


@dataclass(frozen=True)
class Landscape:
    """AMSIP over the redundancy space of one hand target at one time.

    Attributes:
        target: ``(3,)`` hand position [m] (z = 0 for a planar target).
        t: time [s] at which the obstacles were placed.
        method: ``"grid"`` or ``"samples"``.
        axes: the grid axes, one ``(n_k,)`` array [rad] per gene (``()`` for samples).
        S_map: ``(branches, n_1, ..., n_g)`` AMSIP on the grid (``None`` for samples).
        genes: ``(N, g)`` every candidate's genes [rad]. Grid: the axis values (periodic ones in
            ``[0, 2 pi)``), branch-major order, then the gene axes in C order. Samples: where reachable,
            the genes of the solved configuration (``genes_of(q)``), else the sampled genes.
        branch: ``(N,)`` their branches.
        S: ``(N,)`` their AMSIP.
        reachable: ``(N,)`` whether the hand reaches the target.
        best: the candidate of largest S.
        peaks: up to ``top_k`` distinct local maxima with ``S > 0``, best first.
    """

    target: Array
    t: float
    method: str
    axes: tuple[Array, ...]
    S_map: Array | None
    genes: Array
    branch: NDArray[np.int_]
    S: Array
    reachable: NDArray[np.bool_]
    best: Candidate
    peaks: tuple[Candidate, ...]


# ----------------------------------------------------------------------------------- explore


def _grid_axes(redundancy: RedundancyMap, resolution: float) -> tuple[Array, ...]:
    axes: list[Array] = []
    periodic = gene_periodic(redundancy)
    for lo, hi, per in zip(redundancy.gene_lower, redundancy.gene_upper, periodic, strict=True):
        if per:
            count = max(1, round(FULL_TURN / resolution))
            axes.append(np.arange(count, dtype=np.float64) * (FULL_TURN / count))
        else:
            count = max(1, int(np.floor((hi - lo) / resolution + 1e-9)) + 1)
            axes.append(lo + np.arange(count) * resolution)
    return tuple(axes)


def _grid_maxima(S_map: Array, periodic: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Cells of ``S_map (branches, n_1, ..., n_g)`` not below any of their (3^g - 1) grid neighbours."""
    g = S_map.ndim - 1
    is_max = S_map > 0
    for offset in np.ndindex(*(3,) * g):
        shift = tuple(o - 1 for o in offset)
        if not any(shift):
            continue
        neighbour = S_map
        for axis, (s, per) in enumerate(zip(shift, periodic, strict=True), start=1):
            if s == 0:
                continue
            neighbour = np.roll(neighbour, -s, axis=axis)
            if not per:  # no wrap: the rolled-in edge has no neighbour
                edge = [slice(None)] * S_map.ndim
                edge[axis] = slice(-1, None) if s > 0 else slice(0, 1)
                neighbour = neighbour.copy()
                neighbour[tuple(edge)] = -np.inf
        is_max &= S_map >= neighbour
    return is_max


MAX_CANDIDATES = 2**21
"""Most candidates (grid cells or samples, times the branches) one exploration scores: a 0.36 deg grid of a
two-gene map with two branches, or 2,097,152 samples (memory and time stay within a workstation's)."""


def explore(
    robot: Robot,
    evaluator: Evaluator,
    target: object,
    t: float = 0.0,
    *,
    resolution_deg: float = 1.0,
    samples: int | None = None,
    top_k: int = 4,
    rng: np.random.Generator | None = None,
    redundancy: RedundancyMap | None = None,
    min_separation: float = 0.35,
) -> Landscape:
    """Global exploration of AMSIP over the redundancy space of ``target`` at time ``t`` [s].

    Args:
        robot: the arm.
        evaluator: AMSIP evaluator (robot, scene, index, potential).
        target: hand target (see :func:`previewctl.search.redundancy.parse_target`).
        t: time [s] at which the obstacles are placed.
        resolution_deg: grid step [deg] (maps with 1 or 2 genes).
        samples: number of Halton samples of the genes for maps with more genes (default: 65,536 for the
            vectorised planar map, 1,024 for the Newton map); ignored on a grid.
        top_k: the most peaks to report.
        rng: random shift of the Halton sequence (``None``: unshifted, deterministic).
        redundancy: the map (default :func:`~previewctl.search.maps.redundancy_map`).
        min_separation: least joint-space distance [rad] between two reported peaks.

    Returns:
        The landscape. On a grid, a peak is a cell not below any of its 8 neighbours (periodic genes
        wrap around), then the peaks are taken best first, each at least ``min_separation`` from the
        ones kept. With samples, a peak is a sample with no better sample within ``min_separation``.

    Raises:
        UnreachableTargetError: no candidate puts the hand on the target.
        ConfigurationError: a bad option or target, or more than :data:`MAX_CANDIDATES` candidates.
    """
    top_k = _check_options(resolution_deg, top_k, min_separation)
    if samples is not None:
        check_positive_int("samples", samples)  # also on a grid, which does not use it: a typo is still a typo
    red = redundancy if redundancy is not None else redundancy_map(robot)
    goal = parse_target(target, robot)
    reach_check(red, target, robot)
    if int(np.asarray(red.gene_lower).size) <= 2:
        design = _grid_design(red, np.radians(resolution_deg))
    else:
        design = _sample_design(red, samples, rng)
    scored, genes, branch = _score_design(evaluator, red, design, target, t)
    if not scored.reachable.any():
        raise UnreachableTargetError(
            f"target {np.round(goal.position, 4).tolist()} [m]: none of {genes.shape[0]} candidates of robot "
            f"{robot.name!r} reaches it"
        )
    S = scored.S
    best = _candidate(red, scored, int(np.argmax(np.where(scored.reachable, S, -np.inf))))
    S_map: Array | None = None
    if design.method == "grid":
        S_map = S.reshape((int(red.branches), *(len(a) for a in design.axes)))
        kept = _grid_peaks(robot, gene_periodic(red), scored, S_map, min_separation, top_k)
    else:
        kept = _sample_peaks(robot, scored, min_separation, top_k)
    peaks = tuple(_candidate(red, scored, i) for i in kept)
    return Landscape(
        goal.position, float(t), design.method, design.axes, S_map, genes, branch, S, scored.reachable, best, peaks
    )


# ----------------------------------------------------------------------------- explore's steps


def _check_options(resolution_deg: float, top_k: int, min_separation: float) -> int:
    """Validate :func:`explore`'s options; ``top_k`` as an int."""
    if not (np.isfinite(resolution_deg) and 0 < resolution_deg <= 90):
        raise ConfigurationError(f"resolution_deg must lie in (0, 90] [deg], got {resolution_deg!r}")
    checked = check_positive_int("top_k", top_k)
    if not (np.isfinite(min_separation) and min_separation >= 0):
        raise ConfigurationError(f"min_separation must be >= 0 [rad], got {min_separation!r}")
    return checked


@dataclass(frozen=True)
class _Design:
    """The candidates to score: every branch of a grid over the genes, or of Halton samples.

    Attributes:
        method: ``"grid"`` or ``"samples"``.
        axes: the grid axes [rad] (``()`` for samples).
        genes: ``(N, g)`` [rad], branch-major.
        branch: ``(N,)``.
    """

    method: str
    axes: tuple[Array, ...]
    genes: Array
    branch: NDArray[np.int_]


def _grid_design(red: RedundancyMap, resolution: float) -> _Design:
    """Every cell of the grid of step ``resolution`` [rad] (a map with at most 2 genes), every branch."""
    g, branches = int(np.asarray(red.gene_lower).size), int(red.branches)
    axes = _grid_axes(red, resolution)
    count = branches * int(np.prod([len(a) for a in axes]))
    if count > MAX_CANDIDATES:
        per_axis = (MAX_CANDIDATES / branches) ** (1 / max(g, 1))
        span = float(np.max(np.asarray(red.gene_upper) - np.asarray(red.gene_lower)))
        finest = 1.02 * float(np.degrees(span / per_axis))  # rounded up below
        raise ConfigurationError(f"resolution_deg = {np.degrees(resolution):g} makes {count:,} candidates, more than "
                                 f"{MAX_CANDIDATES:,}; use resolution_deg >= {finest:.2g}")
    mesh = np.meshgrid(*axes, indexing="ij") if g else []
    one = np.stack([m.ravel() for m in mesh], axis=1) if g else np.zeros((1, 0))
    return _Design("grid", axes, np.tile(one, (branches, 1)), np.repeat(np.arange(branches), one.shape[0]))


def _sample_design(red: RedundancyMap, samples: int | None, rng: np.random.Generator | None) -> _Design:
    """``samples`` Halton points within the gene bounds (default: see :func:`explore`), every branch."""
    g, branches = int(np.asarray(red.gene_lower).size), int(red.branches)
    count = samples if samples is not None else (65536 if isinstance(red, PlanarRedundancy) else 1024)
    count = check_positive_int("samples", count)
    if count * branches > MAX_CANDIDATES:
        raise ConfigurationError(f"samples = {count:,} makes {count * branches:,} candidates ({branches} branches), "
                                 f"more than {MAX_CANDIDATES:,}; use samples <= {MAX_CANDIDATES // branches:,}")
    one = red.gene_lower + halton(count, g, rng) * (red.gene_upper - red.gene_lower)
    return _Design("samples", (), np.tile(one, (branches, 1)), np.repeat(np.arange(branches), count))


def _score_design(
    evaluator: Evaluator, red: RedundancyMap, design: _Design, target: object, t: float
) -> tuple[Scored, Array, NDArray[np.int_]]:
    """Score the design; with samples, the genes and branches of the reachable ones become those of
    their solved configurations (the sampled genes moved onto the manifold; identity for a closed form)."""
    genes, branch = design.genes, design.branch
    if design.method == "grid" and isinstance(red, PlanarRedundancy):
        return score_configurations(evaluator, *red.solve_grid(design.axes, target), t), genes, branch
    scored = score(evaluator, red, genes, branch, target, t)
    if design.method == "samples" and scored.reachable.any():
        genes = genes.copy()
        genes[scored.reachable], branch[scored.reachable] = red.genes_of(scored.Q[scored.reachable])
    return scored, genes, branch


def _candidate(red: RedundancyMap, scored: Scored, i: int) -> Candidate:
    """Row ``i`` as a candidate, with the map's genes of the solved configuration (for the Newton map:
    the projected genes)."""
    solved, solved_branch = red.genes_of(scored.Q[i : i + 1])
    return Candidate(solved[0], int(solved_branch[0]), scored.Q[i].copy(), float(scored.S[i]))


def _grid_peaks(
    robot: Robot, gene_wraps: NDArray[np.bool_], scored: Scored, S_map: Array, min_separation: float, top_k: int
) -> list[int]:
    """Rows of the grid's local maxima, best first, each ``min_separation`` [rad] from those kept."""
    S = scored.S
    maxima = np.flatnonzero(_grid_maxima(S_map, gene_wraps).ravel())
    order = maxima[np.argsort(-S[maxima], kind="stable")]
    picked = distinct(robot.angles_of(scored.Q[order]), robot.joints.full_turn, min_separation, top_k)
    return [int(order[k]) for k in picked]


def _sample_peaks(robot: Robot, scored: Scored, min_separation: float, top_k: int) -> list[int]:
    """Rows of samples with ``S > 0`` and no better sample within ``min_separation`` [rad], best first
    (among the best 5,000)."""
    S, periodic = scored.S, robot.joints.full_turn
    valid = np.flatnonzero(S > 0)
    order = valid[np.argsort(-S[valid], kind="stable")][:5000]
    angles = robot.angles_of(scored.Q[order])
    kept: list[int] = []
    for rank in range(order.size):
        if len(kept) >= top_k:
            break
        if rank == 0 or joint_distance(angles[rank : rank + 1], angles[:rank], periodic).min() >= min_separation:
            kept.append(int(order[rank]))
    return kept
