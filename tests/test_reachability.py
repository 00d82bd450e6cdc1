"""Reachability over time (search/reachability): the DP against brute force on tiny grids, its best
motion under the exact check, the typed error for spatial arms, and the ``reach-map`` command."""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from previewctl.bench.scenes import generate
from previewctl.cli.main import main
from previewctl.control.factory import make_controller
from previewctl.control.laws import Horizon
from previewctl.control.params import ControllerParams
from previewctl.control.planner import ORACLE_OPTIONS, PlanTiming
from previewctl.errors import ConfigurationError, ParameterError, TrajectoryError
from previewctl.index.evaluator import Evaluator
from previewctl.index.load import load_robot, shipped_robots_dir
from previewctl.kinematics import integrate
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.scene.motion import ConstantVelocity, Static
from previewctl.scene.shapes import Obstacle, Scene, Sphere
from previewctl.search.planar import PlanarRedundancy
from previewctl.search.reachability import PlanarOnlyError, ReachOptions, ReachResult, reach_over_time
from previewctl.search.reachability.families import two_or_more
from previewctl.search.reachability.goals import Goals
from previewctl.search.reachability.grid import MAX_GRID_NODES, fast_enough, grid_model, targets
from previewctl.search.reachability.result import ReachMotion
from previewctl.search.redundancy import wrap_angle
from previewctl.sim.loop import simulate
from previewctl.sim.scenario import Scenario, load_scenario
from previewctl.types import Array

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
LINK = 0.75  # [m], planar4's links
RADIUS = 0.03  # [m], its capsules


def planar2_urdf(tmp: Path) -> Path:
    """planar4 without its last two links: a 2-joint planar arm (no gene: two cells per layer)."""
    text = (shipped_robots_dir() / "planar4.urdf").read_text()
    start = text.index('<joint name="joint3"')
    end = text.index('<joint name="tip_joint"')
    text = text[:start] + text[end:].replace('<parent link="link4"/>', '<parent link="link2"/>', 1)
    out = tmp / "planar2.urdf"
    out.write_text(text.replace('name="planar4"', 'name="planar2"'))
    return out


def planar3_urdf(tmp: Path, limits: tuple[tuple[float, float], ...] | None = None) -> Path:
    """planar4 without its last link: a 3-joint planar arm (one gene); optionally other joint limits [rad]."""
    text = (shipped_robots_dir() / "planar4.urdf").read_text()
    start = text.index('<joint name="joint4"')
    end = text.index('<joint name="tip_joint"')
    text = text[:start] + text[end:].replace('<parent link="link4"/>', '<parent link="link3"/>', 1)
    if limits is not None:
        full = 'lower="-6.283185307179586" upper="6.283185307179586"'
        for lo, hi in limits:
            text = text.replace(full, f'lower="{lo!r}" upper="{hi!r}" ', 1)
    out = tmp / ("planar3.urdf" if limits is None else "planar3_limited.urdf")
    out.write_text(text.replace('name="planar4"', 'name="planar3"'))
    return out


@pytest.fixture(scope="module")
def planar3(tmp_path_factory: pytest.TempPathFactory) -> Robot:
    return load_robot(str(planar3_urdf(tmp_path_factory.mktemp("planar3"))))


@pytest.fixture(scope="module")
def planar4() -> Robot:
    return load_robot("planar4")


def start_on_path(robot: Robot, path: HandPath, genes: tuple[float, ...], branch: int) -> Array:
    red = PlanarRedundancy(robot)
    Q, ok = red.solve(np.array([genes]), np.array([branch]), path.position(0.0))
    assert ok[0]
    return Q[0]


# ------------------------------------------------------------------------------ brute force


def sweep_radii(robot: Robot) -> Array:
    """rho[j, l] for the straight planar chains of these tests: joint j (0-based) to the far end of
    guarded link l (carried by joint l), plus the capsule radius."""
    n, links = robot.nq, len(robot.guarded_links)
    rho = np.zeros((n, links))
    for l_idx in range(links):
        for j in range(l_idx + 1):
            rho[j, l_idx] = (l_idx + 1 - j) * LINK + RADIUS
    return rho


