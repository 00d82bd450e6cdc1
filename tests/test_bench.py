"""Tests of :mod:`previewctl.bench`: the scene generators and their witness, the sweep on a local Dask
cluster end to end with its resume, the report, and the command's errors."""

from __future__ import annotations

import dataclasses
import json
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from distributed import LocalCluster
from helpers import planar_doc, pseudoinverse

from previewctl.bench.keep import contrasts, run_folder, runs_to_keep
from previewctl.bench.metrics import run_metrics
from previewctl.bench.provenance import source_commit
from previewctl.bench.report import write_report
from previewctl.bench.results import append_record, read_records
from previewctl.bench.runs import RunSpec, plan_costs, record_key, settings_hash, simulate_spec
from previewctl.bench.runs import run as bench_run
from previewctl.bench.scenes import BenchScene, generate
from previewctl.bench.settings import SceneSettings
from previewctl.bench.sweep import WORKER_MALLOC, Sweep, dask_client
from previewctl.bench.witness import Witnessed, witness
from previewctl.cli.main import main
from previewctl.control.params import CONTROLLER_NAMES, EXECUTION_MODES, SEEDED_CONTROLLERS
from previewctl.errors import IgnoredSettingWarning, ParameterError, UnknownNameError
from previewctl.search.reachability import ReachMotion
from previewctl.sim.loop import simulate
from previewctl.sim.scenario import scenario_from_dict

ROOT = Path(__file__).resolve().parents[1]
SHORT = SceneSettings(duration=3.0)
"""3 s scenes: the shortest that the planar witness accepts within a few draws."""


# ------------------------------------------------------------------------------------ scenes


def test_planar_scene_is_deterministic_crosses_the_links_and_passes_its_witness(tmp_path: Path) -> None:
    scene = generate("planar4", 1, 0, SHORT)
    assert generate("planar4", 1, 0, SHORT).document == scene.document
    assert generate("planar4", 2, 0, SHORT).document != scene.document
    assert generate("planar4", 1, 1, SHORT).document != scene.document
    scenario = scene.scenario()
    found = witness(scenario, SHORT)
    assert found.holds and "a collision-free tracking motion exists" in found.sentence
    assert "the oracle followed it" in found.sentence
    oracle = simulate(scenario, "oracle")  # what the witness ran: the scene's own (QP) execution
    assert oracle.collision_index is None and float(np.max(oracle.hand_error)) < SHORT.witness_tolerance
    # the witness's oracle run is the bench's oracle run under the QP: the sweep records it instead of running it
    spec = RunSpec("planar4", 1, 0, "oracle", "qp", settings_hash("planar4", 0, SHORT))
    timings = ("wall_time", "cpu_time", "cycle_time_median", "cycle_time_p95")
    again = run_metrics(simulate_spec(spec, scene)[1])
    assert scene.oracle_run is not None and found.oracle_run is not None
    assert {k: v for k, v in scene.oracle_run.items() if k not in timings} == {
        **{k: v for k, v in again.items() if k not in timings}, "execution": "qp", "seed": 0}
    recorded = bench_run(spec, scene)
    assert {k: recorded[k] for k in timings} == {k: scene.oracle_run[k] for k in timings}
    assert recorded["scenario"] == scenario.name and recorded["controller"] == "oracle"
    pinv = bench_run(dataclasses.replace(spec, execution="pseudoinverse"), scene)  # simulated: not the witness's
    assert pinv["execution"] == "pseudoinverse" and pinv["cpu_time"] != scene.oracle_run["cpu_time"]
    # ... but it follows the witness's plan, which is the plan it would make itself
    assert scene.oracle_plan is not None and len(scene.oracle_plan["times"]) > 10
    followed = simulate_spec(dataclasses.replace(spec, execution="pseudoinverse"), scene)[1]
    np.testing.assert_array_equal(followed.q, simulate(pseudoinverse(scenario), "oracle").q)
    # scenes.jsonl keeps the run and the plan (strict JSON, as the sweep writes it); a line written before they
    # were kept reads without them
    append_record(tmp_path / "scenes.jsonl", {**dataclasses.asdict(scene), "settings": spec.settings})
    (line,) = read_records(tmp_path / "scenes.jsonl")
    assert dataclasses.asdict(BenchScene.from_record(line)) == json.loads(json.dumps(dataclasses.asdict(scene)))
    stored, plan = ReachMotion.from_json(line["oracle_plan"]), ReachMotion.from_json(scene.oracle_plan)
    for name in ("times", "q", "S", "branch", "cells"):
        np.testing.assert_array_equal(getattr(stored, name), getattr(plan, name))
    old = BenchScene.from_record({k: v for k, v in line.items() if k not in ("oracle_run", "oracle_plan")})
    assert old.oracle_run is None and old.oracle_plan is None
    # the first obstacle is aimed at the arm's plain-tracking motion: plain tracking (the paper's eq. 19, no
    # damper) is hit, by a guarded link
    run = simulate(pseudoinverse(scenario), "none")
    assert run.collision_index is not None
    assert 0 < run.t[run.collision_index] <= 0.65 * 3.0 + 0.01
    assert np.isfinite(run.link_distances).all()


