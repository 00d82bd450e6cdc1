"""Tests of :mod:`previewctl.search` (explore, ga, genes) and ``previewctl map``: global exploration
and the 1-step GA on the paper's planar arm (and a quick look at the Panda)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from previewctl.cli.main import main
from previewctl.errors import ConfigurationError, ParameterError, UnreachableTargetError
from previewctl.index.evaluator import Evaluator
from previewctl.index.load import load_robot
from previewctl.robot.model import Robot
from previewctl.scene.motion import Static
from previewctl.scene.shapes import Box, Obstacle, Scene, Sphere
from previewctl.search.explore import Landscape, explore
from previewctl.search.ga import OneStepGA, step_together
from previewctl.search.genes import halton
from previewctl.search.maps import redundancy_map
from previewctl.search.planar import PlanarRedundancy
from previewctl.search.redundancy import wrap_angle

# The paper's hand positions A-F (section 7: A = (10 cm, 140 cm), five 75 cm segments).
PATH = np.array([[0.10, 1.40], [0.85, 1.40], [0.85, 0.65], [1.60, 0.65], [1.60, -0.10], [2.35, -0.10]])


def box_scene() -> Scene:
    """A table under the path and a ball beside it (both straddle the arm's plane)."""
    return Scene((
        Obstacle("table", Box((1.2, 0.4, 0.4)), Static(np.array([1.3, -0.55, 0.0]))),
        Obstacle("ball", Sphere(0.15), Static(np.array([0.3, 0.6, 0.0]))),
    ))


@pytest.fixture(scope="module")
def evaluator(planar4: Robot) -> Evaluator:
    return Evaluator(planar4, box_scene())


@pytest.fixture(scope="module")
def landscapes(planar4: Robot, evaluator: Evaluator) -> list[Landscape]:
    return [explore(planar4, evaluator, p) for p in PATH]


# ------------------------------------------------------------------------------------- explore


def test_grid_shape_and_best(planar4: Robot, landscapes: list[Landscape]) -> None:
    land = landscapes[2]
    assert land.method == "grid"
    assert land.S_map is not None and land.S_map.shape == (2, 360, 360)
    assert land.S.size == 259_200 and land.genes.shape == (259_200, 2)
    np.testing.assert_allclose(np.degrees(land.axes[0]), np.arange(360.0), atol=1e-9)
    i = int(np.argmax(land.S))
    assert land.best.S == land.S[i] == land.S_map.max()
    assert land.best.branch == land.branch[i]
    np.testing.assert_allclose(land.best.q[:2], wrap_angle(land.genes[i]))
    assert land.best.S > 0
    # S < 0 exactly where the hand cannot reach or the arm collides
    assert np.all(land.S[~land.reachable] < 0)


def test_grid_best_equals_brute_force(planar4: Robot) -> None:
    """A 10 deg grid, candidates solved and evaluated one by one through Pinocchio + Coal."""
    scene = box_scene()
    fast = Evaluator(planar4, scene)
    slow = Evaluator(planar4, scene, method="general")
    red = PlanarRedundancy(planar4)
    target = PATH[2]
    land = explore(planar4, fast, target, resolution_deg=10.0)
    assert land.S.size == 2 * 36 * 36
    brute = np.empty(land.S.size)
    for k in range(land.S.size):
        Q, ok = red.solve(land.genes[k : k + 1], land.branch[k : k + 1], target)
        brute[k] = slow(Q[0]).S[0] if ok[0] else slow.potential.collision_value
    # two computations of the same S (planar kernels against Pinocchio + Coal): they agree to rounding, about 1e-6
    # relative with numpy 1.25's BLAS (1.01e-6 seen on one of 2592 cells), far below any real error
    np.testing.assert_allclose(land.S, brute, rtol=1e-5, atol=1e-6)
    assert abs(land.best.S - brute.max()) <= 1e-9 * brute.max()


def _neighbours(S_map: np.ndarray, b: int, i: int, j: int) -> np.ndarray:
    n1, n2 = S_map.shape[1:]
    return np.array([S_map[b, (i + di) % n1, (j + dj) % n2]
                     for di in (-1, 0, 1) for dj in (-1, 0, 1) if di or dj])


def test_peaks_are_distinct_local_maxima(planar4: Robot, landscapes: list[Landscape]) -> None:
    periodic = planar4.joints.full_turn
    for land in landscapes:
        assert land.S_map is not None
        assert 1 <= len(land.peaks) <= 4
        assert land.peaks[0].S == land.best.S
        assert [p.S for p in land.peaks] == sorted((p.S for p in land.peaks), reverse=True)
        for peak in land.peaks:
            i, j = (round(np.degrees(g)) % 360 for g in np.mod(peak.genes, 2 * np.pi))
            assert land.S_map[peak.branch, i, j] == peak.S > 0
            assert np.all(_neighbours(land.S_map, peak.branch, i, j) <= peak.S)
        angles = planar4.angles_of(np.array([p.q for p in land.peaks]))
        for a in range(len(angles)):
            for b in range(a + 1, len(angles)):
                diff = np.where(periodic, wrap_angle(angles[a] - angles[b]), angles[a] - angles[b])
                assert np.linalg.norm(diff) >= 0.35


def test_peaks_without_separation_are_the_best_maxima_once_each(planar4: Robot, evaluator: Evaluator) -> None:
    land = explore(planar4, evaluator, PATH[2], min_separation=0.0, top_k=6)
    assert land.S_map is not None
    is_max = land.S_map > 0
    for shift in [(di, dj) for di in (-1, 0, 1) for dj in (-1, 0, 1) if di or dj]:
        is_max &= land.S_map >= np.roll(land.S_map, shift, axis=(1, 2))
    maxima = land.S_map[is_max]
    assert [p.S for p in land.peaks] == sorted(maxima, reverse=True)[:6]
    assert len({(p.branch, *np.round(p.genes, 9)) for p in land.peaks}) == 6


def test_distinct_walks_blocks_like_one_pass() -> None:
    from previewctl.search.genes import distinct

    angles = np.random.default_rng(0).uniform(-np.pi, np.pi, (300, 4))
    periodic = np.array([True, True, False, False])
    one_pass = distinct(angles, periodic, 2.0, 40, block=300)
    assert len(one_pass) > 10
    assert distinct(angles, periodic, 2.0, 40, block=7) == one_pass


def test_explore_unreachable_target_raises(planar4: Robot, evaluator: Evaluator) -> None:
    with pytest.raises(UnreachableTargetError, match=r"target \[3.5, 0.5, 0.0\]"):
        explore(planar4, evaluator, np.array([3.5, 0.5]))
    with pytest.raises(ConfigurationError, match="resolution_deg"):
        explore(planar4, evaluator, PATH[0], resolution_deg=0.0)


def test_explore_samples_on_panda() -> None:
    robot = load_robot("panda")
    scene = Scene((Obstacle("ball", Sphere(0.08), Static(np.array([0.35, 0.0, 0.35]))),))
    ev = Evaluator(robot, scene)
    target = np.array([0.5, 0.1, 0.4])
    land = explore(robot, ev, target, samples=96, rng=np.random.default_rng(0), top_k=3)
    assert land.method == "samples" and land.S_map is None and land.S.size == 96
    assert land.best.S == land.S.max() > 0
    tip = ev(land.best.q).tip_position[0]
    assert np.linalg.norm(tip - target) < 1e-4
    # a sampled peak has no better sample within the separation radius
    periodic = robot.joints.full_turn
    Q = np.array([redundancy_map(robot).solve(land.genes[i : i + 1], 0, target)[0][0] for i in range(96)])
    angles = robot.angles_of(Q)
    for peak in land.peaks:
        d = np.linalg.norm(np.where(periodic, wrap_angle(angles - peak.q), angles - peak.q), axis=1)
        assert np.all(land.S[d < 0.35] <= peak.S)


def test_halton_points() -> None:
    pts = halton(8, 2)
    np.testing.assert_allclose(pts[:4, 0], [0.5, 0.25, 0.75, 0.125])
    np.testing.assert_allclose(pts[:3, 1], [1 / 3, 2 / 3, 1 / 9])
    shifted = halton(1000, 5, np.random.default_rng(0))
    assert shifted.shape == (1000, 5) and np.all((shifted >= 0) & (shifted < 1))


# ------------------------------------------------------------------------------------------- GA


def test_ga_is_reproducible(planar4: Robot, evaluator: Evaluator) -> None:
    red = redundancy_map(planar4)
    runs = []
    for _ in range(2):
        ga = OneStepGA(planar4, evaluator, red, np.random.default_rng(42))
        for _ in range(8):
            best = ga.step(PATH[1], 0.0)
        runs.append((best, ga.population_genes))
    assert runs[0][0].S == runs[1][0].S
    np.testing.assert_array_equal(runs[0][1], runs[1][1])
    other = OneStepGA(planar4, evaluator, red, np.random.default_rng(43))
    other.step(PATH[1], 0.0)
    assert not np.array_equal(other.population_genes, runs[0][1][: other.population])


@pytest.mark.parametrize("position", range(6), ids=list("ABCDEF"))
def test_ga_reaches_grid_optimum_within_one_percent(
    planar4: Robot, evaluator: Evaluator, landscapes: list[Landscape], position: int
) -> None:
    ga = OneStepGA(planar4, evaluator, redundancy_map(planar4), np.random.default_rng(7))
    previous = -np.inf
    for _ in range(50):
        best = ga.step(PATH[position], 0.0)
        assert previous <= best.S + 1e-9  # elitism on a static landscape
        previous = best.S
    assert best.S >= 0.99 * landscapes[position].best.S
    tip = evaluator(best.q).tip_position[0, :2]
    np.testing.assert_allclose(tip, PATH[position], atol=1e-9)
    peaks = ga.peaks()
    assert 1 <= len(peaks) <= 4 and peaks[0].S == best.S and all(p.S > 0 for p in peaks)


def test_ga_tracks_a_moved_target_without_reset(planar4: Robot, evaluator: Evaluator) -> None:
    ga = OneStepGA(planar4, evaluator, redundancy_map(planar4), np.random.default_rng(3))
    start = PATH[3]
    for _ in range(50):
        ga.step(start, 0.0)
    moved = start + np.array([0.03, 0.04])  # 5 cm
    optimum = explore(planar4, evaluator, moved).best.S
    results = [ga.step(moved, 0.0).S for _ in range(5)]
    assert ga.generation == 55
    assert results[0] >= 0.95 * optimum  # the old peak, re-evaluated, is already close
    assert results[-1] >= 0.99 * optimum


def test_ga_seed_injects_a_configuration(planar4: Robot, evaluator: Evaluator, landscapes: list[Landscape]) -> None:
    ga = OneStepGA(planar4, evaluator, redundancy_map(planar4), np.random.default_rng(5), population=16)
    ga.seed(landscapes[4].best.q)
    best = ga.step(PATH[4], 0.0)
    assert best.S >= landscapes[4].best.S - 1e-9
    ga.seed(landscapes[4].peaks[-1].q[None, :])
    ga.step(PATH[4], 0.0)
    assert np.any(np.all(np.isclose(ga.population_genes, wrap_angle(landscapes[4].peaks[-1].genes)), axis=1))


def test_ga_bad_options(planar4: Robot, evaluator: Evaluator) -> None:
    red = redundancy_map(planar4)
    with pytest.raises(ParameterError, match="population must be >= 4, got 2"):
        OneStepGA(planar4, evaluator, red, np.random.default_rng(0), population=2)
    with pytest.raises(ParameterError, match=r"unknown key 'mutaton_scale' \(did you mean 'mutation_scale'\?\); "
                       r"valid keys of GAOptions: population, elite, mutation_scale"):
        OneStepGA(planar4, evaluator, red, np.random.default_rng(0), mutaton_scale=0.1)
    with pytest.raises(ParameterError, match=r"elite \+ top_k must be below population: 2 \+ 4 >= 6"):
        OneStepGA(planar4, evaluator, red, np.random.default_rng(0), population=6)
    with pytest.raises(ParameterError, match="rng"):
        OneStepGA(planar4, evaluator, red, 0)  # type: ignore[arg-type]
    with pytest.raises(ConfigurationError, match="after the first step"):
        _ = OneStepGA(planar4, evaluator, red, np.random.default_rng(0)).best


def test_ga_on_panda_reaches_target() -> None:
    robot = load_robot("panda")
    ev = Evaluator(robot, Scene((Obstacle("ball", Sphere(0.08), Static(np.array([0.35, 0.0, 0.35]))),)))
    ga = OneStepGA(robot, ev, redundancy_map(robot), np.random.default_rng(0), population=24)
    target = np.array([0.5, 0.1, 0.4])
    scores = [ga.step(target, 0.0).S for _ in range(6)]
    assert scores[-1] > 0 and scores[-1] >= scores[0]
    assert np.linalg.norm(ev(ga.best.q).tip_position[0] - target) < 1e-4


@pytest.mark.parametrize("name", ["panda", "planar4"])
def test_step_together_equals_stepping_each(name: str) -> None:
    """One shared Newton projection (or, for the planar map, none to share) changes nothing: the same
    populations and best candidates as stepping each GA on its own."""
    robot = load_robot(name)
    ev = Evaluator(robot, Scene((Obstacle("ball", Sphere(0.08), Static(np.array([0.35, 0.0, 0.35]))),)))
    red = redundancy_map(robot)
    targets = [np.array([0.5, 0.1, 0.4]), np.array([0.45, 0.15, 0.45])] if name == "panda" else \
        [np.array([0.85, 0.65]), np.array([0.9, 0.6])]

    def gas() -> list[OneStepGA]:
        return [OneStepGA(robot, ev, red, np.random.default_rng(k), population=16) for k in range(2)]

    together, alone = gas(), gas()
    for generation in range(3):
        times = [0.1 * generation, 0.1 * generation + 1.0]
        best_together = step_together(together, targets, times)
        best_alone = [ga.step(target, t) for ga, target, t in zip(alone, targets, times, strict=True)]
        for a, b, ga, gb in zip(best_together, best_alone, together, alone, strict=True):
            assert a.S == b.S
            np.testing.assert_array_equal(a.q, b.q)
            np.testing.assert_array_equal(ga.population_genes, gb.population_genes)
    with pytest.raises(ConfigurationError, match="one target and one time per search"):
        step_together(together, targets[:1], [0.0, 1.0])


# ------------------------------------------------------------------------------------ CLI, figures


def test_cli_map_json(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    out = tmp_path / "map.png"
    code = main(["map", "--robot", "planar4", "--target", "0.85,0.65", "--resolution", "5", "--json",
                 "--out", str(out), "--surface", "--top-k", "3"])
    assert code == 0
    report = json.loads(capsys.readouterr().out)
    assert report["method"] == "grid" and report["candidates"] == 2 * 72 * 72
    assert len(report["best"]["genes_deg"]) == 2 and 0 <= report["best"]["genes_deg"][0] < 360
    assert report["best"]["S"] == report["peaks"][0]["S"] and len(report["peaks"]) <= 3
    assert out.is_file() and (tmp_path / "map_surface.png").is_file()
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_map_unreachable(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["map", "--target", "4,0"]) == 2
    err = capsys.readouterr().err
    assert "out of reach" in err and "[4.0, 0.0, 0.0]" in err
