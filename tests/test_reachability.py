"""Reachability over time (search/reachability.py): the DP against brute force on tiny grids, its best
motion under the exact check, the typed error for spatial arms, and the ``reach-map`` command."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from previewctl.index.evaluator import Evaluator
from previewctl.path import HandPath
from previewctl.planar.redundancy import PlanarRedundancy
from previewctl.robot.load import load_robot, shipped_robots_dir
from previewctl.robot.model import Robot
from previewctl.scene.motion import ConstantVelocity, Static
from previewctl.scene.shapes import Obstacle, Scene, Sphere
from previewctl.search.reachability import ReachOptions, ReachResult, reach_over_time
from previewctl.search.redundancy import wrap_angle
from previewctl.types import Array

LINK = 0.75  # [m], planar4's links
RADIUS = 0.03  # [m], its capsules


def planar3_urdf(tmp: Path) -> Path:
    """planar4 without its last link: a 3-joint planar arm (one gene)."""
    text = (shipped_robots_dir() / "planar4.urdf").read_text()
    start = text.index('<joint name="joint4"')
    end = text.index('<joint name="tip_joint"')
    text = text[:start] + text[end:].replace('<parent link="link4"/>', '<parent link="link3"/>', 1)
    out = tmp / "planar3.urdf"
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
    """Every path through the tiny grid, enumerated explicitly, with transitions checked pair by pair."""

    def __init__(self, robot: Robot, evaluator: Evaluator, path: HandPath, q0: Array, duration: float,
                 opts: ReachOptions) -> None:
        red = PlanarRedundancy(robot)
        g, n = red.g, robot.nq
        N, h = opts.steps, np.radians(opts.resolution_deg)
        dt = duration / N
        count = round(360 / opts.resolution_deg)
        axis = np.arange(count) * 2 * np.pi / count
        delta = robot.velocity_limits * opts.velocity_scale * dt
        cap = min(opts.max_step_cells, int(np.floor(delta[0] / h + 1e-9))) * h
        rho = sweep_radii(robot)
        self.times = np.arange(N + 1) * dt
        # constant-velocity or static obstacles: the travel per step is |v| dt
        travel = max((float(np.linalg.norm(np.diff(o.motion.positions([0.0, 1.0]), axis=0))) * dt
                      for o in evaluator.scene.obstacles), default=0.0)
        # every cell of every layer: genes, branch, q, signed elbow, distances, S
        genes = np.array(list(itertools.product(axis, repeat=g))) if g else np.zeros((1, 0))
        self.genes = np.concatenate([genes, genes])
        self.branch = np.repeat([0, 1], len(genes))
        self.layers = []
        for t in self.times:
            Q, ok = red.solve(self.genes, self.branch, path.position(t))
            S = np.full(len(Q), -1.0)
            d = np.full((len(Q), len(robot.guarded_links)), -np.inf)
            ev = evaluator(Q[ok], t)
            S[ok], d[ok] = ev.S, ev.link_distances
            beta = np.abs(wrap_angle(Q[:, n - 1])) * np.where(self.branch == 0, 1, -1)
            self.layers.append((Q, beta, d, S, ok & (opts.s_min < S)))
        ev0 = evaluator(q0, 0.0)
        genes0 = wrap_angle(q0[:g])
        beta0 = q0[n - 1]
        self.q0_S = float(ev0.S[0])

        def allowed(ga: Array, qa: Array, ba: Array, da: Array, gb: Array, qb: Array, bb: Array, db: Array) -> Array:
            """Pairwise: sources a (rows) to destinations b (columns)."""
            dgene = np.abs(wrap_angle(gb[None, :, :] - ga[:, None, :]))  # (A, B, g)
            dq1 = np.abs(wrap_angle(qb[None, :, n - 2] - qa[:, None, n - 2]))
            dbeta = np.abs(bb[None, :] - ba[:, None])
            ok = np.all(dgene <= cap + 1e-9, axis=2) & np.all(dgene <= delta[:g] + 1e-9, axis=2)
            ok &= (dq1 <= delta[n - 2]) & (dbeta <= delta[n - 1])
            moves = np.concatenate([dgene, dq1[..., None], dbeta[..., None]], axis=2)  # (A, B, n)
            sweep = moves @ rho  # (A, B, L)
            ok &= np.all(da[:, None, :] + db[None, :, :] > sweep + travel, axis=2)
            return ok

        self.transitions = []
        for k in range(N):
            if k == 0:
                src = (genes0[None], q0[None], np.array([beta0]), ev0.link_distances)
            else:
                Qa, ba, da, _, _ = self.layers[k]
                src = (self.genes, Qa, ba, da)
            Qb, bb, db, _, feas_b = self.layers[k + 1]
            T = allowed(*src, self.genes, Qb, bb, db)
            if k > 0:
                T &= self.layers[k][4][:, None]
            T &= feas_b[None, :]
            self.transitions.append(T)
        # enumerate every feasible path prefix, layer by layer
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
        S = np.stack([self.layers[i + 1][3][paths[:, i]] for i in range(k)], axis=1)
        return S.min(axis=1), S.sum(axis=1)


def components(cells: set[int], genes_per_branch: int, g: int, count: int, beta: Array, cross: float) -> list[set[int]]:
    """Connected components by breadth-first search (8-neighbours within a branch, branch switch where
    |beta| <= cross on both sides)."""
    def neighbours(c: int) -> list[int]:
        b, p = divmod(c, genes_per_branch)
        idx = np.unravel_index(p, (count,) * g)
        out = []
        for shift in itertools.product((-1, 0, 1), repeat=g):
            if any(shift):
                moved = tuple((i + s) % count for i, s in zip(idx, shift, strict=True))
                out.append(b * genes_per_branch + int(np.ravel_multi_index(moved, (count,) * g)))
        other = (1 - b) * genes_per_branch + p
        if abs(beta[c]) <= cross and abs(beta[other]) <= cross:
            out.append(other)
        return out

    left, found = set(cells), []
    while left:
        seed = left.pop()
        comp, todo = {seed}, [seed]
        while todo:
            for nb in neighbours(todo.pop()):
                if nb in left:
                    left.remove(nb)
                    comp.add(nb)
                    todo.append(nb)
        found.append(comp)
    return found


def flat(result: ReachResult, k: int, which: str) -> set[int]:
    grid = getattr(result, which)[k].reshape(-1)
    return set(np.flatnonzero(grid).tolist())


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
    # forward reachable sets, layer by layer
    for k in range(1, N + 1):
        expected = set(brute.prefixes[k][:, -1].tolist()) if len(brute.prefixes[k]) else set()
        assert flat(result, k, "reachable") == expected, f"layer {k}"
    if K == 0:
        assert np.isnan(result.best_min_S)
        return result
    # best bottleneck, then best total among the bottleneck-optimal paths
    mins, sums = brute.scores(K)
    s_star = mins.max()
    assert result.best_min_S == pytest.approx(s_star, rel=1e-12)
    best_total = sums[mins >= s_star].max()
    motion = result.motion
    assert motion.min_S == pytest.approx(s_star, rel=1e-12)
    assert motion.total_S == pytest.approx(best_total, rel=1e-9)
    # the motion is one of the enumerated paths
    cells = tuple(motion.cells[1:].tolist())
    assert cells in {tuple(p) for p in brute.prefixes[K].tolist()}
    # viable tube, end families and commit time (when a motion exists)
    if K == N:
        full = brute.prefixes[N]
        for k in range(1, N + 1):
            assert flat(result, k, "viable") == set(full[:, k - 1].tolist()), f"viable layer {k}"
        ends = set(full[:, -1].tolist())
        per_branch = len(brute.genes) // 2
        g = robot.nq - 2
        count = round(360 / opts.resolution_deg)
        comps = components(ends, per_branch, g, count, brute.layers[N][1], np.radians(opts.cross_adjacency_deg))
        assert len(result.end_families) == len(comps)
        assert sorted(f.cells for f in result.end_families) == sorted(len(c) for c in comps)
        label = {c: i for i, comp in enumerate(comps) for c in comp}
        family_of_path = np.array([label[c] for c in full[:, -1]])
        shared = [len(comps) >= 2]  # q0 reaches every end family
        for k in range(1, N + 1):
            many = False
            for cell in set(full[:, k - 1].tolist()):
                if len(set(family_of_path[full[:, k - 1] == cell].tolist())) >= 2:
                    many = True
                    break
            shared.append(many)
        expected = max((k for k in range(N + 1) if shared[k]), default=None)
        assert result.commit_time == (None if expected is None else pytest.approx(brute.times[expected]))
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


@pytest.mark.parametrize("case", sorted(PLANAR4_CASES))
def test_planar4_matches_brute_force(planar4: Robot, case: str) -> None:
    """Two genes on a 45 deg grid, 4 steps of 0.8 s (one cell per step): reachable sets, bottleneck,
    tie-break, viable tube, end families and commit time all equal the enumeration of every path."""
    start, end, discs, genes, branch = PLANAR4_CASES[case]
    path = HandPath(np.array([start, end]), 3.2)
    scene = Scene(tuple(Obstacle(f"disc{i}", Sphere(r), Static(np.array([*c, 0.0]))) for i, (r, c) in enumerate(discs)))
    q0 = start_on_path(planar4, path, genes, branch)
    opts = ReachOptions(resolution_deg=45.0, steps=4, max_step_cells=3)
    result = check_against_brute(planar4, scene, path, q0, 3.2, opts)
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