def test_planar_witness_rejects_a_motion_the_oracle_does_not_follow_within_the_tolerance() -> None:
    """The DP's "yes" is not enough: the oracle's run must keep the hand within the witness's tolerance."""
    scenario = generate("planar4", 1, 0, SHORT).scenario()
    error = 1e3 * float(np.max(simulate(scenario, "oracle").hand_error))
    found = witness(scenario, dataclasses.replace(SHORT, witness_tolerance=0.5e-3 * error / 1e3))
    assert not found.holds
    assert "a collision-free tracking motion exists" in found.sentence
    assert f"but the oracle following it leaves the path by {error:.2f} mm" in found.sentence
    assert witness(scenario, dataclasses.replace(SHORT, witness_follow=False)) == Witnessed(
        True, found.sentence.split(", but")[0])


def test_planar_witness_rejects_a_disc_that_runs_over_the_base() -> None:
    """Link 1 starts at the base: a disc reaching the base at t = 1.5 s leaves no motion past it."""
    doc = {"robot": {"source": "planar4", "q0": [0.6, 1.0, -1.2, -1.0]},
           "path": {"waypoints": [[1.9069, 1.0417], [1.6069, 0.6417]], "duration": 3.0},
           "obstacles": [{"name": "disc", "shape": "cylinder", "radius": 0.3, "length": 0.4,
                          "motion": {"type": "constant_velocity", "position": [-1.5, 0.0], "velocity": [1.0, 0.0]}}]}
    found = witness(scenario_from_dict(doc), SHORT)
    assert not found.holds and found.oracle_run is None
    stuck = float(found.sentence.split("stuck by t = ")[1].split(" s")[0])
    assert 1.0 <= stuck <= 1.5


def test_spatial_scene_is_deterministic_and_its_witness_follows_a_found_motion() -> None:
    """The necessary check, then the sampled search's motion followed by the oracle (its run recorded); without
    ``witness_follow`` the necessary check alone."""
    settings = SceneSettings(duration=3.0, witness_samples=64)
    scene = generate("panda", 0, 0, settings)
    assert generate("panda", 0, 0, settings).document == scene.document
    assert "exists every 0.25 s" in scene.witness
    assert "; sampled search: a collision-free tracking motion was found to t = 3.00 s" in scene.witness
    assert "; the oracle followed it (max hand error" in scene.witness
    assert scene.oracle_run is not None and scene.oracle_run["collision_free"]
    assert scene.oracle_run["max_hand_error"] < settings.witness_tolerance
    assert scene.oracle_plan is not None and scene.oracle_plan["times"][-1] == pytest.approx(3.0)
    necessary = witness(scene.scenario(), dataclasses.replace(settings, witness_follow=False))
    assert necessary.holds and necessary.oracle_run is None
    assert necessary.sentence.endswith("; transitions not checked")
    ball = scene.document["obstacles"][0]
    assert ball["shape"] == "sphere" and len(ball["motion"]["velocity"]) == 3