class Brute:
    """Every path through the tiny grid, enumerated explicitly, in unwrapped joint space.

    A state is a joint vector within the limits: genes on the grid over their limits, ``q_(n-1)`` one of
    the values ``a + 2 pi m`` the closed form allows, ``q_n`` the signed elbow angle (no wrapping
    anywhere). Transitions are checked pair by pair with plain differences.
    """

    def __init__(self, robot: Robot, evaluator: Evaluator, path: HandPath, q0: Array, duration: float,
                 opts: ReachOptions) -> None:
        red = PlanarRedundancy(robot)
        g, n = red.g, robot.nq
        N, h = opts.steps, np.radians(opts.resolution_deg)
        dt = duration / N
        lo, hi = robot.lower_limits, robot.upper_limits
        axis = lo[0] + np.arange(int(np.floor((hi[0] - lo[0]) / h + 1e-9)) + 1) * h  # same limits on every gene
        delta = robot.velocity_limits * opts.velocity_scale * dt
        cap = min(opts.max_step_cells, int(np.floor(delta[0] / h + 1e-9))) * h
        rho = sweep_radii(robot)
        self.times = np.arange(N + 1) * dt
        self.count = round(2 * np.pi / h)  # cells per gene of the figures' [0, 360) grid
        travel = max((float(np.linalg.norm(np.diff(o.motion.positions([0.0, 1.0]), axis=0))) * dt
                      for o in evaluator.scene.obstacles), default=0.0)
        beta0 = float(np.abs(wrap_angle(q0[n - 1])) * (1 if q0[n - 1] >= 0 else -1))
        genes = np.array(list(itertools.product(axis, repeat=g))) if g else np.zeros((1, 0))
        gene_index = np.array(list(itertools.product(range(len(axis)), repeat=g))) if g else np.zeros((1, 0), int)
        self.layers = []  # per time: dict of state arrays
        for t in self.times:
            rows = []
            for branch in (0, 1):
                Q, ok = red.solve(genes, np.full(len(genes), branch), path.position(t))
                S = np.full(len(Q), -1.0)
                d = np.full((len(Q), len(robot.guarded_links)), -np.inf)
                ev = evaluator(Q[ok], t)
                S[ok], d[ok] = ev.S, ev.link_distances
                beta = np.abs(wrap_angle(Q[:, n - 1])) * (1 if branch == 0 else -1)
                a = wrap_angle(Q[:, n - 2])
                for m in (-2, -1, 0, 1, 2):
                    u = a + 2 * np.pi * m
                    keep = ok & (opts.s_min < S) & (u >= lo[n - 2] - 1e-9) & (u <= hi[n - 2] + 1e-9)
                    keep &= (beta >= lo[n - 1] - 1e-9) & (beta <= hi[n - 1] + 1e-9)
                    for i in np.flatnonzero(keep):
                        rows.append((genes[i], gene_index[i], branch, u[i], beta[i], d[i], S[i]))
            self.layers.append({
                "genes": np.array([r[0] for r in rows]).reshape(len(rows), g),
                "index": np.array([r[1] for r in rows]).reshape(len(rows), g),
                "branch": np.array([r[2] for r in rows], dtype=int),
                "u": np.array([r[3] for r in rows]),
                "beta": np.array([r[4] for r in rows]),
                "d": np.array([r[5] for r in rows]).reshape(len(rows), len(robot.guarded_links)),
                "S": np.array([r[6] for r in rows]),
            })

        def allowed(src: dict, dst: dict) -> Array:
            dgene = np.abs(dst["genes"][None, :, :] - src["genes"][:, None, :])
            du = np.abs(dst["u"][None, :] - src["u"][:, None])
            dbeta = np.abs(dst["beta"][None, :] - src["beta"][:, None])
            ok = np.all(dgene <= min(cap, delta[0]) + 1e-9, axis=2) & (du <= delta[n - 2]) & (dbeta <= delta[n - 1])
            moves = np.concatenate([dgene, du[..., None], dbeta[..., None]], axis=2)
            ok &= np.all(src["d"][:, None, :] + dst["d"][None, :, :] > moves @ rho + travel, axis=2)
            return ok

        self.q0_S = float(evaluator(q0, 0.0).S[0])
        start = {"genes": q0[None, :g], "u": q0[None, n - 2], "beta": np.array([beta0]),
                 "d": evaluator(q0, 0.0).link_distances}
        self.grid0 = allowed(self.layers[0], self.layers[1])
        self.transitions = [allowed(start, self.layers[1])] + [
            allowed(self.layers[k], self.layers[k + 1]) for k in range(1, N)
        ]
        prefixes = [np.zeros((1, 0), dtype=np.int64)]
        current = np.zeros((1, 0), dtype=np.int64)
        for k in range(N):
            last = np.zeros(len(current), dtype=np.int64) if k == 0 else current[:, -1]
            pairs = np.argwhere(self.transitions[k][last])
            current = np.concatenate([current[pairs[:, 0]], pairs[:, 1:2]], axis=1)
            prefixes.append(current)
        self.prefixes = prefixes

    def last_layer(self) -> int:
        return max(k for k, p in enumerate(self.prefixes) if len(p))

    def scores(self, k: int) -> tuple[Array, Array]:
        paths = self.prefixes[k]
        S = np.stack([self.layers[i + 1]["S"][paths[:, i]] for i in range(k)], axis=1)
        return S.min(axis=1), S.sum(axis=1)

    def q(self, k: int, state: int) -> Array:
        layer = self.layers[k]
        return np.concatenate([layer["genes"][state], [layer["u"][state], layer["beta"][state]]])

    def folded(self, k: int, states: set[int]) -> set[tuple[int, ...]]:
        """The figures' cells ``(branch, i_1, ...)`` over [0, 360) of these states."""
        layer = self.layers[k]
        step = 2 * np.pi / self.count
        return {(int(layer["branch"][s]), *(int(v) for v in np.rint(np.mod(layer["genes"][s], 2 * np.pi) / step)
                                               .astype(int) % self.count)) for s in states}


def components(brute: Brute, k: int, states: set[int], cross: float) -> list[set[int]]:
    """Connected components by breadth-first search: gene-grid neighbours on one branch, or the two branches
    of one cell where |beta| <= cross on both, and q_(n-1) within pi (the short way)."""
    layer = brute.layers[k]
    index, branch, u, beta = layer["index"], layer["branch"], layer["u"], layer["beta"]

    def adjacent(a: int, b: int) -> bool:
        if abs(u[a] - u[b]) > np.pi:
            return False
        step = np.abs(index[a] - index[b]).max(initial=0)
        if branch[a] == branch[b]:
            return step == 1
        return step == 0 and abs(beta[a]) <= cross and abs(beta[b]) <= cross

    left, found = set(states), []
    while left:
        seed = left.pop()
        comp, todo = {seed}, [seed]
        while todo:
            here = todo.pop()
            for other in [s for s in left if adjacent(here, s)]:
                left.remove(other)
                comp.add(other)
                todo.append(other)
        found.append(comp)
    return found


def folded_result(result: ReachResult, k: int, which: str) -> set[tuple[int, ...]]:
    return {tuple(int(v) for v in idx) for idx in np.argwhere(getattr(result, which)[k])}


