"""Coherent ``multi`` on a planned route (``imaginary_arms = "route"``, the default where the window planner covers the
arm): eq. 21 pulls the arm toward where the route that ``reach`` plans puts it at the preview times
(:class:`previewctl.control.laws.MultiPreview` with the :class:`previewctl.control.imaginary.RoutePoints` policy)."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest

from previewctl.bench.runs import RunSpec, simulate_spec
from previewctl.bench.scenes import generate
from previewctl.control.base import ControlState, NullInput
from previewctl.control.factory import make_controller
from previewctl.control.imaginary import ArgmaxArms, RoutePoints, TrackedPeaks
from previewctl.control.laws import MultiPreview
from previewctl.control.params import ControllerSpec
from previewctl.control.planner import WindowPlanner
from previewctl.kinematics import kinematics
from previewctl.sim.loop import simulate
from previewctl.sim.paper import canonical_scenario
from previewctl.sim.scenario import Scenario


def _multi(scenario: Scenario, duration: float, **params: Any) -> Scenario:
    """``scenario`` run by ``multi`` for ``duration`` [s] with the given parameter changes."""
    changed = dataclasses.replace(scenario.controller.params, **params)
    return dataclasses.replace(scenario, controller=ControllerSpec("multi", changed),
                               timing=dataclasses.replace(scenario.timing, duration=duration))


@pytest.mark.parametrize(("params", "policy"), [
    ({}, RoutePoints), ({"imaginary_arms": "peaks"}, TrackedPeaks), ({"coherent": False}, ArgmaxArms),
])
def test_the_imaginary_arms_are_on_the_route_unless_asked_otherwise(params: dict[str, Any], policy: type) -> None:
    law = make_controller(_multi(canonical_scenario("paper_fitted"), 1.0, **params)).law
    assert isinstance(law, MultiPreview) and law.name == "multi"
    assert type(law.policy) is policy
    if isinstance(law.policy, RoutePoints):
        assert isinstance(law.policy.planner.planner, WindowPlanner)


def test_the_pull_is_eq_21_toward_the_plan_at_the_preview_times(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every command's ``v`` is ``K_v Σ k_i (q_plan(t + i t̃) − q)`` from the first frame on (no ramp), and each
    imaginary arm inside the plan has its hand on the path at its own time."""
    scenario = _multi(canonical_scenario("paper_fitted"), 4.0)
    controller = make_controller(scenario)
    law = controller.law
    assert isinstance(law, MultiPreview) and isinstance(law.policy, RoutePoints) and law.local is None
    planner = law.policy.planner.planner
    params, seen, worst = scenario.controller.params, [], [0.0]
    original = law.null_input

    def spy(state: ControlState) -> NullInput:
        null = original(state)  # plans when due: the points below are of the plan the command followed
        t, q = state.t, state.q
        assert planner.motion is not None
        arms = [planner.point(t + (i + 1) * params.preview_time)[0] for i in range(len(params.weights))]
        pull = sum(k * (arm - q) for k, arm in zip(params.weights, arms, strict=True))
        np.testing.assert_allclose(null.v, np.asarray(params.gain) * pull, atol=1e-12)
        np.testing.assert_allclose(null.targets, np.array(arms), atol=0)
        end = planner.motion.times[-1]
        hands = kinematics(scenario.robot, np.array(arms)).tip_position[:, :2]
        for i, hand in enumerate(hands):
            t_i = t + (i + 1) * params.preview_time
            if t_i <= end:
                worst.append(float(np.linalg.norm(hand - scenario.path.position(t_i)[:2])))
        seen.append(t)
        return null

    monkeypatch.setattr(law, "null_input", spy)
    summary = simulate(scenario, controller=controller).summary()
    assert len(seen) == 401 and seen[0] == 0.0  # the first command is checked too: with a ramp it would fail
    # the plan is linear between its samples (chords of up to ~1 mm here); an arm at a wrong time would be
    # decimetres off: the hand moves 0.075 m/s on average and t̃ = 5 s
    assert 0 < max(worst) < 3e-3
    assert not summary["collided"] and summary["max_hand_error"] < 1e-3


def test_the_route_leaves_the_basin_that_the_tracked_peaks_stay_in() -> None:
    """Planar bench scene 27 of scene seed 6 (held out, QP): ``multi`` on its tracked peaks stays in the basin the disc
    closes and gives up the path (> 100 mm); on the route it finishes within 1 mm, collision-free."""
    scene = generate("planar4", 27, seed=6)
    errors = {}
    for arms in ("route", "peaks"):
        document = dict(scene.document, controller={**scene.document["controller"], "imaginary_arms": arms})
        spec = RunSpec("planar4", 27, 0, "multi", "qp", "test", 6)
        _, result, _ = simulate_spec(spec, dataclasses.replace(scene, document=document))
        summary = result.summary()
        assert not summary["collided"]
        errors[arms] = summary["max_hand_error"]
    assert errors["route"] < 1e-3 < 0.1 < errors["peaks"]


def test_multi_changes_elbow_through_the_stretched_wrist_on_the_staircase() -> None:
    """On the staircase (seed 0) the route leaves the dying family early: q4 changes sign through 0 (the stretched
    wrist, not the fold at ±π) with the hand on the path and no collision, which tracked peaks never do."""
    run = simulate(_multi(canonical_scenario("paper_planar"), 8.0), seed=0)
    q4, error = np.asarray(run.q)[:, 3], np.asarray(run.hand_error)
    crossings = np.flatnonzero(np.sign(q4[1:]) != np.sign(q4[:-1]))
    assert crossings.size >= 1, "multi kept its elbow branch"
    for k in crossings:
        assert max(abs(q4[k]), abs(q4[k + 1])) < 0.05  # through q4 = 0
        assert error[k] < 1e-3  # [m]
    assert not run.summary()["collided"]
