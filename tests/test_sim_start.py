"""Tests of :mod:`previewctl.sim.start`: a start configuration in collision is bad input, refused before anything
runs (``simulate``, ``previewctl run``, ``previewctl paper``), with the pair, its penetration and what to change."""

from __future__ import annotations

import pickle
import re
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from helpers import PLANAR_Q0, planar_doc, tiny_planar_toml

import previewctl.sim.paper as paper_module
from previewctl.cli.main import main
from previewctl.errors import ScenarioError, StartCollisionError
from previewctl.index.evaluator import Evaluation, Evaluator
from previewctl.index.load import load_robot
from previewctl.sim.loop import simulate
from previewctl.sim.paper import run_paper_scenes
from previewctl.sim.scenario import Scenario, scenario_from_dict
from previewctl.sim.start import CONTACT_SOURCES, Contact, check_start, start_message
from previewctl.types import Array

LINK_RADIUS = 0.03
"""planar4's link cylinders [m] (robots/planar4.urdf)."""
LINKS = 0.75
"""planar4's link length [m]."""
PANDA_Q0 = [-0.231, -0.1124, -0.2518, -2.1351, -0.0842, 2.0147, 0.785]
"""scenarios/panda_crossing.toml's start [rad]: the hand at (0.45, -0.25, 0.35) m."""


def beside_link(link: int, gap: float, q: list[float] = PLANAR_Q0) -> list[float]:
    """The point ``gap`` [m] from the axis of planar4's ``link`` (1-4) at its middle, in the plane (planar
    trigonometry, independent of the robot model)."""
    angles = np.cumsum(q)
    joints = np.vstack([np.zeros(2), np.cumsum(LINKS * np.c_[np.cos(angles), np.sin(angles)], axis=0)])
    a, b = joints[link - 1], joints[link]
    axis = (b - a) / LINKS
    point = (a + b) / 2 + gap * np.array([-axis[1], axis[0]])
    return [float(v) for v in point]


def ball(name: str, position: list[float], radius: float = 0.05, **keys: Any) -> dict[str, Any]:
    """A sphere's ``[[obstacles]]`` table."""
    return {"name": name, "shape": "sphere", "radius": radius, "position": position, **keys}


def toml_ball(table: dict[str, Any]) -> str:
    """A sphere's table as TOML text."""
    keys = "".join(f"{k} = {str(v).lower() if isinstance(v, bool) else repr(v).replace(chr(39), chr(34))}\n"
                   for k, v in table.items())
    return f"[[obstacles]]\n{keys}"


@pytest.fixture(scope="module")
def link2_hit() -> Scenario:
    """A 5 cm ball whose centre is 6 cm from link2's axis: 3 cm cylinder + 5 cm ball - 6 cm = 2 cm deep."""
    return scenario_from_dict(planar_doc(obstacles=[ball("post", beside_link(2, 0.06))]))


@pytest.fixture(scope="module")
def hand_on_part() -> dict[str, Any]:
    """The hand link (link4) 2 cm into a ball ``part`` that is not marked as a work surface."""
    return planar_doc(obstacles=[ball("part", beside_link(4, 0.06))], timing={"duration": 0.2})


# ------------------------------------------------------------------------------------- the API


def test_a_link_in_an_obstacle_at_the_start_is_refused_naming_the_pair_and_the_depth(link2_hit: Scenario) -> None:
    with pytest.raises(StartCollisionError, match=re.escape(
            "scenario 'planar_test': the start configuration robot.q0 collides at t = 0 s (exact geometry): "
            "link 'link2' and obstacle 'post' (penetration 20.00 mm); move robot.q0 or the obstacle, or start from "
            "robot.q0 = \"auto\"")) as caught:
        check_start(link2_hit)
    ((link, other, distance),) = caught.value.pairs
    assert (link, other) == ("link2", "post") and distance == pytest.approx(-0.02, abs=1e-6)
    assert "work_surface" not in str(caught.value)  # link2 is no hand link
    assert isinstance(caught.value, ScenarioError)


def test_simulate_refuses_a_start_in_collision_before_the_first_step(link2_hit: Scenario) -> None:
    seen: list[tuple[float, float]] = []
    for stop in (True, False):  # also when collisions are logged and the run goes on
        with pytest.raises(StartCollisionError, match=re.escape(
                "link 'link2' and obstacle 'post' (penetration 20.00 mm)")):
            simulate(link2_hit, progress=lambda f, t: seen.append((f, t)), stop_on_collision=stop)
    assert seen == [], "nothing ran"