def check_against_brute(robot: Robot, scene: Scene, path: HandPath, q0: Array, duration: float,
                        opts: ReachOptions) -> ReachResult:
    evaluator = Evaluator(robot, scene)
    result = reach_over_time(robot, evaluator, path, q0, duration, opts)
    brute = Brute(robot, evaluator, path, q0, duration, opts)
    N = opts.steps
    K = brute.last_layer()
    assert result.exists == (K == N)
    assert (result.dead_end is None) == (K == N)
    if K < N:
        assert result.dead_end == pytest.approx(brute.times[K])
    for k in range(1, N + 1):  # forward reachable sets, layer by layer
        expected = set(brute.prefixes[k][:, -1].tolist()) if len(brute.prefixes[k]) else set()
        assert folded_result(result, k, "reachable") == brute.folded(k, expected), f"layer {k}"
    if K == 0:
        assert np.isnan(result.best_min_S)
        return result
    # best bottleneck, then best total among the bottleneck-optimal paths; the motion is one of them
    mins, sums = brute.scores(K)
    s_star = mins.max()
    assert result.best_min_S == pytest.approx(s_star, rel=1e-12)
    best_total = sums[mins >= s_star].max()
    motion = result.motion
    assert motion.min_S == pytest.approx(s_star, rel=1e-12)
    assert motion.total_S == pytest.approx(best_total, rel=1e-9)
    best_paths = brute.prefixes[K][(mins >= s_star) & (sums >= best_total - 1e-9 * abs(best_total))]
    assert any(np.allclose(motion.q[1:], [brute.q(k + 1, s) for k, s in enumerate(p)], atol=1e-9) for p in best_paths)
    np.testing.assert_allclose(motion.q[0], q0)
    if K == N:  # viable tube, end families and commit time
        full = brute.prefixes[N]
        for k in range(1, N + 1):
            assert folded_result(result, k, "viable") == brute.folded(k, set(full[:, k - 1].tolist())), f"viable {k}"
        comps = components(brute, N, set(full[:, -1].tolist()), np.radians(opts.cross_adjacency_deg))
        assert sorted(f.cells for f in result.end_families) == sorted(len(c) for c in comps)
        label = {c: i for i, comp in enumerate(comps) for c in comp}
        family_of_path = np.array([label[c] for c in full[:, -1]])
        shared = [len(comps) >= 2]  # q0 reaches every end family
        for k in range(1, N + 1):
            column = full[:, k - 1]
            shared.append(any(len(set(family_of_path[column == c].tolist())) >= 2 for c in set(column.tolist())))
        expected = max((k for k in range(N + 1) if shared[k]), default=None)
        assert result.commit_time == (None if expected is None else pytest.approx(brute.times[expected]))
        # the best motion ends in the family result.best_family names
        end_state = next(s for s in comps[0] | set().union(*comps)
                         if np.allclose(brute.q(N, s), motion.q[-1], atol=1e-9))
        family = next(f for f in result.end_families if f.label == result.best_family)
        assert family.cells == len(next(c for c in comps if end_state in c))
    if opts.start_families:
        comps = components(brute, 0, set(range(len(brute.layers[0]["S"]))), np.radians(opts.cross_adjacency_deg))
        assert sorted(f.cells for f in result.start_families) == sorted(len(c) for c in comps)
        for comp in comps:
            alive = np.zeros(len(brute.layers[0]["S"]), dtype=bool)
            alive[list(comp)] = True
            last = 0
            for k in range(N):
                alive = (brute.grid0 if k == 0 else brute.transitions[k])[alive].any(axis=0)
                if alive.any():
                    last = k + 1
            # the family of the same size whose lifetime matches (sizes can repeat)
            assert any(f.cells == len(comp) and f.alive_until == pytest.approx(brute.times[last])
                       and f.finishes == (last == N) for f in result.start_families)
    return result


# ------------------------------------------------------------------------------------- tests


def test_planar3_matches_brute_force(planar3: Robot) -> None:
    """One gene on a 30 deg grid, 5 steps of 1.1 s (two cells per step), a disc beside the path."""
    path = HandPath(np.array([[1.2, 0.6], [0.9, 1.0]]), 5.5)
    scene = Scene((Obstacle("disc", Sphere(0.25), Static(np.array([0.2, 1.1, 0.0]))),))
    q0 = start_on_path(planar3, path, (0.3,), 0)
    opts = ReachOptions(resolution_deg=30.0, steps=5, max_step_cells=3)
    result = check_against_brute(planar3, scene, path, q0, 5.5, opts)
    assert result.exists
    assert list(result.gene_cells) == [2]  # floor(1.1 rad / 30 deg)


def test_motion_to_a_goal_matches_brute_force(planar3: Robot) -> None:
    """Goals (imaginary arms' peaks): the motion ends at the latest level with a reached goal, in the reached state
    within one grid step of it with the best bottleneck, and it is a brute-force path there with the best
    bottleneck, then the best total S; a better goal that no motion reaches is passed over."""
    path = HandPath(np.array([[1.2, 0.6], [0.9, 1.0]]), 5.5)
    scene = Scene((Obstacle("disc", Sphere(0.25), Static(np.array([0.2, 1.1, 0.0]))),))
    q0 = start_on_path(planar3, path, (0.3,), 0)
    opts = ReachOptions(resolution_deg=30.0, steps=5, max_step_cells=3)
    evaluator = Evaluator(planar3, scene)
    brute = Brute(planar3, evaluator, path, q0, 5.5, opts)
    assert brute.last_layer() == 5
    h, k = np.radians(opts.resolution_deg), 3

    def matched(layer: int, q: Array) -> set[int]:
        """Brute states of ``layer`` that a motion reaches, within one step of ``q``'s gene, on its branch."""
        states = brute.layers[layer]
        reached = set(brute.prefixes[layer][:, -1].tolist())
        branch = int(wrap_angle(q[-1]) < 0)
        return {s for s in reached if states["branch"][s] == branch
                and abs(wrap_angle(states["genes"][s, 0] - q[0])) <= h + 1e-9}

    mins, sums = brute.scores(k)
    ends = brute.prefixes[k][:, -1]
    goal_state = int(ends[np.argmin(mins)])  # the reached state with the worst bottleneck
    goal = brute.q(k, goal_state)
    # at the last layer: a configuration of the other branch whose gene no motion comes near, scored higher
    unreached = [brute.q(5, s) for s in range(len(brute.layers[5]["S"])) if not matched(5, brute.q(5, s))]
    assert unreached
    goals = [Goals(float(brute.times[k]), goal[None, :], np.array([1.0])),
             Goals(float(brute.times[5]), unreached[0][None, :], np.array([10.0]))]
    result = reach_over_time(planar3, evaluator, path, q0, 5.5, opts, goals=goals)
    assert result.goal == (0, 0)
    near = matched(k, goal)
    at_near = np.isin(ends, list(near))
    s_goal = mins[at_near].max()
    total = sums[at_near & (mins >= s_goal)].max()
    motion = result.motion
    assert motion.q.shape[0] == k + 1 and motion.min_S == pytest.approx(s_goal, rel=1e-12)
    assert motion.total_S == pytest.approx(total, rel=1e-9)
    best = brute.prefixes[k][at_near & (mins >= s_goal) & (sums >= total - 1e-9 * abs(total))]
    assert any(np.allclose(motion.q[1:], [brute.q(i + 1, s) for i, s in enumerate(p)], atol=1e-9) for p in best)
    # without a reached goal the motion is the best one overall
    alone = reach_over_time(planar3, evaluator, path, q0, 5.5, opts, goals=goals[1:])
    assert alone.goal is None and alone.motion.min_S == pytest.approx(result.best_min_S, rel=1e-12)
    assert alone.motion.q.shape[0] == 6


