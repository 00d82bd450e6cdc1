"""Tests of :mod:`previewctl.control.peaks` and the coherent preview mode: peak identity, the GA's
branch lock, blends within one family, and the paper-literal mode unchanged."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from previewctl.control.base import ControlState
from previewctl.control.factory import compose
from previewctl.control.nullspace import wrapped_difference
from previewctl.control.params import SPATIAL_NEIGHBOURS, ControllerParams, ControllerSpec
from previewctl.control.peaks import PeakTracker
from previewctl.index.evaluator import Evaluator
from previewctl.kinematics import kinematics
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.scene.shapes import Scene
from previewctl.search.ga import OneStepGA
from previewctl.search.planar import PlanarRedundancy
from previewctl.sim.log import RunResult
from previewctl.sim.loop import simulate
from previewctl.sim.paper import canonical_scenario


def _options(*pairs: tuple[list[float], float]) -> tuple[np.ndarray, np.ndarray]:
    """A search's individuals ``Q`` and their ``S`` from ``(q, S)`` pairs."""
    return np.array([q for q, _ in pairs], dtype=float), np.array([S for _, S in pairs], dtype=float)


def _tracker(**options: float) -> PeakTracker:
    settings = {"track_radius": 0.5, "settle_frames": 4, **options}
    return PeakTracker(lambda Q: Q, np.ones(4, dtype=bool), **settings)  # type: ignore[arg-type]


A, B = [0.5, 1.0, -1.0, 0.5], [2.0, -1.0, 1.0, -0.5]  # two peaks far apart in joint space
REACH = np.full(4, 1.0)  # [rad] each joint's move in one preview step (planar4: 1 rad/s, t̃ = 1 s)


def test_peak_identity_survives_a_small_perturbation_of_the_landscape() -> None:
    tracker = _tracker()
    first = tracker.update(*_options((A, 100.0), (B, 120.0)), np.array(A) + 0.1, REACH)
    assert first is not None and np.allclose(first.q, A)  # the arm's own basin, not the best peak
    # the landscape shifts a little and B edges ahead: keep A's identity
    moved = [a + 0.05 for a in A]
    second = tracker.update(*_options((B, 115.0), (moved, 100.0)), np.array(A), REACH)
    assert second is not None and np.allclose(second.q, moved) and not second.switched


def test_a_better_peak_in_another_basin_does_not_take_over() -> None:
    tracker = _tracker()
    tracker.update(*_options((A, 100.0), (B, 90.0)), np.array(A), REACH)
    kept = tracker.update(*_options((A, 100.0), (B, 400.0)), np.array(A), REACH)
    assert kept is not None and np.allclose(kept.q, A) and not kept.switched


def test_the_best_individual_near_the_last_target_carries_the_peak() -> None:
    tracker = _tracker()
    tracker.update(*_options((A, 100.0), (B, 90.0)), np.array(A), REACH)
    climbed = [a + 0.2 for a in A]  # within track_radius, and better: the same peak, moved uphill
    chosen = tracker.update(*_options((A, 100.0), (climbed, 110.0), (B, 120.0)), np.array(A), REACH)
    assert chosen is not None and np.allclose(chosen.q, climbed) and not chosen.switched


def test_a_lost_peak_is_replaced_by_the_best_survivor_within_reach_of_the_arm_before() -> None:
    tracker = _tracker()
    tracker.update(*_options((A, 100.0)), np.array(A), REACH)
    near = [a + 0.7 for a in A]  # beyond track_radius (|Δ| = 1.4 rad), within reach (0.7 rad per joint)
    nearer = [a + 0.6 for a in A]  # also within reach, and nearer, but worse
    chosen = tracker.update(*_options((B, 500.0), (near, 50.0), (nearer, 40.0)), np.array(A), REACH)
    assert chosen is not None and np.allclose(chosen.q, near) and chosen.switched
    # B is better still, but its joints move by 1.5-2 rad: out of one preview step's reach
    assert np.abs(np.subtract(B, A)).max() > REACH.max()


def test_a_lost_peak_with_no_survivor_within_reach_takes_the_nearest_to_the_arm_before() -> None:
    tracker = _tracker()
    tracker.update(*_options((A, 100.0)), np.array(A), REACH)
    far = [a + 1.2 for a in A]  # out of reach, but nearer to A than B is
    chosen = tracker.update(*_options((B, 500.0), (far, 50.0)), np.array(A), REACH)
    assert chosen is not None and np.allclose(chosen.q, far) and chosen.switched


