"""The paper's planar experiment (section 7) with every controller, on the canonical scenes.

The canonical scenes (:data:`CANONICAL_SCENES`, in the order ``previewctl paper`` runs them):

* ``paper_fitted``: the path fitted to the paper's Table 3 (global optima at A-F) with the object the
  hand traces (``examples/fit_paper_path.py`` recomputes the fit);
* ``paper_planar``: the inverted staircase with a pillar, a harder trap of two mirror families.

Controllers and their parameters (the paper's where it gives them):

* ``none``: eq. 19 with feedback, no null-space term (baseline);
* ``qp``: the same with the constrained QP of :mod:`previewctl.control.execution` (the velocity-damper
  method of NEO: the peer baseline);
* ``gradient``: local null-space ascent of AMSIP (a local-method baseline);
* ``single``: eq. 20, one imaginary arm at ``t + 10 s`` (section 7.1);
* ``multi``: eq. 21, three imaginary arms at ``t + 5, 10, 15 s``, ``k = (0.3, 0.65, 0.05)`` (section 7.2), on the
  route ``reach`` plans (Fig. 3);
* ``reach``: the reachability sequence of Fig. 3 over the same three preview times and weights;
* ``horizon``: the reachability DP over the preview window ``[t, t + 15 s]``, replanned every 2.5 s;
* ``oracle``: the reachability DP's best motion (non-causal: a reference).

Each controller runs under both executions (:data:`~previewctl.control.params.EXECUTION_MODES`): the QP
(the default, labelled with the controller's name) and the paper's pseudo-inverse eq. 19 (labelled
``<name>-pinv``). ``none`` under the QP is the ``qp`` baseline and ``qp`` is always a QP, so the pair
``none``/``qp`` gives two runs, ``qp`` and ``none-pinv`` (:func:`paper_runs`).
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from previewctl.control.params import (
    CONTROLLER_NAMES,
    EXECUTION_MODES,
    PAPER_WEIGHTS,
    ControllerSpec,
    controller_runs,
)
from previewctl.errors import PreviewctlError, shared_settings
from previewctl.files import atomic_folder, atomic_write_bytes, check_output_folder
from previewctl.sim.log import RunResult, save_run
from previewctl.sim.loop import simulate
from previewctl.sim.scenario import Scenario, load_scenario
from previewctl.sim.start import check_start

_PAPER_PARAMETERS: dict[str, dict[str, Any]] = {
    "single": {"preview_time": 10.0},
    "multi": {"preview_time": 5.0, "weights": PAPER_WEIGHTS},
    "reach": {"preview_time": 5.0, "weights": PAPER_WEIGHTS},
}
PAPER_CONTROLLERS: dict[str, dict[str, Any]] = {name: _PAPER_PARAMETERS.get(name, {}) for name in CONTROLLER_NAMES}
"""Every controller, with its parameter overrides (on top of the scenario's ``[controller]`` table)."""


PINV_SUFFIX = "-pinv"
"""Label suffix of a run executed by the pseudo-inverse eq. 19 (the QP runs carry the bare controller name)."""


def paper_runs(controllers: Sequence[str], executions: Sequence[str] = EXECUTION_MODES) -> dict[str, tuple[str, str]]:
    """The runs of ``controllers`` × ``executions`` as ``{label: (controller, execution)}``, in order.

    ``none`` runs under the pseudo-inverse only and ``qp`` under the QP only
    (:func:`~previewctl.control.params.controller_runs`).
    """
    runs: dict[str, tuple[str, str]] = {}
    for execution in executions:
        for controller, _ in controller_runs(controllers, [execution]):
            runs[controller if execution == "qp" else controller + PINV_SUFFIX] = (controller, execution)
    return runs


def shipped_scenarios_dir() -> Path:
    """The folder of scenarios shipped with previewctl (inside the wheel, or the repo's ``scenarios/``)."""
    packaged = resources.files("previewctl").joinpath("scenarios")
    if packaged.is_dir():
        return Path(str(packaged))
    return Path(__file__).resolve().parents[2] / "scenarios"


CANONICAL_SCENES: tuple[str, ...] = ("paper_fitted", "paper_planar")
"""The canonical planar scenes (``scenarios/<name>.toml``), the one fitted to the paper's tables first."""


def _require(kind: str, names: Sequence[str], valid: Sequence[str]) -> None:
    """Raise :class:`PreviewctlError` naming the first of ``names`` that is not in ``valid`` (and the valid ones)."""
    for name in names:
        if name not in valid:
            raise PreviewctlError(f"unknown {kind} {name!r}; valid: {', '.join(valid)}")


def canonical_scenario(name: str = CANONICAL_SCENES[0]) -> Scenario:
    """A canonical planar scene, ``scenarios/<name>.toml`` (default: the Table-3 fit, ``paper_fitted``).

    Raises:
        PreviewctlError: ``name`` is not one of :data:`CANONICAL_SCENES`.
    """
    _require("canonical scene", [name], CANONICAL_SCENES)
    return load_scenario(shipped_scenarios_dir() / f"{name}.toml")


def with_controller(scenario: Scenario, name: str, execution: str | None = None) -> Scenario:
    """``scenario`` with controller ``name``, the paper's parameters for it and ``execution`` (default: the
    scenario's)."""
    _require("controller", [name], tuple(PAPER_CONTROLLERS))
    changes = dict(PAPER_CONTROLLERS[name]) | ({} if execution is None else {"execution": execution})
    params = dataclasses.replace(scenario.controller.params, **changes)
    return dataclasses.replace(scenario, controller=ControllerSpec(name, params))


@dataclass(frozen=True)
class PaperRun:
    """One run of ``previewctl paper``: a canonical scene, a controller and an execution, under a label."""

    scene: str
    label: str
    controller: str
    execution: str


def paper_plan(scenes: Sequence[str], controllers: Sequence[str], executions: Sequence[str]) -> list[PaperRun]:
    """The runs of ``scenes`` × :func:`paper_runs`, in order.

    Raises:
        PreviewctlError: an unknown scene, controller or execution name.
    """
    _require("controller", controllers, tuple(PAPER_CONTROLLERS))
    _require("execution", executions, EXECUTION_MODES)
    _require("canonical scene", scenes, CANONICAL_SCENES)
    runs = paper_runs(controllers, executions)
    return [PaperRun(scene, label, *runs[label]) for scene in scenes for label in runs]


AfterRun = Callable[[str, Scenario, RunResult, Path], None]
"""``after_run(label, scenario, result, folder)``, called where the run ran (e.g. to draw its figures); it must
pickle (a module-level function or a ``functools.partial`` of one) when runs go to worker processes."""


def run_one(
    run: PaperRun,
    out_dir: Path,
    seed: int | None = None,
    after_run: AfterRun | None = None,
    tolerance: float | None = None,
) -> dict[str, Any]:
    """Simulate one run, save it to ``out_dir/<scene>/<label>/`` and return its summary (``after_run`` gets the
    run's temporary folder, which becomes ``out_dir/<scene>/<label>/`` once it returns)."""
    scenario = with_controller(canonical_scenario(run.scene), run.controller, run.execution)
    with shared_settings():
        result = simulate(scenario, run.controller, seed=seed, tolerance=tolerance)
    with atomic_folder(out_dir / run.scene / run.label) as folder:  # each run's folder is replaced whole
        save_run(result, folder)
        if after_run is not None:
            after_run(run.label, scenario, result, folder)
    return result.summary()


def run_paper_scenes(
    out_dir: str | os.PathLike[str],
    *,
    scenes: Sequence[str] = CANONICAL_SCENES,
    controllers: Sequence[str] = tuple(PAPER_CONTROLLERS),
    executions: Sequence[str] = EXECUTION_MODES,
    seed: int | None = None,
    jobs: int = 1,
    on_done: Callable[[PaperRun, dict[str, Any]], None] | None = None,
    after_run: AfterRun | None = None,
    tolerance: float | None = None,
) -> dict[str, dict[str, dict[str, Any]]]:
    """Every controller under every execution on each canonical scene, into ``out_dir/<scene>/<label>/``.

    Args:
        out_dir: output folder; ``out_dir/<scene>/summary.json`` per scene and ``out_dir/summary.json``
            with every scene.
        scenes: which canonical scenes, in order (names of :data:`CANONICAL_SCENES`).
        controllers: which controllers, in order.
        executions: which executions, in order (:func:`paper_runs` labels the runs).
        seed: random seed (default: each scenario's).
        jobs: worker processes (1: in this process); the runs are independent, so the results do not depend on it.
        on_done: called as ``on_done(run, summary)`` when each run finishes (in completion order).
        after_run: see :data:`AfterRun`.
        tolerance: largest hand error [m] of a successful run (default: each scenario's).

    Returns:
        ``{scene: {label: summary}}`` in plan order (also written, atomically, to ``out_dir/summary.json``).

    Raises:
        PreviewctlError: an unknown scene, controller or execution name, or a scene whose start collides
            (:class:`~previewctl.errors.StartCollisionError`); checked before anything runs.
    """
    plan = paper_plan(scenes, controllers, executions)
    for scene in dict.fromkeys(run.scene for run in plan):  # a start in collision: refused before anything runs
        check_start(canonical_scenario(scene))
    out = check_output_folder(out_dir)
    summaries: dict[PaperRun, dict[str, Any]] = {}
    if jobs <= 1:
        for run in plan:
            summaries[run] = run_one(run, out, seed, after_run, tolerance)
            if on_done is not None:
                on_done(run, summaries[run])
    else:
        with ProcessPoolExecutor(jobs) as pool:
            futures = {pool.submit(run_one, run, out, seed, after_run, tolerance): run for run in plan}
            for future in as_completed(futures):
                run = futures[future]
                summaries[run] = future.result()
                if on_done is not None:
                    on_done(run, summaries[run])
    results: dict[str, dict[str, dict[str, Any]]] = {}
    for run in plan:
        results.setdefault(run.scene, {})[run.label] = summaries[run]
    for scene, per_scene in results.items():
        atomic_write_bytes(out / scene / "summary.json", (json.dumps(per_scene, indent=2) + "\n").encode("utf-8"))
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(out / "summary.json", (json.dumps(results, indent=2) + "\n").encode("utf-8"))
    return results
