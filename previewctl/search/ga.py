"""Search of the redundancy space: global exploration (paper Table 3) and the 1-step GA (section 6).

* :func:`explore` evaluates AMSIP over the whole redundancy space of a hand target. For a map with one
  or two genes (planar4: ``q1, q2``) it is a dense grid, by default 1 deg over ``[0, 360)`` per
  periodic gene, times every branch (planar4: 360 x 360 x 2 = 259,200 candidates), solved and
  evaluated in one vectorised batch. Otherwise (more genes, e.g. the Newton map of a spatial arm) it
  evaluates a randomly shifted Halton sequence of the genes. Unreachable candidates score
  ``collision_value`` (< 0) and are not evaluated.
* :class:`OneStepGA` runs one generation per call (one camera frame); its population persists between
  calls, so it tracks the optimum while the target and the obstacles move.

Peaks (distinct local maxima of S, the paper's Fig. 8) are reported by both. Distinctness is measured
in joint space: the Euclidean norm of the joint-angle difference [rad], angles of full-turn joints
compared modulo 2 pi.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Annotated, Any

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from previewctl.errors import ConfigurationError, ParameterError
from previewctl.index.evaluator import Evaluator
from previewctl.robot.model import Robot
from previewctl.search.genes import (
    Candidate,
    candidates,
    distinct,
    gene_periodic,
    halton,
)
from previewctl.search.newton import NewtonRedundancy
from previewctl.search.planar import PlanarRedundancy
from previewctl.search.redundancy import RedundancyMap, wrap_angle
from previewctl.search.scoring import Scored, score, score_configurations
from previewctl.types import Array
from previewctl.validation import Checked, Count, Finite, Integer, NonNegative, Probability, build, interval

# ------------------------------------------------------------------------------------- 1-step GA

MAX_POPULATION = 10_000
"""Most individuals per generation: each frame scores ``population`` configurations per imaginary arm, so
10 000 already takes seconds of a 33 ms frame (the default is 64)."""
Population = Annotated[Integer, Field(ge=4, le=MAX_POPULATION)]
"""Individuals per generation (at least 4: an elite, a peak and two parents; at most :data:`MAX_POPULATION`)."""


@dataclass(frozen=True)
class GAOptions(Checked):
    """Settings of the 1-step GA (:class:`OneStepGA` describes the operators).

    Attributes:
        population: individuals per generation.
        elite: individuals copied unchanged.
        mutation_scale: largest Gaussian mutation standard deviation [rad].
        top_k: peaks kept.
        niche_radius: least joint-space distance [rad] between two peaks.
        immigrants: fraction of random individuals per generation, in [0, 0.5].
        tournament: tournament size.
        crossover_rate: probability of crossover.
        blend: BLX ``alpha``.
        branch_flip: probability of a branch flip.
    """

    population: Population = 64
    elite: Count = 2
    mutation_scale: NonNegative = 0.25
    top_k: Count = 4
    niche_radius: NonNegative = 0.35
    immigrants: Annotated[Finite, interval(0, 0.5)] = 0.1
    tournament: Count = 2
    crossover_rate: Probability = 0.9
    blend: NonNegative = 0.5
    branch_flip: Probability = 0.1

    def check(self) -> None:
        """The elite and the peaks leave room for children: ``elite + top_k < population``."""
        if self.elite + self.top_k >= self.population:
            raise ParameterError(
                f"elite + top_k must be below population: {self.elite} + {self.top_k} >= {self.population}"
            )



class OneStepGA:
    """The 1-step genetic algorithm: one generation per call, the population kept between calls.

    Each :meth:`step` breeds a new population from the previous one (whose fitness was measured at the
    previous call), then evaluates the *whole* new population at the current target and time, so the
    survivors are always judged against the current frame. Operators:

    * elitism: the ``elite`` best individuals are copied unchanged; so are the stored peaks (below),
      which keeps several distinct optima alive;
    * immigrants: a fraction ``immigrants`` of fresh random individuals (new peaks can be found when an
      obstacle moves);
    * selection: tournaments of ``tournament`` individuals on S;
    * crossover (probability ``crossover_rate``): blend crossover BLX-``blend`` per gene,
      ``child = a + u (b - a)`` with ``u ~ U(-blend, 1 + blend)``; for periodic genes the difference is
      taken on the circle (``wrap(b - a)``) and the child wrapped to ``[-pi, pi)``; bounded genes are
      reflected into their bounds; the branch comes from a random parent;
    * mutation: Gaussian on every gene with a per-child scale ``mutation_scale * 2^-u``,
      ``u ~ U(0, 5)`` (log-uniform: large exploring jumps and fine local steps in each generation),
      and a branch flip with probability ``branch_flip``;
    * Lamarckian repair: a reachable individual's genes are replaced by the genes of its solved
      configuration (a no-op for the planar map; for the Newton map, the next frame's projection starts
      on the manifold and converges in a step or two);
    * niching: after evaluation, the top ``top_k`` individuals at least ``niche_radius`` apart in
      joint space are the peaks (:meth:`peaks`); they are re-injected as elites next generation.

    Args:
        robot: the arm.
        evaluator: AMSIP evaluator.
        redundancy: the redundancy map.
        rng: the only source of randomness (seed it for reproducible runs).
        options: :class:`GAOptions` fields to change from their defaults, e.g. ``population=16``.

    Raises:
        ParameterError: ``rng`` is not a generator, or an unknown or bad option.

    Attributes:
        branch_lock: ``None`` (search every branch, the default) or one branch: every individual of the
            next generations is bred on that branch (coherent preview keeps an imaginary arm on the
            real arm's elbow branch). Setting it draws no random numbers, so a GA with ``None`` behaves
            exactly as before.
    """

    def __init__(
        self,
        robot: Robot,
        evaluator: Evaluator,
        redundancy: RedundancyMap,
        rng: np.random.Generator,
        **options: Any,
    ) -> None:
        if not isinstance(rng, np.random.Generator):
            raise ParameterError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        self.options = o = build(GAOptions, options, ParameterError)
        self.population, self.elite, self.top_k, self.tournament = o.population, o.elite, o.top_k, o.tournament
        self.mutation_scale, self.niche_radius, self.immigrants = o.mutation_scale, o.niche_radius, o.immigrants
        self.crossover_rate, self.blend, self.branch_flip = o.crossover_rate, o.blend, o.branch_flip
        self.robot, self.evaluator, self.redundancy, self.rng = robot, evaluator, redundancy, rng
        self._lower = np.asarray(redundancy.gene_lower, dtype=float)
        self._upper = np.asarray(redundancy.gene_upper, dtype=float)
        self._gene_periodic = gene_periodic(redundancy)
        self._lamarck = not isinstance(redundancy, PlanarRedundancy)
        self.g = int(self._lower.size)
        self.generation = 0
        self._genes = np.zeros((0, self.g))
        self._branch = np.zeros(0, dtype=int)
        self._S = np.zeros(0)
        self._Q = np.zeros((0, robot.nq))
        self._best: Candidate | None = None
        self._peaks: tuple[Candidate, ...] = ()
        self._peak_genes = np.zeros((0, self.g))  # the peaks' genes and branches, for re-injection
        self._peak_branch = np.zeros(0, dtype=int)
        self._pending_genes = np.zeros((0, self.g))
        self._pending_branch = np.zeros(0, dtype=int)
        self.branch_lock: int | None = None

    # ------------------------------------------------------------------------------- state

    @property
    def best(self) -> Candidate:
        """The best individual of the last evaluated generation.

        Raises:
            ConfigurationError: before the first :meth:`step`.
        """
        if self._best is None:
            raise ConfigurationError("OneStepGA.best is only defined after the first step()")
        return self._best

    def peaks(self) -> tuple[Candidate, ...]:
        """Up to ``top_k`` distinct optima (at least ``niche_radius`` apart, ``S > 0``), best first."""
        return self._peaks

    @property
    def population_genes(self) -> Array:
        """``(P, g)`` genes of the current population (a copy)."""
        return self._genes.copy()

    @property
    def population_q(self) -> Array:
        """``(P, nq)`` configurations of the current population (a copy; unreachable rows are placeholders)."""
        return self._Q.copy()

    @property
    def population_branch(self) -> NDArray[np.int_]:
        """``(P,)`` branches of the current population (a copy)."""
        return self._branch.copy()

    @property
    def population_S(self) -> Array:  # noqa: N802 -- the paper's symbol S
        """``(P,)`` AMSIP of the current population at the last step's target and time (a copy)."""
        return self._S.copy()

    def seed(self, q: Array, neighbours: int = 0) -> None:
        """Inject configuration(s) ``(nq,)`` or ``(B, nq)`` (e.g. the current arm) into the next generation,
        each with ``neighbours`` mutants of it (the mutation operator below, same branch).

        They replace offspring (or random initial individuals) at the next :meth:`step`; at most
        ``population - elite - top_k`` are kept.
        """
        Q, _ = self.robot.check_configurations(q)
        genes, branch = self.redundancy.genes_of(Q)
        if neighbours:
            mutants = np.repeat(genes, neighbours, axis=0)
            genes = np.concatenate([genes, self._repair(self._mutate(mutants))])
            branch = np.concatenate([branch, np.repeat(branch, neighbours)])
        self._pending_genes = np.concatenate([self._pending_genes, genes])
        self._pending_branch = np.concatenate([self._pending_branch, branch])

    # ---------------------------------------------------------------------------- operators

    def _random(self, count: int) -> tuple[Array, NDArray[np.int_]]:
        genes = self._lower + self.rng.random((count, self.g)) * (self._upper - self._lower)
        return genes, self.rng.integers(0, self.redundancy.branches, count)

    def _repair(self, genes: Array) -> Array:
        """Wrap periodic genes, reflect bounded ones into their bounds."""
        if self._gene_periodic.all():
            return wrap_angle(genes)
        span = self._upper - self._lower
        reflected = np.abs((genes - self._lower) % (2 * span) - span)
        bounded = self._upper - reflected
        return np.where(self._gene_periodic, wrap_angle(genes), bounded)

    def _offspring(self, count: int) -> tuple[Array, NDArray[np.int_]]:
        rng, P = self.rng, self._S.size
        contenders = rng.integers(0, P, (2 * count, self.tournament))
        winners = contenders[np.arange(2 * count), np.argmax(self._S[contenders], axis=1)].reshape(2, count)
        a, b = self._genes[winners[0]], self._genes[winners[1]]
        diff = b - a
        diff = np.where(self._gene_periodic, wrap_angle(diff), diff)
        u = rng.uniform(-self.blend, 1.0 + self.blend, (count, self.g))
        cross = rng.random(count) < self.crossover_rate
        child = np.where(cross[:, None], a + u * diff, a)
        from_b = cross & (rng.random(count) < 0.5)
        branch = np.where(from_b, self._branch[winners[1]], self._branch[winners[0]])
        child = self._mutate(child)
        if self.redundancy.branches > 1:
            flip = rng.random(count) < self.branch_flip
            other = (branch + rng.integers(1, self.redundancy.branches, count)) % self.redundancy.branches
            branch = np.where(flip, other, branch)
        return self._repair(child), branch.astype(int)

    def _mutate(self, genes: Array) -> Array:
        """Gaussian mutation of every gene, one log-uniform scale ``mutation_scale 2^-u``, ``u ~ U(0, 5)``, per row."""
        sigma = self.mutation_scale * 2.0 ** -self.rng.uniform(0.0, 5.0, len(genes))
        return genes + sigma[:, None] * self.rng.standard_normal(genes.shape)

    def _next_population(self) -> tuple[Array, NDArray[np.int_]]:
        P = self.population
        pending_g, pending_b = self._pending_genes, self._pending_branch
        if self._S.size == 0:
            fill = max(P - pending_g.shape[0], 0)
            unit = halton(fill, self.g, self.rng) if self.g else np.zeros((fill, 0))
            genes = np.concatenate([pending_g, self._lower + unit * (self._upper - self._lower)])[:P]
            branch = np.concatenate([pending_b, self.rng.integers(0, self.redundancy.branches, fill)])[:P]
            return self._repair(genes), branch.astype(int)
        elite = np.argsort(-self._S, kind="stable")[: self.elite]
        parts_g = [self._genes[elite]]
        parts_b = [self._branch[elite]]
        # the peaks that are not already among the elites
        same = (self._peak_genes[:, None] == parts_g[0][None]).all(axis=2) & (self._peak_branch[:, None] == parts_b[0])
        fresh = ~same.any(axis=1)
        parts_g.append(self._peak_genes[fresh])
        parts_b.append(self._peak_branch[fresh])
        room = P - sum(len(p) for p in parts_b)
        parts_g.append(pending_g[:room])
        parts_b.append(pending_b[:room])
        room -= min(room, pending_g.shape[0])
        n_imm = min(room, round(self.immigrants * P))
        imm_g, imm_b = self._random(n_imm)
        child_g, child_b = self._offspring(room - n_imm)
        genes = np.concatenate([*parts_g, imm_g, child_g])
        branch = np.concatenate([*parts_b, imm_b, child_b]).astype(int)
        return genes, branch

    # -------------------------------------------------------------------------------- step

    def step(self, target: object, t: float) -> Candidate:
        """Run exactly one generation at hand target ``target`` and time ``t`` [s].

        Returns:
            The best individual of the new generation, evaluated at ``(target, t)``. Thanks to elitism
            it is the previous best re-evaluated, unless a better individual was found. Its ``S`` is
            negative if nothing in the population reaches the target without collision.
        """
        genes, branch = self._breed()
        return self._adopt(genes, branch, score(self.evaluator, self.redundancy, genes, branch, target, t))

    def _breed(self) -> tuple[Array, NDArray[np.int_]]:
        """The next generation's genes and branches (the pending seeds are used up)."""
        genes, branch = self._next_population()
        if self.branch_lock is not None:
            branch = np.full_like(branch, self.branch_lock)
        self._pending_genes, self._pending_branch = np.zeros((0, self.g)), np.zeros(0, dtype=int)
        return genes, branch

    def _adopt(self, genes: Array, branch: NDArray[np.int_], scored: Scored) -> Candidate:
        """Make the scored generation current: Lamarckian repair, peaks; returns the best."""
        if self._lamarck and scored.reachable.any():
            solved, solved_branch = self.redundancy.genes_of(scored.Q[scored.reachable])
            genes = genes.copy()
            genes[scored.reachable], branch[scored.reachable] = solved, solved_branch
        self._genes, self._branch, self._S, self._Q = genes, branch, scored.S, scored.Q
        self.generation += 1
        valid = np.flatnonzero(self._S > 0)
        order = valid[np.argsort(-self._S[valid], kind="stable")]
        angles = self.robot.angles_of(self._Q[order]) if order.size else np.zeros((0, self.robot.nv))
        kept = [int(order[k]) for k in distinct(angles, self.robot.joints.full_turn, self.niche_radius, self.top_k)]
        best, *peaks = candidates(
            genes, branch, self._Q, self._S, [int(np.argmax(self._S)), *kept], self._gene_periodic
        )
        self._best, self._peaks = best, tuple(peaks)
        self._peak_genes = np.array([p.genes for p in peaks]).reshape(len(peaks), self.g)
        self._peak_branch = np.array([p.branch for p in peaks], dtype=int)
        return best


def step_together(searches: Sequence[OneStepGA], targets: Sequence[object], times: Sequence[float]) -> list[Candidate]:
    """One generation of each GA: ``searches[i]`` at hand target ``targets[i]`` and time ``times[i]`` [s].

    The same result as ``[ga.step(target, t) for ...]``. GAs that share one :class:`NewtonRedundancy`
    project their new populations in a single :meth:`NewtonRedundancy.solve_many` call: the Newton
    iteration's per-step overhead, most of a generation's cost on a spatial arm, is then paid once
    per frame instead of once per imaginary arm.
    """
    if not (len(searches) == len(targets) == len(times)):
        raise ConfigurationError(
            f"step_together needs one target and one time per search: {len(searches)} searches, "
            f"{len(targets)} targets, {len(times)} times"
        )
    bred = [ga._breed() for ga in searches]
    solved: dict[int, tuple[Array, NDArray[np.bool_]]] = {}
    for redundancy, members in _shared_newton_maps(searches):
        genes = np.concatenate([bred[i][0] for i in members])
        branch = np.concatenate([bred[i][1] for i in members])
        groups = np.repeat(np.arange(len(members)), [len(bred[i][0]) for i in members])
        Q, reachable = redundancy.solve_many(genes, branch, [targets[i] for i in members], groups)
        for k, i in enumerate(members):
            rows = groups == k
            solved[i] = Q[rows], reachable[rows]
    best = []
    for i, (ga, (genes, branch)) in enumerate(zip(searches, bred, strict=True)):
        if i in solved:
            scored = score_configurations(ga.evaluator, *solved[i], times[i])
        else:
            scored = score(ga.evaluator, ga.redundancy, genes, branch, targets[i], times[i])
        best.append(ga._adopt(genes, branch, scored))
    return best


def _shared_newton_maps(searches: Sequence[OneStepGA]) -> list[tuple[NewtonRedundancy, list[int]]]:
    """The Newton maps of ``searches``, each with the indices of the searches using it (searches with
    another kind of map are left out)."""
    groups: list[tuple[NewtonRedundancy, list[int]]] = []
    for i, ga in enumerate(searches):
        if isinstance(ga.redundancy, NewtonRedundancy):
            shared = next((members for red, members in groups if red is ga.redundancy), None)
            if shared is None:
                groups.append((ga.redundancy, [i]))
            else:
                shared.append(i)
    return groups