def test_a_reached_goal_that_leads_nowhere_is_passed_over(planar4_intermediate: Robot) -> None:
    """A goal counts only if a motion goes on from it to the window's end: at layer 3 of 4 (45 deg grid, found by
    a seeded search) two states are reached but are dead ends with no viable state within a grid step; as
    goals they are passed over for a worse-scored viable one, and alone they leave the best motion overall."""
    path = HandPath(np.array([(1.1105, 0.8467), (1.2459, 0.8913)]), 3.2)
    discs = [(0.2872, (-1.0238, -0.7147)), (0.285, (0.401, -1.4464))]
    scene = Scene(tuple(Obstacle(f"disc{i}", Sphere(r), Static(np.array([*c, 0.0]))) for i, (r, c) in enumerate(discs)))
    q0 = start_on_path(planar4_intermediate, path, (0.2963, 2.6483), 0)
    opts = ReachOptions(resolution_deg=45.0, steps=4, max_step_cells=3)
    evaluator = Evaluator(planar4_intermediate, scene)
    brute, k, h = Brute(planar4_intermediate, evaluator, path, q0, 3.2, opts), 3, np.radians(45.0)
    assert brute.last_layer() == 4
    layer, reached = brute.layers[k], set(brute.prefixes[k][:, -1].tolist())
    viable = set(brute.prefixes[4][:, k - 1].tolist())

    def near(a: int, b: int) -> bool:
        return bool(layer["branch"][a] == layer["branch"][b]
                    and np.all(np.abs(wrap_angle(layer["genes"][a] - layer["genes"][b])) <= h + 1e-9))

    dead = sorted(s for s in reached - viable if not any(near(s, v) for v in viable))
    assert len(dead) == 2
    alive = min(viable)
    t_k = float(brute.times[k])
    goals = [Goals(t_k, np.array([brute.q(k, s) for s in (*dead, alive)]), np.array([10.0, 9.0, 1.0]))]
    result = reach_over_time(planar4_intermediate, evaluator, path, q0, 3.2, opts, goals=goals)
    assert result.goal == (0, 2)
    assert np.allclose(result.motion.q[-1], brute.q(k, alive), atol=1e-9) or any(
        near(alive, s) and np.allclose(result.motion.q[-1], brute.q(k, s), atol=1e-9) for s in viable)
    only_dead = [Goals(t_k, np.array([brute.q(k, s) for s in dead]), np.array([10.0, 9.0]))]
    alone = reach_over_time(planar4_intermediate, evaluator, path, q0, 3.2, opts, goals=only_dead)
    assert alone.goal is None and alone.motion.min_S == pytest.approx(alone.best_min_S, rel=1e-12)
    assert alone.motion.q.shape[0] == 5


def test_planar3_narrow_joint_limits(tmp_path: Path) -> None:
    """Joint limits narrower than a turn (q1 in [-2.5, 3], q2 in [-3.5, 0.5]): the limits cut states and
    motions exactly as the enumeration in unwrapped joint space says."""
    robot = load_robot(str(planar3_urdf(tmp_path, ((-2.5, 3.0), (-3.5, 0.5), (-6.2, 6.2)))))
    path = HandPath(np.array([[1.2, 0.6], [0.9, 1.0]]), 5.5)
    scene = Scene((Obstacle("disc", Sphere(0.25), Static(np.array([0.2, 1.1, 0.0]))),))
    q0 = start_on_path(robot, path, (0.3,), 0)
    opts = ReachOptions(resolution_deg=30.0, steps=5, max_step_cells=3)
    result = check_against_brute(robot, scene, path, q0, 5.5, opts)
    assert np.all(result.motion.q >= robot.lower_limits - 1e-9) and np.all(result.motion.q <= robot.upper_limits + 1e-9)


def test_planar2_no_gene(tmp_path: Path) -> None:
    """A two-link arm has no redundancy: one cell per branch; the DP still tracks, and switches branch only
    through the stretched elbow."""
    robot = load_robot(str(planar2_urdf(tmp_path)))
    path = HandPath(np.array([[1.2, 0.3], [1.0, 0.8]]), 4.0)
    scene = Scene((Obstacle("disc", Sphere(0.2), Static(np.array([0.2, 1.2, 0.0]))),))
    Q, ok = PlanarRedundancy(robot).solve(np.zeros((1, 0)), np.array([0]), path.position(0.0))
    assert ok[0]
    result = check_against_brute(robot, scene, path, Q[0], 4.0, ReachOptions(resolution_deg=30.0, steps=4))
    assert result.map_axes == () and result.shape == (2,)


