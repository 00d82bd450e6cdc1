"""Reachability over time: dynamic programming over the planar redundancy grid x time (the global reference).

The paper's section 5.1 asks "whether the current configuration is reachable to the future optimal
configuration" and answers by looking at the AMSIP maps at ten times (Fig. 8, Table 1). This package
answers it exactly on a grid, for planar arms, offline and non-causally (it reads the whole future):

* **Space.** The redundancy grid of :class:`~previewctl.search.planar.PlanarRedundancy`: the
  genes ``q_1 .. q_(n-2)`` on a ``h``-degree grid x the two elbow branches; the last two joints in
  closed form, so every cell puts the hand on the path. Joint limits hold along every motion: a
  gene's grid runs over its joint limits (planar4: ``[-360°, 360°]``, so a grid value *is* the joint
  value; only a gene without finite limits gets a periodic ``[0, 360)`` axis), ``q_n = β + c`` with the
  signed elbow angle ``β`` in ``[-π, π]`` never wraps, and ``q_(n-1)``, which the closed form gives
  modulo 2π as ``a`` in ``[-π, π)``, is carried by a *state* ``(cell, m)``: the arm is at ``a + 2π m``,
  and only the representatives within the joint's limits exist. (Without this a motion can wind a
  ``±2π`` joint past its limit: docs/decisions.md#joint-windings-on-the-reachability-grid.)
* **Time.** ``N`` steps of ``Δt = duration / N`` [s]; layer ``k`` holds the cells at ``t_k = t_0 + k Δt``
  with the obstacles and the hand target of that time. Layer 0 of the dynamic programme is the
  start configuration ``q0`` itself (not a grid cell); the grid at ``t_0`` is only used for the
  start families and the figures.
* **Feasible cells.** ``S > s_min`` (AMSIP, eq. 18; ``S < 0`` when colliding or unreachable).
* **Transitions** ``c -> c'`` from layer ``k`` to ``k + 1`` (all conditions, each conservative):

  1. joint speed (every joint, the closed-form last two included): ``|Δq_j| <= δ_j = v_j Δt``
     with ``v_j`` the URDF speed limit x ``velocity_scale`` [rad/s]. Genes move by whole cells,
     ``|Δi_a| <= r_a = min(floor(δ_a / h), max_step_cells)``: the cap ``max_step_cells`` bounds the
     work, and it is a further (reported) restriction when ``r_a h < δ_a``. ``q_(n-1)`` moves the
     short way, ``Δ = wrap(a' - a)``, ``|Δ| <= δ_(n-1)``, its representative following (``m' = m``, or
     ``m ± 1`` when the short way crosses ``±π``), and the new state must exist (within the limits).
     The elbow is compared through ``β`` (branch 0: ``β >= 0``, branch 1: ``β < 0``) *without*
     wrapping, so an elbow switch can only pass the stretched wrist ``β = 0``
     (``|β| + |β'| <= δ_n``), never the folded one (``β = ±π``).
  2. the continuous motion between the samples: the arm is taken to move linearly in joint space
     from ``c`` at ``t_k`` to ``c'`` at ``t_(k+1)``. A point of guarded capsule ``l`` then moves by at most
     ``B_l = Σ_j |Δq_j| ρ_jl`` [m], with ``ρ_jl`` the largest distance from joint ``j`` to that capsule
     (link lengths along the chain + capsule end + radius: a bound independent of the
     configuration). The obstacles move by at most ``m = v_obs Δt`` (``v_obs`` estimated from
     ``obstacle_substeps`` samples of their motion; 0 for static ones). The step is collision-free
     if ``d_l(c) + d_l(c') > B_l + m`` for every guarded capsule ``l``, ``d_l`` the capsule-obstacle
     distance [m]: at a fraction ``s`` of the step the clearance is at least
     ``max(d_l(c) - s (B_l + m), d_l(c') - (1 - s)(B_l + m)) > 0``. The hand leaves the path between
     samples by a little (the path is not linear in joint space); a tracking controller such as
     :class:`~previewctl.control.laws.Oracle` keeps it on the path and uses the motion
     as a reference.

  So a motion the DP returns is, as sampled and linearly interpolated, within the speed limits
  and collision-free for the guarded links. A "no" is relative to the grid, the time step and the
  step cap: the DP is resolution-complete, not complete.

The programme, over stored edge lists (one per step, built once, between states):

Every quantity below is per state (cell and representative); the figures fold states onto cells
over ``[0, 360)``. Layer ``k + 1`` is evaluated only at the cells one step away from the states
reachable at layer ``k`` (a lazy forward sweep: the DP from ``q0`` never needs the rest).

* **(a) existence.** ``W_k(c)`` = the best bottleneck ``max over motions q0 -> c of min_(1<=i<=k) S_i``
  (forward max-min; ``-inf`` when ``c`` is not reachable). A motion to the end exists iff some
  ``W_N > -inf``. Otherwise the *dead end* is ``t_K`` with ``K`` the last layer that can be reached.
* **(c) the best motion.** ``S* = max W_K`` (the best minimum S over ``t_1 .. t_K``; ``q0`` is given and
  its own S reported apart). Among the motions whose every sample has ``S >= S*``, the one with the
  largest total ``Σ_k S_k`` (a backward max-sum DP on the cells with ``W_k >= S*``, then a forward
  read-out): the exact lexicographic optimum (max min S, then max total S).
* **(b) the commit time.** The *end families* are the connected components (8-neighbour grid
  adjacency within a branch; the two branches of a cell are adjacent where ``|β| <= cross_adjacency``)
  of the cells at ``t_K`` that ``q0`` reaches (``K = N`` when a motion exists; otherwise the families
  that last longest). A backward OR of family bit masks gives, for every
  reachable cell, the set of end families still reachable from it; the *viable tube* is the reachable
  cells with a non-empty set. The **commit time** is the last ``t_k`` at which some cell of the viable
  tube (or ``q0`` at ``t_0``) can still reach two or more end families: until then the arm can keep
  its options open; from ``t_(k+1)`` on every viable configuration leads to exactly one family. With
  one end family there is nothing to commit to (``None``).
* **Start families** (the paper's view of Fig. 8): the components of the feasible cells at ``t_0``.
  A forward OR of their bits gives each family's *lifetime* (the last ``t_k`` at which its forward
  reachable set is non-empty; the paper's peak 4 dies at 15 s), whether it reaches ``t_N``, and the
  last time its reachable set shares a cell with another family's (after that, the family's tube is
  separate from the others).

The package, one concept a module; each imports only modules above it in this list:

* :mod:`~previewctl.search.reachability.options`: :class:`ReachOptions` and :class:`PlanarOnlyError`.
* :mod:`~previewctl.search.reachability.result`: :class:`ReachResult`, :class:`ReachMotion`, :class:`Family`
  and the JSON summary.
* :mod:`~previewctl.search.reachability.grid`: the grid model (gene axes, representatives of
  ``q_(n-1)``, flat cell index, per-step bounds, sweep radii) and ``q0`` on it.
* :mod:`~previewctl.search.reachability.layers`: evaluating a layer (its feasible cells) and which
  cells to evaluate.
* :mod:`~previewctl.search.reachability.transitions`: the allowed steps between two layers, stored as
  edges.
* :mod:`~previewctl.search.reachability.problem`: one run's context; builds layers and edges and times
  them.
* :mod:`~previewctl.search.reachability.dp`: (a) the forward max-min and (c) the best motion's states.
* :mod:`~previewctl.search.reachability.motion`: those states as joint values (:class:`ReachMotion`).
* :mod:`~previewctl.search.reachability.components`: connected components of a layer's states.
* :mod:`~previewctl.search.reachability.families`: (b) end families, viable tube, commit time; start
  families.
* :mod:`~previewctl.search.reachability.maps`: the figures' S maps and states folded onto them.
* :mod:`~previewctl.search.reachability.over_time`: :func:`reach_over_time`, which runs them in order.
"""

from previewctl.search.reachability.families import MAX_FAMILY_BITS
from previewctl.search.reachability.grid import signed_elbow
from previewctl.search.reachability.options import PlanarOnlyError, ReachOptions
from previewctl.search.reachability.over_time import reach_over_time
from previewctl.search.reachability.result import Family, ReachMotion, ReachResult

__all__ = [
    "MAX_FAMILY_BITS",
    "Family",
    "PlanarOnlyError",
    "ReachMotion",
    "ReachOptions",
    "ReachResult",
    "reach_over_time",
    "signed_elbow",
]