def test_each_imaginary_arm_starts_from_the_arm_before_it_in_the_chain() -> None:
    """At the first frame the reference is ``before`` (for arm i > 1: arm i - 1's target, not the real arm)."""
    tracker = _tracker()
    first = tracker.update(*_options((A, 100.0), (B, 90.0)), np.array(B) + 0.1, REACH)
    assert first is not None and np.allclose(first.q, B) and first.switched


def test_the_pull_ramps_in_after_a_change_and_nothing_feasible_gives_none() -> None:
    tracker = _tracker(settle_frames=4)
    ramps = [tracker.update(*_options((A, 100.0)), np.array(A), REACH).ramp for _ in range(6)]  # type: ignore[union-attr]
    assert ramps == [0.0, 0.25, 0.5, 0.75, 1.0, 1.0]
    assert tracker.update(*_options((A, -1.0)), np.array(A), REACH) is None


@pytest.mark.parametrize("seed", [0, 1])
def test_a_tracked_peak_of_a_spatial_arm_climbs_with_its_mutants(panda: Robot, seed: int) -> None:
    """The hand holds still in free space, so the landscape does not change: the tracked target should climb to
    the peak above the arm (S ≈ 5500, where the gradient from there goes). With no mutants bred around it the
    population (64 individuals, 7 genes on a 4-dimensional self-motion manifold) holds nothing else within
    ``track_radius`` of it, and it stays put."""
    q = np.array([-0.14, 0.23, -0.54, -2.16, 0.05, 2.18, 0.79])
    kin = kinematics(panda, q[None, :])
    tip = kin.tip_position[0]
    state = ControlState(q, 0.0, kin, HandPath(np.array([tip, tip + 1e-9]), 5.0), 0.01, frame_due=True)
    climbed = {}
    for neighbours in (0, None):
        law = compose(ControllerSpec("single", ControllerParams(track_neighbours=neighbours)), panda, Scene(),
                      Evaluator(panda), np.random.default_rng(seed)).law
        S = []
        for _ in range(30):  # 30 camera frames at the same time: a static landscape
            null = law.null_input(state)
            assert null.target_amsip is not None
            S.append(float(null.target_amsip[0]))
        climbed[neighbours] = S[-1] / S[0]
    assert ControllerParams().neighbours(planar=False) == SPATIAL_NEIGHBOURS > 0
    assert climbed[None] > 3.0  # 1534 -> 5500
    assert climbed[0] < 1.5  # 1534 -> 1813 (seed 0) or 1534 (seed 1)


def test_planar_arms_breed_no_mutants_by_default_and_a_given_number_is_kept() -> None:
    assert ControllerParams().neighbours(planar=True) == 0
    assert ControllerParams(track_neighbours=4).neighbours(planar=True) == 4
    assert ControllerParams(track_neighbours=0).neighbours(planar=False) == 0


def test_branch_lock_breeds_every_individual_on_one_branch(planar4: Robot) -> None:
    ga = OneStepGA(planar4, Evaluator(planar4), PlanarRedundancy(planar4), np.random.default_rng(3))
    ga.branch_lock = 1
    for _ in range(5):
        ga.step(np.array([0.85, 0.65]), 0.0)
    assert np.all(ga.population_branch == 1)
    assert ga.peaks() and all(p.branch == 1 for p in ga.peaks())
    _, solved = PlanarRedundancy(planar4).genes_of(np.array([p.q for p in ga.peaks()]))
    assert np.all(solved == 1)


def test_unlocked_ga_is_unchanged_by_the_lock_attribute(planar4: Robot) -> None:
    runs = []
    for lock in (False, True):
        ga = OneStepGA(planar4, Evaluator(planar4), PlanarRedundancy(planar4), np.random.default_rng(5))
        if lock:
            ga.branch_lock = None
        for _ in range(4):
            best = ga.step(np.array([0.85, 0.65]), 0.0)
        runs.append((best.q, ga.population_genes))
    assert np.array_equal(runs[0][0], runs[1][0]) and np.array_equal(runs[0][1], runs[1][1])


def test_an_elbow_change_kept_unwrapped_passes_the_stretched_wrist(planar4: Robot) -> None:
    q = np.array([0.3, 0.4, 0.2, -2.9])
    target = np.array([0.3, 0.4, 0.2, 2.9])
    wrapped = wrapped_difference(planar4, q, target)
    kept = wrapped_difference(planar4, q, target, keep=(3,))
    assert wrapped[3] == pytest.approx(5.8 - 2 * np.pi)  # the short way: through the fold q4 = ±π
    assert kept[3] == pytest.approx(5.8)  # through q4 = 0, the stretched wrist
    # on the way, q4 = 0 is crossed: the straight line q + s * kept passes it for s in (0, 1)
    s = -q[3] / kept[3]
    assert 0.0 < s < 1.0