def test_planar3_moving_obstacle_and_dead_end(planar3: Robot) -> None:
    """A disc sweeping across the arm: the sweep bound includes the obstacle's travel; the brute force
    agrees on where every motion gets stuck."""
    path = HandPath(np.array([[1.2, 0.6], [0.9, 1.0]]), 5.5)
    disc = Obstacle("disc", Sphere(0.3), ConstantVelocity(np.array([-0.6, 1.4, 0.0]), np.array([0.35, -0.1, 0.0])))
    scene = Scene((disc,))
    q0 = start_on_path(planar3, path, (0.3,), 0)
    opts = ReachOptions(resolution_deg=30.0, steps=5, max_step_cells=3)
    check_against_brute(planar3, scene, path, q0, 5.5, opts)


PLANAR4_CASES = {
    # hand from A to B [m], discs (radius [m], centre [m]), q0 genes [rad] and branch; found by a seeded
    # random search for what each case exercises
    "two_end_families": ((1.4242, -0.0072), (1.5311, 0.2213), [(0.1653, (1.8065, 1.8811))], (3.0938, -2.8744), 0),
    "many_paths": ((0.7952, 0.0257), (0.3779, 0.1754), [(0.2125, (1.6705, 1.5155)), (0.2843, (1.7727, 0.5644))],
                   (0.0145, -2.9052), 0),
    "dead_end": ((1.1623, 1.1885), (1.3626, 0.746), [(0.2233, (-0.822, -0.2829)), (0.2155, (0.7847, -0.0625))],
                 (1.5354, 0.2063), 1),
}


@pytest.fixture(scope="module")
def planar4_intermediate() -> Robot:
    """planar4 guarding links 1-3 only: the robot :data:`PLANAR4_CASES` were found for."""
    return load_robot("planar4", guarded_links="intermediate")


@pytest.mark.parametrize("case", sorted(PLANAR4_CASES))
def test_planar4_matches_brute_force(planar4_intermediate: Robot, case: str) -> None:
    """Two genes on a 45 deg grid, 4 steps of 0.8 s (one cell per step): reachable sets, bottleneck,
    tie-break, viable tube, end families and commit time all equal the enumeration of every path."""
    planar4 = planar4_intermediate
    start, end, discs, genes, branch = PLANAR4_CASES[case]
    path = HandPath(np.array([start, end]), 3.2)
    scene = Scene(tuple(Obstacle(f"disc{i}", Sphere(r), Static(np.array([*c, 0.0]))) for i, (r, c) in enumerate(discs)))
    q0 = start_on_path(planar4, path, genes, branch)
    opts = ReachOptions(resolution_deg=45.0, steps=4, max_step_cells=3, start_families=True)
    result = check_against_brute(planar4, scene, path, q0, 3.2, opts)
    assert result.start_families and sum(f.holds_q0 is True for f in result.start_families) == 1
    if case == "two_end_families":
        assert result.exists and len(result.end_families) == 2 and result.commit_time == pytest.approx(1.6)
    elif case == "dead_end":
        assert not result.exists and result.dead_end == pytest.approx(2.4)
        assert "stuck by t = 2.4 s" in result.verdict()


def test_planar3_two_end_families(planar3: Robot) -> None:
    """One gene, 30 deg grid, 5 steps of 0.8 s: two end families, the arm must choose at the last step."""
    path = HandPath(np.array([[1.0068, 0.3411], [0.7231, -0.0582]]), 4.0)
    scene = Scene((Obstacle("a", Sphere(0.2404), Static(np.array([0.0975, 1.6421, 0.0]))),
                   Obstacle("b", Sphere(0.267), Static(np.array([-0.1522, 1.9079, 0.0])))))
    q0 = start_on_path(planar3, path, (0.5784,), 0)
    result = check_against_brute(planar3, scene, path, q0, 4.0, ReachOptions(resolution_deg=30.0, steps=5))
    assert len(result.end_families) == 2 and result.commit_time == pytest.approx(3.2)


# --------------------------------------------------------------- the canonical scene, exact check


@pytest.fixture(scope="module")
def canonical() -> tuple[Scenario, ReachResult]:
    """paper_planar on a 4 deg grid (the figures' maps off): quick enough for a test. Links 1-3 guarded (the
    paper's intermediate links): with the hand's link guarded against the pillar too, this grid's sweep bound
    finds no motion past t = 49 s (docs/results.md, the staircase)."""
    scenario = load_scenario(SCENARIOS / "paper_planar.toml")
    scenario = dataclasses.replace(scenario, robot=load_robot("planar4", guarded_links="intermediate"))
    evaluator = Evaluator(scenario.robot, scenario.scene, scenario.index, scenario.potential)
    opts = ReachOptions(resolution_deg=4.0, steps=50, map_times=0)
    return scenario, reach_over_time(scenario.robot, evaluator, scenario.path, scenario.q0, 50.0, opts)


def test_best_motion_respects_speed_and_joint_limits(canonical: tuple[Scenario, ReachResult]) -> None:
    scenario, result = canonical
    robot, motion = scenario.robot, result.motion
    assert result.exists and len(motion.times) == 51
    step = np.abs(np.diff(motion.q, axis=0))
    assert np.all(step <= robot.velocity_limits * result.dt + 1e-9)
    assert np.all(motion.q >= robot.lower_limits - 1e-9) and np.all(motion.q <= robot.upper_limits + 1e-9)
    # every sample after q0 puts the hand on the path
    for t, q in zip(motion.times[1:], motion.q[1:], strict=True):
        data = robot.model.createData()
        pin.framesForwardKinematics(robot.model, data, q)
        np.testing.assert_allclose(data.oMf[robot.tip_frame_id].translation[:2], scenario.path.position(t), atol=1e-9)
    # the elbow changes branch only through the stretched wrist
    for k in np.flatnonzero(np.diff(motion.branch) != 0):
        assert abs(motion.q[k, 3]) + abs(motion.q[k + 1, 3]) <= robot.velocity_limits[3] * result.dt + 1e-9
    assert motion.min_S == pytest.approx(result.best_min_S) and motion.min_S > 0


