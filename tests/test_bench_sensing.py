"""Tests of ``previewctl bench --sensing``: observed runs in the matrix, their key and record, the report that sets
them beside the perfect-foresight runs, and the command's flags."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from previewctl.bench.keep import run_folder
from previewctl.bench.report import write_report
from previewctl.bench.results import read_records
from previewctl.bench.robots import cached_robot, profile
from previewctl.bench.runs import OBSERVED_SENSING, RunSpec, record_key, sensing_summary, settings_hash, simulate_spec
from previewctl.bench.scenes import BenchScene, draw_document, generate
from previewctl.bench.settings import SceneSettings
from previewctl.bench.sweep import Sweep
from previewctl.cli.main import main
from previewctl.errors import ParameterError, UnknownNameError
from previewctl.scene.file import motion_from_dict

ROOT = Path(__file__).resolve().parents[1]


def test_observed_runs_have_their_own_key_and_foresight_controllers_run_once() -> None:
    sweep = Sweep(scenes=1, controllers=("none", "qp", "multi", "oracle"), executions=("qp", "pseudoinverse"),
                  sensings=("none", "observed"))
    runs = [(s.controller, s.execution, s.sensing) for s in sweep.runs()]
    assert runs == [("none", "pseudoinverse", "none"), ("qp", "qp", "none"), ("multi", "qp", "none"),
                    ("multi", "pseudoinverse", "none"), ("oracle", "qp", "none"), ("oracle", "pseudoinverse", "none"),
                    ("qp", "qp", "observed"), ("multi", "qp", "observed"), ("multi", "pseudoinverse", "observed")]
    keys = [s.key for s in sweep.runs()]
    assert len(set(keys)) == len(keys)
    known = sweep.runs()[1]
    older = {k: v for k, v in dataclasses.asdict(known).items() if k != "sensing"}  # a line from before --sensing
    assert record_key(older) == known.key != sweep.runs()[6].key


@pytest.mark.parametrize(("kwargs", "error", "message"), [
    ({"sensings": ("seen",)}, UnknownNameError, r"unknown sensing 'seen'; valid: none, observed"),
    ({"sensings": ()}, ParameterError, r"^give at least one sensing; valid: none, observed$"),
])
def test_sweep_names_a_bad_sensing(kwargs: dict[str, object], error: type[Exception], message: str) -> None:
    with pytest.raises(error, match=message):
        Sweep(**kwargs)  # type: ignore[arg-type]


def _record(scene: int, controller: str, ok: bool, sensing: str | None = None) -> dict[str, object]:
    record: dict[str, object] = {
        "robot": "planar4", "scene": scene, "seed": 0, "controller": controller, "execution": "qp",
        "settings": "abc", "success_1mm": ok, "success_5mm": ok, "collision_free": ok, "self_collision_free": True,
        "max_hand_error": 1e-4, "cycle_time_median": 1e-3, "cycle_time_p95": 2e-3, "wall_time": 1.0,
        "cpu_time": 0.5}
    return record if sensing is None else {**record, "sensing": sensing}


def test_report_sets_observed_runs_beside_perfect_foresight_on_the_same_scenes(tmp_path: Path) -> None:
    records = [_record(s, "multi", True) for s in range(4)] + [_record(s, "qp", s < 2) for s in range(4)]
    records += [_record(s, "multi", s != 1, "observed") for s in range(3)]  # scene 3 not observed: left out
    records += [_record(s, "qp", s == 0, "observed") for s in range(4)]
    fed = sensing_summary(OBSERVED_SENSING)
    for r in records[8:-1]:
        r["sensing_settings"] = fed
    text = write_report(records, [], tmp_path)[0].read_text()
    assert "| multi (observed) | qp | 3 | 67% |" in text and "| qp (observed) | qp | 4 | 25% |" in text
    assert "## Observed against perfect foresight (success < 1 mm, same scenes and seeds)\n\nObserved runs: 6 with " \
           "30 Hz, 5 mm noise, 50 ms latency, dropout 0; predicted by imm, q = 0.0001 cruising, 0.1 manoeuvring " \
           "m²/s³, margin min(3 cm, 2 σ); and 1 with settings not recorded.\n" in text  # each run's record
    assert "| planar4 | multi | qp | 3 | 100% | 67% | -33 |" in text
    assert "| planar4 | qp | qp | 4 | 50% | 25% | -25 |" in text
    # preview (observed) is set against qp fed the same observations: it wins scene 2 (known qp succeeds there)
    assert "| planar4 | multi (observed) | qp | 2:0 | - |" in text and "| planar4 | multi | qp | 2:0, 3:0 | - |" in text
    assert "--sensing none,observed`" in text and "Rows marked *(observed)*" in text
    assert "Observed against" not in write_report(records[:8], [], tmp_path)[0].read_text()  # old lines: foresight
    assert run_folder(records[8]) == "planar4_000_s0_multi_qp_observed" != run_folder(records[0])


def test_an_observed_bench_run_is_fed_the_default_observations() -> None:
    assert (OBSERVED_SENSING.rate, OBSERVED_SENSING.noise, OBSERVED_SENSING.latency, OBSERVED_SENSING.dropout) == (
        30.0, 0.005, 0.05, 0.0)


def test_bench_help_names_the_sensing_and_motion_flags(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as done:
        main(["bench", "--help"])
    assert done.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "--sensing NAMES" in text and "none, observed" in text and "30 Hz, 5 mm noise, 50 ms latency" in text
    assert "--motions KIND" in text and "constant, surprise" in text
    assert "--history S" in text and "already observes them" in text


def test_a_tiny_observed_sweep_of_surprise_scenes_end_to_end(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setenv("PYTHONPATH", str(ROOT))  # the worker processes import this worktree's previewctl
    out = tmp_path / "bench"
    assert main(["bench", "--scenes", "1", "--duration", "3", "--controller", "qp", "--execution", "qp",
                 "--sensing", "none,observed", "--motions", "surprise", "--workers", "1", "--keep", "0",
                 "--out", str(out), "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["done"] == 2 and printed["failed"] == []
    records = read_records(out / "results.jsonl")
    assert sorted(r["sensing"] for r in records) == ["none", "observed"]
    assert {r["motions"] for r in records} == {"surprise"}
    (scene,) = read_records(out / "scenes.jsonl")
    assert {o["motion"]["type"] for o in scene["document"]["obstacles"]} <= {"turn", "stop", "speed_change",
                                                                              "random_walk"}
    report = (out / "report.md").read_text()
    assert "| planar4 | qp | qp | 1 |" in report  # the observed-against-foresight table's row
    assert "--sensing none,observed --motions surprise`" in report
    # the observed run was fed observations only: its log says how many (3 s at 30 Hz, 50 ms late)
    observed = next(r for r in records if r["sensing"] == "observed")
    spec = RunSpec(**{f.name: observed[f.name] for f in dataclasses.fields(RunSpec)})
    _, result, _ = simulate_spec(spec, BenchScene.from_record(scene))
    assert result.summary()["max_hand_error"] == pytest.approx(observed["max_hand_error"], abs=1e-12)
    assert result.summary()["observations"] > 0


# ------------------------------------------------------------------------------------ a sensor running before the start


def test_a_history_moves_the_obstacles_before_the_start_and_not_after() -> None:
    arm, prof = cached_robot("planar4"), profile("planar4")
    cold, warm = SceneSettings(duration=3.0), SceneSettings(duration=3.0, history=1.0)
    documents = [draw_document(arm, "planar4", prof, np.random.default_rng(7), s, "draw") for s in (cold, warm)]
    times = np.linspace(0.0, 3.0, 31)
    for before, after in zip(documents[0]["obstacles"], documents[1]["obstacles"], strict=True):
        moving = motion_from_dict(after["motion"], "motion")
        still = motion_from_dict(before["motion"], "motion")
        np.testing.assert_array_equal(moving.positions(times), still.positions(times))  # the same run from t = 0
        velocity = np.asarray(after["motion"]["velocity"])
        np.testing.assert_allclose(moving.positions(np.array([-0.5]))[0, :2], still.positions(np.array([0.0]))[0, :2]
                                   - 0.5 * velocity, atol=1e-12)  # seen moving before it
        np.testing.assert_array_equal(still.positions(np.array([-0.5])), still.positions(np.array([0.0])))
    assert settings_hash("planar4", 0, warm) != settings_hash("planar4", 0, cold)
    assert settings_hash("planar4", 0, SceneSettings()) == "cdae7f6ae12f"  # results from before keep their key
    with pytest.raises(ParameterError, match="history"):
        SceneSettings(history=-1.0)


def test_an_observed_run_of_a_scene_with_a_history_observes_from_before_the_start() -> None:
    scene = generate("planar4", 0, 0, SceneSettings(duration=2.0, history=1.0))
    assert scene.history == 1.0
    assert BenchScene.from_record({**dataclasses.asdict(scene), "settings": "abc"}).history == 1.0
    assert BenchScene.from_record({k: v for k, v in dataclasses.asdict(scene).items() if k != "history"}).history == 0
    settings = settings_hash("planar4", 0, SceneSettings(duration=2.0, history=1.0))
    scenario, result, _ = simulate_spec(RunSpec("planar4", 0, 0, "qp", "qp", settings, 0, "inline", "observed"),
                                        scene)
    assert scenario.sensing is not None and scenario.sensing.history == 1.0
    assert "observed from 1 s before the start" in sensing_summary(scenario.sensing)
    # 30 Hz over [-1 s, 2 s] per obstacle, all delivered (no dropout): more than the run alone would get
    assert result.summary()["observations"] >= 30 * 3 * len(scenario.scene.obstacles) - len(scenario.scene.obstacles)
    known, _, _ = simulate_spec(RunSpec("planar4", 0, 0, "qp", "qp", settings, 0, "inline", "none"), scene)
    assert known.sensing is None


def test_the_report_names_the_history_it_ran_with(tmp_path: Path) -> None:
    records = [{**_record(s, "qp", True), "history": 1.0} for s in range(2)]
    assert "--history 1`" in write_report(records, [], tmp_path)[0].read_text()
    assert "--history" not in write_report([_record(s, "qp", True) for s in range(2)], [], tmp_path)[0].read_text()