def test_generator_errors_name_the_bad_value() -> None:
    with pytest.raises(UnknownNameError, match="unknown robot 'pandas'; valid: planar4, panda, xarm7"):
        generate("pandas", 0)
    with pytest.raises(ParameterError, match="scene index must be an integer >= 0, got -1"):
        generate("planar4", -1)
    with pytest.raises(ParameterError, match="duration must be at least two control periods"):
        SceneSettings(duration=0.01)
    with pytest.raises(ParameterError, match="witness_tolerance must be > 0, got 0"):
        SceneSettings(witness_tolerance=0)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"dt": "x"}, r"^dt must be a finite number, got 'x'; valid: numbers > 0$"),
    ({"duration": float("inf")}, r"^duration must be finite, got inf$"),
    ({"duration": -1.0}, r"^duration must be > 0, got -1\.0$"),
    ({"max_draws": 0}, r"^max_draws must be >= 1, got 0$"),
    ({"witness_samples": 2.0}, r"^witness_samples must be an integer, got 2\.0; valid: integers >= 1$"),
    ({"witness_follow": "yes"}, r"^witness_follow must be true or false, got 'yes'$"),
])
def test_scene_settings_name_the_bad_value(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(ParameterError, match=message):
        SceneSettings(**kwargs)  # type: ignore[arg-type]


# ------------------------------------------------------------------------------- sweep, resume


def test_bench_end_to_end_on_a_local_dask_cluster_and_its_resume_on_a_running_scheduler(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setenv("PYTHONPATH", str(ROOT))  # the worker processes import this worktree's previewctl
    out = tmp_path / "bench"
    common = ["bench", "--scenes", "2", "--duration", "3", "--execution", "pseudoinverse", "--out", str(out)]
    assert main([*common, "--workers", "1", "--controller", "none,gradient", "--keep", "1"]) == 0  # a local cluster
    assert "4 runs done" in capsys.readouterr().out
    records = read_records(out / "results.jsonl")
    assert sorted((r["scene"], r["controller"]) for r in records) == [
        (0, "gradient"), (0, "none"), (1, "gradient"), (1, "none")]
    for r in records:
        free = r["collision_free"] and r["self_collision_free"]
        assert r["success_5mm"] == (free and r["max_hand_error"] < 5e-3)
        assert r["success_1mm"] == (free and r["max_hand_error"] < 1e-3)
        assert (r["collision_time"] is None) == r["collision_free"]
        assert (r["self_collision_time"] is None) == r["self_collision_free"]
        assert r["cycle_time_median"] <= r["cycle_time_p95"]
        assert r["host"].endswith(f"load {float(r['host'].rsplit(' ', 1)[1]):.1f}")
        assert r["commit"] == source_commit() and re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ", r["measured"])
    # the workers measured what an in-process run of the same scene measures
    scene = next(s for s in read_records(out / "scenes.jsonl") if s["index"] == 1)
    direct = simulate(pseudoinverse(scenario_from_dict(scene["document"], source=scene["document"]["name"])), "none",
                      seed=0)
    logged = next(r for r in records if r["scene"] == 1 and r["controller"] == "none")
    assert logged["max_hand_error"] == pytest.approx(float(direct.hand_error.max()), abs=1e-12)
    assert logged["collision_free"] == (direct.collision_index is None)
    report = (out / "report.md").read_text()
    assert "| none | pseudoinverse | 2 |" in report and "| gradient | pseudoinverse | 2 |" in report
    assert "rejected by the solvability witness on the way (reachability DP on a 4 deg grid, 12 steps, then " \
           "followed by the oracle)" in report
    assert (out / "success.png").read_bytes().startswith(b"\x89PNG")
    # kept: per controller and execution the first failure and the first success, each with its replay
    kept = sorted(p.name for p in (out / "runs").iterdir())
    assert kept == sorted(run_folder(r) for r in runs_to_keep(records, failures=1))
    for name in kept:
        written = {p.name for p in (out / "runs" / name).iterdir()}
        assert {"run.npz", "summary.json", "strobe.png", "replay.html"} <= written
        kept_run = next(r for r in records if run_folder(r) == name)
        assert json.loads((out / "runs" / name / "summary.json").read_text())["max_hand_error"] == pytest.approx(
            kept_run["max_hand_error"], abs=1e-12)  # simulated again, the same run
    assert f"[replay.html](runs/{kept[0]}/replay.html)" in (out / "report.md").read_text()

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        assert main([*common, "--scheduler", cluster.scheduler_address, "--controller", "none,gradient,single",
                     "--keep", "0", "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)  # --json: the whole of stdout is one document
    assert {k: printed[k] for k in ("planned", "done", "skipped", "failed", "records")} == {
        "planned": 6, "done": 2, "skipped": 4, "failed": [], "records": 6}
    again = read_records(out / "results.jsonl")
    assert len(again) == 6 and again[:4] == records
    assert sorted(r["scene"] for r in again[4:]) == [0, 1] and {r["controller"] for r in again[4:]} == {"single"}
    assert len(read_records(out / "scenes.jsonl")) == 2  # the resume reused the stored scenes


@pytest.mark.parametrize(("kwargs", "error", "message"), [
    ({"scenes": 0}, ParameterError, r"^scenes must be >= 1, got 0$"),
    ({"scenes": 2.5}, ParameterError, r"^scenes must be an integer, got 2\.5; valid: integers >= 1$"),
    ({"seeds": 3}, ParameterError, r"^seeds must be a list of integers, got 3$"),
    ({"seeds": (-1,)}, ParameterError, r"^seeds\[0\] must be >= 0, got -1$"),
    ({"seeds": ()}, ParameterError, r"^give at least one controller seed, e.g. seeds=\(0,\)$"),
    ({"scene_seed": -1}, ParameterError, r"^scene_seed must be >= 0, got -1$"),
    ({"scene_seed": 1.5}, ParameterError, r"^scene_seed must be an integer, got 1\.5; valid: integers >= 0$"),
    ({"robots": ()}, ParameterError, r"^give at least one robot; valid: planar4, panda, xarm7, a URDF file, "),
    ({"robots": "planar4"}, ParameterError, r"^robots must be a list of strings, got 'planar4'$"),
    ({"robots": ("pandas",)}, UnknownNameError, r"unknown robot 'pandas'; valid: planar4, panda, xarm7"),
    ({"controllers": ("multi", "fancy")}, UnknownNameError, r"unknown controller 'fancy'; valid: none, qp, "),
    ({"executions": ("lp",)}, UnknownNameError, r"unknown execution mode 'lp'; valid: qp, pseudoinverse"),
    ({"latencies": ("measure",)}, UnknownNameError, r"unknown latency 'measure'; valid: none, measured"),
    ({"latencies": ()}, ParameterError, r"^give at least one latency; valid: none, measured$"),
    ({"settings": {"dt": 0.01}}, ParameterError, r"^settings: .*instance of SceneSettings, got \{'dt': 0\.01\}$"),
])
def test_sweep_names_the_bad_value(kwargs: dict[str, object], error: type[Exception], message: str) -> None:
    with pytest.raises(error, match=message):
        Sweep(**kwargs)  # type: ignore[arg-type]


def test_sweep_keeps_its_settings_and_takes_lists() -> None:
    sweep = Sweep(robots=["planar4", "panda"], settings=SHORT)  # type: ignore[arg-type]
    assert sweep.robots == ("planar4", "panda") and sweep.settings is SHORT


def test_the_matrix_holds_each_distinct_run_once() -> None:
    sweep = Sweep(robots=("planar4", "panda"), scenes=2, controllers=("none", "qp", "multi", "oracle"))
    runs = [(s.robot, s.scene, s.controller, s.execution) for s in sweep.runs()]
    for robot in ("planar4", "panda"):
        for scene in (0, 1):
            expected = [("none", "pseudoinverse"), ("qp", "qp"), ("multi", "qp"), ("multi", "pseudoinverse"),
                        ("oracle", "qp"), ("oracle", "pseudoinverse")]  # the spatial oracle too
            assert [(c, e) for r, s, c, e in runs if (r, s) == (robot, scene)] == expected
    # none runs under the pseudo-inverse only, qp under the QP only: asked for under the other, they do not run
    assert Sweep(controllers=("qp",), executions=("pseudoinverse",)).runs() == []
    assert Sweep(controllers=("none",), executions=("qp",)).runs() == []
    assert [(s.controller, s.execution) for s in Sweep(controllers=("none", "qp"), executions=("qp",)).runs()] \
        == [("qp", "qp")] * 10
    # with seeds, only the controllers that draw random numbers run again
    seeded = Sweep(scenes=1, seeds=(0, 1, 2), controllers=("qp", "multi", "oracle"), executions=("qp",)).runs()
    assert [(s.seed, s.controller) for s in seeded] == [
        (0, "qp"), (0, "multi"), (0, "oracle"), (1, "multi"), (2, "multi")]
    # seeds without 0: the others still run once, as seed 0
    seeded = Sweep(scenes=1, seeds=(4, 2), controllers=("qp", "multi"), executions=("qp",)).runs()
    assert [(s.seed, s.controller) for s in seeded] == [(0, "qp"), (4, "multi"), (2, "multi")]


def test_a_measured_latency_adds_runs_of_their_own_key_for_the_replanning_controllers_only() -> None:
    """``--latency none,measured``: multi, reach and horizon run twice per scene, under distinct keys; qp and the
    oracle once, inline. A line written before runs had a latency has the inline run's key, so it is not re-run."""
    sweep = Sweep(scenes=1, controllers=("qp", "multi", "reach", "horizon", "oracle"), executions=("qp",),
                  latencies=("none", "measured"))
    runs = [(s.controller, s.latency) for s in sweep.runs()]
    assert runs == [("qp", "none"), ("multi", "none"), ("reach", "none"), ("horizon", "none"), ("oracle", "none"),
                    ("multi", "measured"), ("reach", "measured"), ("horizon", "measured")]
    keys = [s.key for s in sweep.runs()]
    assert len(set(keys)) == len(keys)
    inline = sweep.runs()[1]
    older = {k: v for k, v in dataclasses.asdict(inline).items() if k != "latency"}
    assert record_key(older) == inline.key != sweep.runs()[5].key
    assert [s.latency for s in Sweep(scenes=1, controllers=("multi",), executions=("qp",)).runs()] == ["none"]


def test_a_run_records_its_plans_cpu_times() -> None:
    assert plan_costs([]) == {}
    costs = [0.1 * k for k in range(1, 21)]  # 0.1 .. 2.0 s
    assert plan_costs(costs) == pytest.approx({"plans": 20, "plan_cpu_p50": 1.05, "plan_cpu_p95": 1.9,
                                               "plan_cpu_max": 2.0})


def test_report_shows_the_measured_latency_rows_beside_the_inline_ones(tmp_path: Path) -> None:
    timed = {"plans": 16, "plan_cpu_p50": 0.25, "plan_cpu_p95": 0.5, "plan_cpu_max": 0.75}
    records = [_record(0, "qp", False), _record(0, "multi", True), _record(1, "qp", True), _record(1, "multi", True),
               {**_record(0, "multi", True), "latency": "measured", **timed},
               {**_record(1, "multi", False), "latency": "measured", **timed}]
    text = write_report(records, [], tmp_path)[0].read_text()
    rows = [line for line in text.splitlines() if line.startswith("| multi")]
    assert rows[0].startswith("| multi | qp | 2 | 100% |")
    assert rows[1].startswith("| multi (measured latency) | qp | 2 | 50% |")
    assert "they are not bit-reproducible" in text
    assert "--latency measured,none --controller qp,multi --execution qp`" in text
    assert "| planar4 | multi (measured latency) | qp | 2 | 16 | 0.250 | 0.500 | 0.750 |" in text
    assert "| planar4 | multi | qp | 0:0 | - |" in text
    assert "| planar4 | multi (measured latency) | qp | 0:0 | 1:0 |" in text
    assert "measured latency" not in write_report(records[:4], [], tmp_path)[0].read_text()
    assert run_folder(records[4]) == "planar4_000_s0_multi_qp_measured" != run_folder(records[1])


@pytest.mark.parametrize("name", [*(n for n in CONTROLLER_NAMES if n not in SEEDED_CONTROLLERS), "single"])
def test_the_unseeded_controllers_give_one_run_for_every_seed(name: str) -> None:
    """What lets the matrix run them for seed 0 only; ``single`` shows that the scene tells the seeds apart."""
    disc = {"name": "disc", "shape": "cylinder", "radius": 0.1, "length": 0.4,
            "motion": {"type": "constant_velocity", "position": [1.3, 0.9, 0.0], "velocity": [0.0, -0.1, 0.0]}}
    scenario = scenario_from_dict(planar_doc(obstacles=[disc], timing={"duration": 1.0}))
    runs = [simulate(scenario, name, seed=seed) for seed in (0, 1)]
    assert np.array_equal(runs[0].q, runs[1].q) == (name not in SEEDED_CONTROLLERS)


def test_none_runs_the_pseudoinverse_and_qp_the_qp_whatever_the_execution_setting() -> None:
    """What lets the matrix run ``none`` under the pseudo-inverse only and ``qp`` under the QP only: the execution
    setting does not change their logs."""
    box = {"name": "wall", "shape": "box", "size": [0.1, 0.1, 0.2], "position": [1.0, 1.2, 0.0], "rpy": [0, 0, 0.3]}
    scenario = scenario_from_dict(planar_doc(obstacles=[box], timing={"duration": 5.0}))
    assert scenario.controller.params.execution == "qp"
    none, pinv = simulate(scenario, "none"), simulate(pseudoinverse(scenario), "none")
    qp = simulate(scenario, "qp")
    with pytest.warns(IgnoredSettingWarning, match="'qp' does not use execution = 'pseudoinverse'"):
        qp_pinv = simulate(pseudoinverse(scenario), "qp")
    np.testing.assert_array_equal(none.q, pinv.q)
    np.testing.assert_array_equal(qp.q, qp_pinv.q)
    assert (none.execution, qp.execution) == ("pseudoinverse", "qp")
    assert qp.collision_index is None and none.collision_index is not None  # the QP's dampers are at work


def test_local_cluster_workers_keep_freed_memory_and_dasks_thread_settings() -> None:
    """The DP's large arrays must not be handed back to the system at every step (see WORKER_MALLOC)."""
    import os

    with dask_client(workers=1) as client:
        environ = next(iter(client.run(lambda: dict(os.environ)).values()))
    assert {k: environ[k] for k in WORKER_MALLOC} == {k: str(v) for k, v in WORKER_MALLOC.items()}
    assert environ["OPENBLAS_NUM_THREADS"] == "1"  # Dask's own pre-spawn settings are kept


@pytest.mark.parametrize(("argv", "message"), [
    (["--robot", "pandas"], "unknown robot 'pandas'; valid: planar4, panda, xarm7"),
    (["--scenes", "0"], "scenes must be >= 1, got 0"),
    (["--scene-seed", "-2"], "scene_seed must be >= 0, got -2"),
    (["--controller", "none,fancy"], "unknown controller 'fancy'; valid: none, qp, gradient"),
    (["--execution", "lp"], "unknown execution mode 'lp'; valid: "),
    (["--sensing", "none,seen"], "unknown sensing 'seen'; valid: none, observed"),
    (["--motions", "wild"], "motions = 'wild' is not valid; valid: constant, surprise"),
])
def test_bench_bad_input_is_one_line_and_exit_2(
    argv: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["bench", *argv, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------------------------- report


def _record(scene: int, controller: str, ok: bool) -> dict[str, object]:
    return {"robot": "planar4", "scene": scene, "seed": 0, "controller": controller, "execution": "qp",
            "success_1mm": ok, "success_5mm": ok, "collision_free": ok, "self_collision_free": True,
            "max_hand_error": 1e-4,
            "cycle_time_median": 1e-3, "cycle_time_p95": 2e-3, "wall_time": 1.0, "cpu_time": 0.5}


def test_report_lists_where_preview_beats_and_loses_to_the_qp_baseline(tmp_path: Path) -> None:
    records = [_record(0, "qp", False), _record(0, "multi", True), _record(1, "qp", True),
               _record(1, "multi", False), _record(2, "qp", True), _record(2, "multi", True)]
    records += [{**_record(scene, "multi", ok), "execution": "pseudoinverse"} for scene, ok in ((0, False), (2, False))]
    report, figure = write_report(records, [], tmp_path)
    text = report.read_text()
    assert "| planar4 | multi | qp | 0:0 | 1:0 |" in text
    assert "| planar4 | multi | pseudoinverse | - | 2:0 |" in text  # against qp, which is always a QP
    assert "| multi | qp | 3 | 67% | 67% | 67% | 100% |" in text and "| qp | qp | 3 | 67% |" in text
    older = [{k: v for k, v in r.items() if k != "self_collision_free"} for r in records]  # recorded before self pairs
    assert "| multi | qp | 3 | 67% | 67% | 67% | n/a |" in write_report(older, [], tmp_path)[0].read_text()
    assert figure.read_bytes().startswith(b"\x89PNG")
    assert "oracle" not in text
    scene = {"robot": "planar4", "rejected": 1, "oracle_run": {"cpu_time": 1.0},
             "witness": "reachability DP on a 4 deg grid, 32 steps: ...; the oracle followed it (...)"}
    text = write_report([*records, _record(0, "oracle", True)], [scene], tmp_path)[0].read_text()
    assert "1 draws rejected by the solvability witness on the way (reachability DP on a 4 deg grid, 32 steps, " \
           "then followed by the oracle)" in text
    assert "The witness's oracle run is the `oracle` QP run of its scene (recorded, not run again" in text
    spatial = {"robot": "panda", "rejected": 2, "witness": "a collision-free configuration with the hand on the path "
               "exists every 0.25 s (64 samples; least best S 90.1); sampled search: a collision-free tracking motion "
               "was found to t = 10.00 s (best min S 85.0); the oracle followed it (max hand error 0.001 mm, no "
               "collision)"}
    text = write_report([{**r, "robot": "panda"} for r in records], [spatial], tmp_path)[0].read_text()
    assert ("panda: 1 scenes generated, 2 draws rejected by the solvability witness on the way (a collision-free "
            "configuration with the hand on the path exists every 0.25 s, then a motion found by the sampled search, "
            "then followed by the oracle).") in text


def test_results_reader_skips_a_torn_line(tmp_path: Path) -> None:
    log = tmp_path / "results.jsonl"
    append_record(log, {"run": 1, "clearance": float("inf")})
    with log.open("ab") as handle:
        handle.write(b'{"run": 2, "cle')
    append_record(log, {"run": 3, "plan": {"S": [float("nan"), 2.0], "min_S": float("-inf")}})
    assert read_records(log) == [{"run": 1, "clearance": None}, {"run": 3, "plan": {"S": [None, 2.0], "min_S": None}}]


def _outcome(scene: int, controller: str, execution: str, success: bool) -> dict[str, object]:
    return {"robot": "planar4", "scene": scene, "seed": 0, "controller": controller, "execution": execution,
            "success_5mm": success}


def test_kept_runs_are_the_first_failures_one_success_and_a_contrast_each_way() -> None:
    records = [_outcome(k, "none", "qp", k == 3) for k in range(5)]
    records += [_outcome(k, "multi", "qp", k in (1, 2)) for k in range(5)] + [_outcome(k, "qp", "qp", k in (0, 2))
                                                                             for k in range(5)]
    kept = {run_folder(r) for r in runs_to_keep(records, failures=2)}
    assert {"planar4_000_s0_none_qp", "planar4_001_s0_none_qp", "planar4_003_s0_none_qp"} <= kept  # 2 fail, 1 ok
    assert "planar4_002_s0_none_qp" not in kept and "planar4_004_s0_none_qp" not in kept
    pairs = contrasts(records)
    assert {key: (a["scene"], b["scene"]) for key, (a, b) in pairs.items()} == {
        ("planar4", True): (1, 1), ("planar4", False): (0, 0)}  # multi wins on 1, loses on 0
    assert {"planar4_001_s0_multi_qp", "planar4_001_s0_qp_qp", "planar4_000_s0_multi_qp"} <= kept


def test_report_says_when_at_which_commits_and_on_which_scenes_and_seeds_it_was_measured(tmp_path: Path) -> None:
    records = [{**_record(scene, "multi", True), "commit": "abc1234", "measured": f"2026-12-0{scene + 1}T10:00:00Z",
                "host": f"2 cores, load {scene + 0.5}"} for scene in range(3)]
    records += [{**_record(5, "qp", False), "scene_seed": 4}]  # older: no commit, no date
    text = write_report(records, [], tmp_path)[0].read_text()
    assert "measured between 2026-12-01T10:00:00Z and 2026-12-03T10:00:00Z, at commit `abc1234` (3 runs), " \
           "`unknown` (1 runs) (`unknown`: recorded before runs carried their commit). Load average of the host as " \
           "runs finished: 0.5 to 2.5" in text
    assert "from 4 runs measured" in text
    again = write_report([*records, dict(records[0])], [], tmp_path)[0].read_text()  # a run appended twice
    assert "from 4 runs measured" in again and "| multi | qp | 3 |" in again
    reproduce = "`previewctl bench --robot planar4 --scenes {} --scene-seed {} --controller {} --execution qp` |"
    assert "| planar4 | 0-2 | 0 | 0 | multi | qp | " + reproduce.format(3, 0, "multi") in text
    assert "| planar4 | 5 | 4 | 0 | qp | qp | " + reproduce.format(6, 4, "qp") in text
    every = [_record(0, name, True) | {"execution": mode} for name in CONTROLLER_NAMES for mode in EXECUTION_MODES]
    text = write_report(every, [], tmp_path)[0].read_text()  # the defaults: no --controller, no --execution
    assert "`previewctl bench --robot planar4 --scenes 1 --scene-seed 0` |" in text


def test_published_report_leaves_the_kept_runs_out_and_bad_names_are_refused(tmp_path: Path,
                                                                            capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "bench"
    out.mkdir()
    for record in (_record(0, "qp", False), _record(0, "multi", True)):
        append_record(out / "results.jsonl", record)
    site = tmp_path / "docs" / "results" / "bench-planar4.md"
    assert main(["bench", "--report-only", "--out", str(out), "--publish", str(site)]) == 0
    assert site.read_text().startswith("# previewctl bench: planar4\n")
    assert site.with_suffix(".png").read_bytes().startswith(b"\x89PNG")
    assert "](runs/" not in site.read_text()
    assert main(["bench", "--report-only", "--out", str(out), "--publish", str(tmp_path / "bench.html")]) == 2
    assert "--publish takes a Markdown file name ending in .md, got" in capsys.readouterr().err


def test_a_bench_run_does_not_warn_about_the_scene_table_it_ignores_but_logs_it() -> None:
    """Every controller of a scene gets the profile's one ``[controller]`` table: a setting one of them does not read
    is recorded in its composition, not warned about once per run."""
    document = planar_doc(controller={"name": "none", "plan_window": 6.0}, timing={"duration": 0.5})
    scene = BenchScene("planar4", 0, 0, document, rejected=0, witness="")
    spec = RunSpec("planar4", 0, 0, "none", "pseudoinverse", settings="test")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _, result, _ = simulate_spec(spec, scene)
    assert "ignored: plan_window = 6.0" in result.composition