def test_best_motion_is_collision_free_under_the_exact_check(canonical: tuple[Scenario, ReachResult]) -> None:
    """The linear interpolation between the samples (20 points per step), checked on the robot with its
    URDF collision geometry through Pinocchio + Coal (the simulator's exact check)."""
    scenario, result = canonical
    exact = Evaluator(scenario.exact_robot(), scenario.scene, scenario.index, scenario.potential, method="general")
    motion = result.motion
    fine = np.linspace(motion.times[0], motion.times[-1], 20 * (len(motion.times) - 1) + 1)
    Q = np.stack([motion.at(t) for t in fine])
    check = exact(Q, 0.0)  # static scene
    assert not check.collision.any()
    assert check.min_distance.min() > 0


def test_spatial_robot_gets_the_typed_error(panda: Robot) -> None:
    path = HandPath(np.array([[0.4, 0.0, 0.4], [0.4, 0.2, 0.4]]), 2.0)
    with pytest.raises(PlanarOnlyError, match=r"^reach-map: planar arms only \(robot 'panda' is spatial\)$"):
        reach_over_time(panda, Evaluator(panda), path, panda.neutral(), 2.0)


@pytest.mark.parametrize(("field", "value", "message"), [
    ("resolution_deg", 0, r"^resolution_deg must lie in \(0, 90\], got 0\.0$"),
    ("resolution_deg", True, r"^resolution_deg must be a finite number, got True; valid: numbers in \(0, 90\]$"),
    ("steps", 2.5, r"^steps must be an integer, got 2\.5; valid: integers >= 1$"),
    ("steps", 0, r"^steps must be >= 1, got 0$"),
    ("max_step_cells", "3", r"^max_step_cells must be an integer, got '3'; valid: integers >= 1$"),
    ("s_min", float("nan"), r"^s_min must be finite, got nan$"),
    ("s_min", -1.0, r"^s_min must be >= 0, got -1\.0$"),
    ("velocity_scale", 1.5, r"^velocity_scale must lie in \(0, 1\], got 1\.5$"),
    ("obstacle_substeps", True, r"^obstacle_substeps must be an integer, got True; valid: integers >= 1$"),
    ("cross_adjacency_deg", 200, r"^cross_adjacency_deg must lie in \[0, 180\], got 200\.0$"),
    ("map_times", -1, r"^map_times must be >= 0, got -1$"),
    ("start_families", 1, r"^start_families must be true or false, got 1$"),
])
def test_options_name_the_bad_value(field: str, value: object, message: str) -> None:
    with pytest.raises(ConfigurationError, match=message):
        ReachOptions(**{field: value})  # type: ignore[arg-type]


def test_options_take_integers_for_numbers() -> None:
    options = ReachOptions(resolution_deg=4, s_min=1, map_times=0)
    assert options.resolution_deg == 4.0 and isinstance(options.resolution_deg, float)
    assert options.s_min == 1.0 and isinstance(options.s_min, float) and options.map_times == 0


def test_time_step_too_short_for_the_grid(planar4: Robot) -> None:
    path = HandPath(np.array([[1.6, 0.4], [1.2, 1.0]]), 1.0)
    q0 = start_on_path(planar4, path, (0.2, 0.9), 1)
    with pytest.raises(ConfigurationError, match=r"time step 0\.01 s lets joint 1 move only 0\.573 deg.*fewer steps"):
        reach_over_time(planar4, Evaluator(planar4), path, q0, 1.0, ReachOptions(resolution_deg=2.0, steps=100))


def test_all_gene_offsets_at_once_equal_one_offset_at_a_time(planar4: Robot) -> None:
    """``targets`` over ``K`` offsets, as the vectorised transitions use it, is the ``K`` single-offset calls."""
    red = PlanarRedundancy(planar4)
    model, _ = grid_model(planar4, red, ReachOptions(resolution_deg=10.0), 1.0, np.zeros(4))
    wrapped = dataclasses.replace(model, periodic=np.array([True, False]))  # one periodic gene axis as well
    rng = np.random.default_rng(3)
    for grid in (model, wrapped):
        gene_index = np.stack([rng.integers(0, n, 200) for n in grid.shape], axis=1)
        gene_index[:2] = [[grid.shape[0] - 1, 0], [0, grid.shape[1] - 1]]  # at the edges
        flat, ok = targets(grid, gene_index, grid.offsets)
        assert flat.shape == ok.shape == (len(grid.offsets), 200)
        for k, offset in enumerate(grid.offsets):
            one_flat, one_ok = targets(grid, gene_index, offset)
            np.testing.assert_array_equal(flat[k], one_flat)
            np.testing.assert_array_equal(ok[k], one_ok)
    step = np.array([1, 0])  # off the top edge of gene 1: lost on a bounded axis, wrapped to 0 on a periodic one
    top = np.array([[model.shape[0] - 1, 5]])
    assert not targets(model, top, step)[1][0]
    assert targets(wrapped, top, step)[1][0] and targets(wrapped, top, step)[0][0] == 5 * model.strides[1]


# -------------------------------------------------------------------------------- CLI, oracle