def _short(name: str, coherent: bool, duration: float = 3.0, execution: str = "qp", step_correction: bool = True
           ) -> RunResult:
    """A short staircase run; coherent ``multi``'s imaginary arms on their tracked peaks (``imaginary_arms =
    "peaks"``, which no other run reads)."""
    scenario = canonical_scenario("paper_planar")
    arms = "peaks" if name == "multi" and coherent else None
    params = dataclasses.replace(scenario.controller.params, coherent=coherent, execution=execution,
                                 step_correction=step_correction, imaginary_arms=arms)
    scenario = dataclasses.replace(
        scenario,
        controller=ControllerSpec(name, params),
        timing=dataclasses.replace(scenario.timing, duration=duration),
    )
    return simulate(scenario, name, seed=0)


def test_coherent_multi_keeps_every_imaginary_arm_on_the_arms_branch(planar4: Robot) -> None:
    run = _short("multi", coherent=True)
    red = PlanarRedundancy(planar4)
    _, arm_branch = red.genes_of(np.asarray(run.q))
    targets = np.asarray(run.targets)
    for i in range(targets.shape[1]):
        _, branch = red.genes_of(targets[:, i])
        assert np.array_equal(branch, arm_branch), f"imaginary arm {i} left the arm's branch"
    # and the blend of same-branch targets is on that branch too: q4 keeps the arm's sign
    blend = np.einsum("i,kij->kj", np.array(ControllerParams().weights), targets)
    assert np.all(np.sign(blend[:, 3]) == np.sign(np.asarray(run.q)[:, 3]))


def test_paper_literal_mode_reproduces_the_earlier_numbers() -> None:
    """Final states of 2 s runs measured on the code before the coherent mode, the QP and the step correction
    existed (74c8822): the paper's eq. 19 as printed, eq. 21 on each frame's argmax."""
    expected = {
        "single": (
            [2.0846967344853375, -2.0701491960356195, -3.5014025394206705, -2.0981358516907154], 6098.114509488421
        ),
        "multi": ([1.856542568169394, -1.9532411518477506, -3.249357064929832, -2.00864364315927], 7372.09706020939),
    }
    expected["reach"] = (
        [1.5565944196780397, -1.7879554910765183, -3.1033333144848654, -1.8190763811678305], 7103.2697696369105
    )
    for name, (q_end, S_end) in expected.items():
        run = _short(name, coherent=False, duration=3.0 if name == "reach" else 2.0, execution="pseudoinverse",
                     step_correction=False)
        assert np.asarray(run.q)[-1] == pytest.approx(q_end, abs=1e-12)
        assert float(np.asarray(run.S)[-1]) == pytest.approx(S_end, rel=1e-12)


def test_coherent_targets_never_jump_between_peaks_on_the_fitted_scene() -> None:
    """On the real landscape of ``paper_fitted`` (10 s, seed 0) no imaginary arm's target moves more than
    0.5 rad between two frames: the peaks keep their identity while the target and the object move.
    (The paper-literal rule jumps between near-tied peaks; measured in docs/guide/controllers.md.)"""
    scenario = canonical_scenario("paper_fitted")
    params = dataclasses.replace(scenario.controller.params, imaginary_arms="peaks")
    scenario = dataclasses.replace(scenario, controller=ControllerSpec("multi", params),
                                   timing=dataclasses.replace(scenario.timing, duration=10.0))
    run = simulate(scenario, seed=0)
    targets = np.asarray(run.targets)
    step = np.abs(np.diff(targets, axis=0))
    step = np.minimum(step, 2 * np.pi - step)  # planar4's joints turn a full circle
    assert np.linalg.norm(step, axis=2).max() < 0.5
    assert not run.summary()["collided"]


def test_reach_changes_elbow_through_the_stretched_wrist_with_the_hand_on_the_path() -> None:
    """On the staircase (seed 0) reach leaves the dying family by changing elbow branch: q4 changes sign
    through 0 (not through the fold at ±π), with the hand on the path and no collision."""
    scenario = canonical_scenario("paper_planar")
    scenario = dataclasses.replace(scenario, timing=dataclasses.replace(scenario.timing, duration=28.0))
    run = simulate(scenario, "reach", seed=0)
    q4, error = np.asarray(run.q)[:, 3], np.asarray(run.hand_error)
    crossings = np.flatnonzero(np.sign(q4[1:]) != np.sign(q4[:-1]))
    assert crossings.size >= 1, "reach kept its elbow branch"
    for k in crossings:
        assert max(abs(q4[k]), abs(q4[k + 1])) < 0.05  # through q4 = 0, the stretched wrist
        assert error[k] < 1e-3  # [m]
    assert not run.summary()["collided"]
