"""The runs a sweep keeps for a person to look at: each one's log, figures and 3-D replay.

Per robot, controller and execution mode: the first :data:`FAILURES_KEPT` failed runs (success < 5 mm
not met) and the first successful one; and per robot, the first scene where ``multi`` (under the QP)
succeeds and ``qp`` fails, and the first where it is the other way round, with both runs of each (the
report shows their strobe plots side by side). A kept run is simulated again on a worker (the runs are
deterministic: same scene, seed, controller and execution give the same log) and written to
``OUT/runs/<robot>_<scene>_s<seed>_<controller>_<execution>/`` (:func:`run_folder`; ``<robot>``: its
:func:`~previewctl.bench.robots.robot_label`) through an atomic folder. A folder that
already holds its replay is not redone, so a resumed sweep keeps only what is missing.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from previewctl.bench.robots import robot_label
from previewctl.bench.runs import INLINE, KNOWN, RunSpec, simulate_spec
from previewctl.bench.scenes import BenchScene
from previewctl.control.params import run_seed
from previewctl.files import atomic_folder
from previewctl.sim.log import save_run
from previewctl.viz.figures import make_figures
from previewctl.viz.replay import REPLAY_NAME, write_replay

RUNS_FOLDER = "runs"
FAILURES_KEPT = 2
"""Failed runs kept per robot, controller and execution mode."""
CONTRAST = ("multi", "qp")
"""The preview mode and the baseline whose disagreements are kept: a scene each way."""


def run_folder(record: dict[str, Any]) -> str:
    """The folder name of a run under ``OUT/runs/`` (``..._measured`` for a run with a measured latency,
    ``..._observed`` for one that observed the obstacles)."""
    latency, sensing = record.get("latency", INLINE), record.get("sensing", KNOWN)
    return (f"{robot_label(record['robot'])}_{record['scene']:03d}_s{record['seed']}_{record['controller']}_"
            f"{record['execution']}" + ("" if latency == INLINE else f"_{latency}")
            + ("" if sensing == KNOWN else f"_{sensing}"))


def contrasts(records: list[dict[str, Any]]) -> dict[tuple[str, bool], tuple[dict[str, Any], dict[str, Any]]]:
    """Per (robot, whether the preview mode wins): the first scene's (preview run, baseline run) result lines,
    both under the QP, where exactly one of them succeeds (< 5 mm)."""
    preview, baseline = CONTRAST
    by_key = {(r["robot"], r["scene"], r["seed"], r["controller"], r["execution"]): r
              for r in sorted(records, key=lambda r: (r["robot"], r["scene"], r["seed"]))
              if r.get("latency", INLINE) == INLINE and r.get("sensing", KNOWN) == KNOWN}
    pairs: dict[tuple[str, bool], tuple[dict[str, Any], dict[str, Any]]] = {}
    for (robot, scene, seed, controller, execution), r in by_key.items():
        base = by_key.get((robot, scene, run_seed(baseline, seed), baseline, "qp"))
        if controller == preview and execution == "qp" and base is not None and r["success_5mm"] != base["success_5mm"]:
            pairs.setdefault((robot, bool(r["success_5mm"])), (r, base))
    return pairs


def runs_to_keep(records: list[dict[str, Any]], failures: int = FAILURES_KEPT) -> list[dict[str, Any]]:
    """The result lines of the runs to keep (see the module docstring), each once."""
    kept: dict[str, dict[str, Any]] = {}
    counts: dict[tuple[str, str, str, str, str, bool], int] = {}
    for r in sorted(records, key=lambda r: (r["robot"], r["scene"], r["seed"])):
        group = (r["robot"], r["controller"], r["execution"], r.get("latency", INLINE), r.get("sensing", KNOWN),
                 bool(r["success_5mm"]))
        if counts.get(group, 0) < (1 if r["success_5mm"] else failures):
            counts[group] = counts.get(group, 0) + 1
            kept.setdefault(run_folder(r), r)
    for pair in contrasts(records).values():
        for r in pair:
            kept.setdefault(run_folder(r), r)
    return list(kept.values())


def keep_run(spec: RunSpec, scene: BenchScene, folder: str) -> str:
    """Simulate ``spec`` again and write its log, figures (no GIF) and replay into ``folder``; the folder."""
    scenario, result, _ = simulate_spec(spec, scene)
    with atomic_folder(Path(folder)) as tmp:
        save_run(result, tmp)
        make_figures(result, scenario, tmp, gif=False)
        write_replay(result, tmp / REPLAY_NAME, scenario=scenario)
    return folder