def test_cli_reach_map_json_and_files(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    code = main(["reach-map", str(SCENARIOS / "planar_free.toml"), "--resolution", "6", "--steps", "10",
                 "--out", str(tmp_path), "--json"])
    assert code == 0
    report = json.loads(capsys.readouterr().out)
    assert report["scenario"] == "planar_free" and report["exists"] is True
    assert report["best_min_S"] > 0 and (report["commit_time"] is None or 0 <= report["commit_time"] <= 5)
    assert report["grid"]["steps"] == 10 and report["grid"]["gene_cells_per_step"] == [3, 3]
    assert len(report["motion"]["times"]) == 11
    for name in ("reach_maps.png", "reach_motion.png", "reach.json", "reach_motion.npz"):
        assert (tmp_path / name).stat().st_size > 0
    saved = np.load(tmp_path / "reach_motion.npz")
    assert saved["q"].shape == (11, 4)


def test_cli_reach_map_table(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["reach-map", str(SCENARIOS / "planar_free.toml"), "--resolution", "6", "--steps", "10"]) == 0
    out = capsys.readouterr().out
    for label in ("verdict", "best min S", "commit time", "time taken", "a collision-free tracking motion exists"):
        assert label in out


def test_cli_reach_map_takes_enough_steps_for_the_genes_speed_by_default(capsys: pytest.CaptureFixture[str],
                                                                         tmp_path: Path) -> None:
    """Without --steps, the oracle's model: at least 50 steps, more where a gene could not move at half its joint
    speed limit (planar_free made 40 s long: 0.5 rad/s x 40 s / (3 cells x 6 deg) -> 64 steps); --steps is kept."""
    text = (SCENARIOS / "planar_free.toml").read_text().replace("duration = 5.0", "duration = 40.0")
    assert text.count("duration = 40.0") == 2
    scenario = tmp_path / "long.toml"
    scenario.write_text(text)
    assert main(["reach-map", str(scenario), "--resolution", "6", "--json"]) == 0
    grid = json.loads(capsys.readouterr().out)["grid"]
    assert grid["steps"] == 64 and grid["resolution_deg"] == 6
    assert min(grid["gene_speed_deg_s"]) >= 0.5 * np.degrees(1.0)
    assert main(["reach-map", str(scenario), "--resolution", "6", "--steps", "20", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["grid"]["steps"] == 20


def test_cli_reach_map_spatial_robot_runs_the_sampled_search(capsys: pytest.CaptureFixture[str],
                                                              tmp_path: Path) -> None:
    """``panda_crossing`` (10 s): the sampled search finds a motion; the printed verdict, the JSON and the files."""
    assert main(["reach-map", str(SCENARIOS / "panda_crossing.toml"), "--json", "--out", str(tmp_path)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["search"] == "sampled" and summary["exists"] and summary["reached"] == 10.0
    assert summary["verdict"].startswith("a collision-free tracking motion was found to t = 10.00 s")
    assert summary["best_min_S"] > 0 and summary["options"]["beam"] == 48
    assert json.loads((tmp_path / "reach.json").read_text()) == summary
    motion = np.load(tmp_path / "reach_motion.npz")
    assert motion["q"].shape == (len(motion["times"]), 7) and motion["times"][-1] == pytest.approx(10.0)


def test_oracle_tracks_the_plan_without_collision() -> None:
    """planar_free with the oracle: it plans at its first command and follows the plan through eq. 19."""
    scenario = load_scenario(SCENARIOS / "planar_free.toml")
    result = simulate(scenario, "oracle")
    assert result.controller == "oracle"
    assert not result.collision.any()
    assert result.hand_error.max() < 5e-3
    assert result.targets.shape == (len(result.t), 1, 4)
    # the arm stays near its plan (the target is taken 0.1 s ahead on the plan)
    gap = np.abs(result.q - result.targets[:, 0]).max()
    assert gap < 0.15


@pytest.mark.parametrize(("duration", "share", "resolution", "steps"),
                         [(8.0, 0.5, 2.0, 50), (8.0, 1.0, 2.0, 77), (50.0, 0.5, 4.0, 120), (50.0, 1.0, 4.0, 239)])
def test_the_oracles_grid_lets_the_genes_move_fast_enough(planar4: Robot, duration: float, share: float,
                                                          resolution: float, steps: int) -> None:
    """fast_enough: the gene cap r h / Δt reaches the share of the joint speed limit with the fewest steps (never
    fewer than asked) on the finest grid (2°, else 4°, ...) whose nodes fit the budget (50 s at 2° and half speed
    would need 239 steps: 62 M nodes)."""
    opts = fast_enough(planar4, ORACLE_OPTIONS, duration, share)
    assert (opts.resolution_deg, opts.steps) == (resolution, steps)
    h, speed = np.radians(opts.resolution_deg), share * planar4.velocity_limits[:2].max()
    assert opts.max_step_cells * h / (duration / opts.steps) >= speed - 1e-9
    if opts.steps > ORACLE_OPTIONS.steps:  # no fewer steps would do
        assert opts.max_step_cells * h / (duration / (opts.steps - 1)) < speed
    def nodes(deg: float, n_steps: int) -> int:
        return (int(720 / deg) + 1) ** 2 * 2 * (n_steps + 1)  # planar4's genes: [-360, 360] deg, two branches

    assert nodes(resolution, opts.steps) <= MAX_GRID_NODES
    if resolution > 2.0:  # the finer grid would not fit
        assert nodes(2.0, int(np.ceil(duration * speed / (opts.max_step_cells * np.radians(2.0))))) > MAX_GRID_NODES


# ------------------------------------------------------------------------------------- horizon


@pytest.mark.parametrize(("plan_window", "window"), [(None, 3.0), (4.5, 4.5)])
def test_horizon_plans_only_over_its_window_every_half_preview_time(plan_window: float | None,
                                                                     window: float) -> None:
    """horizon is causal: each plan starts at its cycle's time and ends at t + plan_window (by default the last
    preview time, t + p t̃ = 3 s here; the 8 s path is not over yet); a new one every t̃ / 2 = 0.5 s."""
    scenario = generate("planar4", 1, 0).scenario()
    params = dataclasses.replace(scenario.controller.params, plan_window=plan_window)
    ctrl = make_controller(scenario, name="horizon", params=params)
    q, dt, plans = np.array(scenario.q0), 0.01, {}
    for k in range(151):
        qdot = ctrl.step(q, k * dt, dt)
        assert isinstance(ctrl.law, Horizon)
        motion = ctrl.law.planner.motion
        assert motion is not None
        plans[float(motion.times[0])] = float(motion.times[-1])
        q = integrate(scenario.robot, q, qdot, dt)
    assert list(plans) == pytest.approx([0.0, 0.5, 1.0, 1.5])
    assert [end - start for start, end in plans.items()] == pytest.approx([window] * 4)


def test_horizon_with_a_plan_latency_follows_each_plan_from_its_arrival() -> None:
    """plan_latency = 0.5 s (the replan period): the first plan (t = 0) is followed at once, the plan made at
    t = 0.5 s only from 1.0 s on, and so on; a latency longer than the replan period is refused."""
    scenario = generate("planar4", 1, 0).scenario()
    params = dataclasses.replace(scenario.controller.params, plan_latency=0.5)
    ctrl = make_controller(scenario, name="horizon", params=params)
    q, dt = np.array(scenario.q0), 0.01
    for k in range(151):
        t = k * dt
        qdot = ctrl.step(q, t, dt)
        assert isinstance(ctrl.law, Horizon)
        planner = ctrl.law.planner
        assert planner.motion is not None and planner.planned is not None
        made = 0.5 * math.floor(t / 0.5 + 1e-9)  # the last plan made
        followed = max(0.0, made - 0.5)
        assert float(planner.motion.times[0]) == pytest.approx(followed), t
        assert float(planner.planned.times[0]) == pytest.approx(made), t
        q = integrate(scenario.robot, q, qdot, dt)
    with pytest.raises(ConfigurationError, match=r"plan latency of 0\.6 s is longer than the replan period 0\.5 s"):
        make_controller(scenario, name="horizon", params=dataclasses.replace(params, plan_latency=0.6))


def test_horizon_finishes_a_bench_scene_where_the_qp_baseline_is_trapped() -> None:
    """Bench scene 1 (seed 0): qp, single, multi and reach all stay where plain tracking goes and are pushed
    63 mm off the path; horizon, seeing 3 s ahead like multi, finishes within 1 mm without collision."""
    scenario = generate("planar4", 1, 0).scenario()
    baseline = simulate(scenario, "qp").summary()
    assert not baseline["collided"] and baseline["max_hand_error"] > 0.05
    summary = simulate(scenario, "horizon").summary()
    assert summary["success"] and summary["max_hand_error"] < 1e-3


def test_horizon_refuses_a_bad_replan_period_or_window() -> None:
    with pytest.raises(ParameterError, match="replan_period"):
        ControllerParams(replan_period=0.0)
    with pytest.raises(ParameterError, match=r"plan_window.*-1"):
        ControllerParams(plan_window=-1.0)


@pytest.mark.parametrize(("field", "value", "message"), [
    ("replan_period", 0.0, r"^replan_period must be > 0, got 0\.0$"),
    ("window", float("nan"), r"^window must be finite, got nan$"),
    ("latency", -0.1, r"^latency must be a time >= 0 \[s\] or 'measured', got -0\.1$"),
    ("lookahead", "0.1", r"^lookahead must be a finite number, got '0\.1'; valid: numbers >= 0$"),
])
def test_plan_timing_names_the_bad_value(field: str, value: object, message: str) -> None:
    """The planner's timing (the oracle's and horizon's, and the routes') is checked by the validation layer."""
    with pytest.raises(ConfigurationError, match=message):
        PlanTiming(**{field: value})  # type: ignore[arg-type]


def test_two_or_more_bits_matches_a_popcount_on_every_bit_position() -> None:
    """The families' bit test (numpy 1.x has no ``bitwise_count``) against Python's own count of set bits."""
    rng = np.random.default_rng(3)
    singles = [1 << k for k in range(64)]
    values = [0, *singles, *(a | b for a, b in itertools.combinations(singles[::7], 2)), 2**64 - 1,
              *(int(v) for v in rng.integers(0, 2**64 - 1, 200, dtype=np.uint64, endpoint=True))]
    F = np.array(values, dtype=np.uint64)
    expected = [bin(v).count("1") >= 2 for v in values]
    assert two_or_more(F).tolist() == expected and sum(expected) > 200 and not any(two_or_more(F[1:65]))


@pytest.mark.parametrize(("times", "rows", "S"), [(0, 0, 0), (3, 2, 3), (3, 3, 2)])
def test_a_motion_without_one_sample_per_time_is_refused(times: int, rows: int, S: int) -> None:
    """The compiled sampling reads one row of q and one S per time, and at least one: anything else is refused when
    the motion is made, naming the shapes."""
    ints = np.zeros(times, dtype=np.int64)
    with pytest.raises(TrajectoryError, match=rf"got {times} times, q of shape \({rows}, 7\), S of shape \({S},\)"):
        ReachMotion(np.arange(float(times)), np.zeros((rows, 7)), np.zeros(S), ints, ints, 0.0, 0.0)


def test_motion_sample_is_np_interp_bit_for_bit() -> None:
    """``ReachMotion.sample`` (compiled) and ``at`` interpolate every joint at once with ``np.interp``'s arithmetic, and
    S as ``np.interp`` does: the same bits at the samples, between them and outside (held), NaN S included."""
    rng = np.random.default_rng(7)
    nan_between = 0
    for k in range(300):
        times = np.unique(rng.uniform(0.0, 3.0, rng.integers(1, 9)))
        q = rng.normal(size=(times.size, 7)) * 3.0
        S = rng.normal(size=times.size)
        if k % 3 == 0:  # a held motion's S is NaN; here one sample's or all
            S[rng.integers(0, times.size) if k % 2 else slice(None)] = np.nan
        ints = np.zeros(times.size, dtype=np.int64)
        motion = ReachMotion(times, q, S, ints, ints, 0.0, 0.0)
        query = np.array([*rng.uniform(-1.0, 4.0, 10), *times])
        got_q, got_S = motion.sample(query)
        for i, t in enumerate(query):
            expected = np.array([np.interp(min(max(t, times[0]), times[-1]), times, column) for column in q.T])
            np.testing.assert_array_equal(got_q[i], expected)
            np.testing.assert_array_equal(motion.at(t), expected)
            np.testing.assert_array_equal(got_S[i], np.interp(t, times, S))
            nan_between += bool(np.isnan(got_S[i]) and times[0] < t < times[-1] and not np.isnan(S).all())
    assert nan_between > 20  # the NaN branches are checked too