def test_the_hand_in_an_object_that_is_no_work_surface_is_told_to_mark_it(hand_on_part: dict[str, Any]) -> None:
    scenario = scenario_from_dict(hand_on_part)
    with pytest.raises(StartCollisionError, match=re.escape(
            "link 'link4' and obstacle 'part' (penetration 20.00 mm); link 'link4' moves with the hand: if the hand "
            "works on 'part' (traces or touches it), mark that obstacle work_surface = true in [[obstacles]] (the "
            "hand may touch the object it works on); otherwise move robot.q0 or the obstacle")):
        simulate(scenario)


def test_the_same_scene_with_the_object_as_work_surface_runs(hand_on_part: dict[str, Any]) -> None:
    doc = {**hand_on_part, "obstacles": [{**hand_on_part["obstacles"][0], "work_surface": True}]}
    scenario = scenario_from_dict(doc)
    check_start(scenario)
    summary = simulate(scenario).summary()
    assert summary["steps"] == 21 and not summary["collided"]


@pytest.fixture(scope="module")
def panda_doc() -> dict[str, Any]:
    """scenarios/panda_crossing.toml's robot and path, no obstacle, 0.05 s."""
    return {"name": "panda_elbow", "robot": {"source": "panda", "q0": PANDA_Q0},
            "path": {"waypoints": [[0.45, -0.25, 0.35], [0.45, 0.25, 0.35]], "duration": 10.0},
            "controller": {"name": "none"}, "timing": {"duration": 0.05}}


def panda_frame(doc: dict[str, Any], frame: str) -> list[float]:
    """Where ``frame``'s origin is at the start [m]."""
    robot = scenario_from_dict(doc).robot
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, np.array(PANDA_Q0))
    return [float(v) for v in data.oMf[robot.model.getFrameId(frame)].translation]


def test_a_panda_link_in_an_obstacle_at_the_start_is_refused(panda_doc: dict[str, Any]) -> None:
    """A 5 cm ball at the origin of panda_link4's frame (the elbow, inside its mesh)."""
    elbow = panda_frame(panda_doc, "panda_link4")
    hit = scenario_from_dict({**panda_doc, "obstacles": [ball("ball", elbow)]})
    with pytest.raises(StartCollisionError, match=r"^scenario 'panda_elbow': the start configuration robot\.q0 "
                       r"collides at t = 0 s \(exact geometry\): link 'panda_link\d' and obstacle 'ball' "
                       r"\(penetration \d+\.\d\d mm\)") as caught:
        simulate(hit)
    links = {link for link, other, distance in caught.value.pairs if other == "ball" and distance < 0}
    assert "panda_link4" in links and links <= set(hit.robot.guarded_links)
    assert "work_surface" not in str(caught.value)  # the elbow is not the hand
    away = [elbow[0], elbow[1], elbow[2] + 0.5]  # the same ball 0.5 m higher: the start is clear
    check_start(scenario_from_dict({**panda_doc, "obstacles": [ball("ball", away)]}))


def test_the_panda_hand_in_an_object_is_told_to_mark_it(panda_doc: dict[str, Any]) -> None:
    """A 5 cm ball at the origin of panda_hand's frame: the hand's links only; as a work surface, the start is clear."""
    hand = panda_frame(panda_doc, "panda_hand")
    with pytest.raises(StartCollisionError, match=re.escape(
            "move with the hand: if the hand works on 'ball' (traces or touches it), mark that obstacle "
            "work_surface = true")) as caught:
        check_start(scenario_from_dict({**panda_doc, "obstacles": [ball("ball", hand)]}))
    held = {link for link, _, _ in caught.value.pairs}
    assert held and held <= set(scenario_from_dict(panda_doc).robot.hand_links)
    check_start(scenario_from_dict({**panda_doc, "obstacles": [ball("ball", hand, work_surface=True)]}))


def test_the_error_crosses_a_process_boundary_whole(link2_hit: Scenario) -> None:
    with pytest.raises(StartCollisionError) as caught:
        check_start(link2_hit)
    again = pickle.loads(pickle.dumps(caught.value))
    assert type(again) is StartCollisionError and str(again) == str(caught.value)
    assert again.pairs == caught.value.pairs


# ---------------------------------------------------------------- self-collision at the start

PANDA_FOLDED = [-0.23, 0.026, 1.678, -2.793, 0.456, 0.726, 1.786]
"""A Panda configuration whose hand is inside ``panda_link2`` (found among seeded random samples, exact meshes)."""


def test_a_panda_folded_into_itself_at_the_start_is_refused_naming_both_links(panda_doc: dict[str, Any]) -> None:
    doc = {**panda_doc, "robot": {"source": "panda", "q0": PANDA_FOLDED}}
    robot = load_robot("panda")
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, np.array(PANDA_FOLDED))
    hand = data.oMf[robot.tip_frame_id].translation
    above = hand + np.array([0.0, 0.0, 0.05])
    scenario = scenario_from_dict({**doc, "path": {"waypoints": [hand.tolist(), above.tolist()], "duration": 1.0}})
    named = r"links 'panda_link2' and 'panda_hand' \((touching|penetration [0-9.]+ mm)\); move robot.q0, or start from"
    with pytest.raises(StartCollisionError, match=named) as caught:
        simulate(scenario)
    ((_, _, depth),) = [p for p in caught.value.pairs if p[:2] == ("panda_link2", "panda_hand")]
    assert depth <= 0.0  # meshes in contact: Coal gives no penetration depth between two meshes, only 0


# ---------------------------------------------------------------- the hook for more kinds of pairs


def test_a_self_collision_is_named_by_both_links() -> None:
    message = start_message([Contact("link2", "link4", -0.003, "link")])
    assert message == ("the start configuration robot.q0 collides at t = 0 s (exact geometry): links 'link2' and "
                       "'link4' (penetration 3.00 mm); move robot.q0, or start from robot.q0 = \"auto\" (previewctl "
                       "run --q0 auto: the best collision-free start at the first waypoint)")


def test_a_contact_source_added_to_the_hook_refuses_a_start(monkeypatch: pytest.MonkeyPatch) -> None:
    """What the self-collision pairs will do: a source of (link, link) pairs appended to CONTACT_SOURCES."""

    def elbow_folded(evaluator: Evaluator, q: Array, t: float, check: Evaluation) -> list[Contact]:
        return [Contact("link1", "link3", -0.001, "link")]

    free = scenario_from_dict(planar_doc())
    check_start(free)
    monkeypatch.setattr("previewctl.sim.start.CONTACT_SOURCES", (*CONTACT_SOURCES, elbow_folded))
    with pytest.raises(StartCollisionError, match=re.escape("links 'link1' and 'link3' (penetration 1.00 mm)")):
        simulate(free)


def test_many_pairs_show_the_deepest_and_count_the_rest() -> None:
    contacts = [Contact("link2", f"b{i}", -0.001 * (6 - i)) for i in range(6)]
    message = start_message(contacts)
    assert "link 'link2' and obstacle 'b0' (penetration 6.00 mm), " in message
    assert "obstacle 'b3' (penetration 3.00 mm), and 2 more; move" in message and "'b4'" not in message


# ---------------------------------------------------------------------------- the command line


def refused(argv: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    """``previewctl argv`` exits 2 with one line on stderr containing ``message``."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("previewctl: error: "), err
    assert message in err, err


def test_run_refuses_a_start_in_collision_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scenario = tmp_path / "hit.toml"
    scenario.write_text(tiny_planar_toml("hit", toml_ball(ball("post", beside_link(2, 0.06)))))
    out = tmp_path / "new" / "run"
    refused(["run", str(scenario), "--out", str(out)],
            f"previewctl: error: {scenario}: the start configuration robot.q0 collides at t = 0 s (exact geometry): "
            "link 'link2' and obstacle 'post' (penetration 20.00 mm); move robot.q0", capsys)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["hit.toml"], "nothing written, not even --out's parent"


def test_run_tells_to_mark_the_work_surface(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scenario = tmp_path / "trace.toml"
    scenario.write_text(tiny_planar_toml("trace", toml_ball(ball("part", beside_link(4, 0.06)))))
    refused(["run", str(scenario), "--out", str(tmp_path / "run")],
            "mark that obstacle work_surface = true in [[obstacles]]", capsys)
    assert not (tmp_path / "run").exists()


def test_paper_refuses_a_scene_that_starts_in_collision_before_any_run(
    link2_hit: Scenario, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def simulated(*args: object, **kwargs: object) -> None:
        raise AssertionError("a run started")

    monkeypatch.setattr(paper_module, "canonical_scenario", lambda name="paper_fitted": link2_hit)
    monkeypatch.setattr(paper_module, "simulate", simulated)
    out = tmp_path / "paper"
    with pytest.raises(StartCollisionError, match="link 'link2' and obstacle 'post'"):
        run_paper_scenes(out, scenes=("paper_planar",), controllers=("none",))
    assert not out.exists()
