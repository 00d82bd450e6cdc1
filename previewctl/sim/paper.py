"""The paper's planar experiment (section 7) with every controller, on the canonical scenes.

The canonical scenes (:data:`CANONICAL_SCENES`, in the order ``previewctl paper`` runs them):

* ``paper_fitted``: the path fitted to the paper's Table 3 (global optima at A-F) with the object the
  hand traces (``examples/fit_paper_path.py`` recomputes the fit);
* ``paper_planar``: the inverted staircase with a pillar, a harder trap of two mirror families.

Controllers and their parameters (the paper's where it gives them):

* ``none``: eq. 19 with feedback, no null-space term (baseline);
* ``gradient``: local null-space ascent of AMSIP (a local-method baseline);
* ``single``: eq. 20, one imaginary arm at ``t + 10 s`` (section 7.1);
* ``multi``: eq. 21, three imaginary arms at ``t + 5, 10, 15 s``, ``k = (0.3, 0.65, 0.05)`` (section 7.2);
* ``reach``: the reachability sequence of Fig. 3 over the same three preview times and weights.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import os
from collections.abc import Callable, Sequence
from importlib import resources
from pathlib import Path
from typing import Any

from previewctl.control.params import CONTROLLER_NAMES, PAPER_WEIGHTS, ControllerSpec
from previewctl.errors import PreviewctlError
from previewctl.files import atomic_write_bytes
from previewctl.sim.log import RunResult, save_run
from previewctl.sim.loop import simulate
from previewctl.sim.scenario import Scenario, load_scenario

_PAPER_PARAMETERS: dict[str, dict[str, Any]] = {
    "single": {"preview_time": 10.0},
    "multi": {"preview_time": 5.0, "weights": PAPER_WEIGHTS},
    "reach": {"preview_time": 5.0, "weights": PAPER_WEIGHTS},
}
PAPER_CONTROLLERS: dict[str, dict[str, Any]] = {name: _PAPER_PARAMETERS.get(name, {}) for name in CONTROLLER_NAMES}
"""Every controller, with its parameter overrides (on top of the scenario's ``[controller]`` table)."""


def shipped_scenarios_dir() -> Path:
    """The folder of scenarios shipped with previewctl (inside the wheel, or the repo's ``scenarios/``)."""
    packaged = resources.files("previewctl").joinpath("scenarios")
    if packaged.is_dir():
        return Path(str(packaged))
    return Path(__file__).resolve().parents[2] / "scenarios"


CANONICAL_SCENES: tuple[str, ...] = ("paper_fitted", "paper_planar")
"""The canonical planar scenes (``scenarios/<name>.toml``), the one fitted to the paper's tables first."""


def canonical_scenario(name: str = CANONICAL_SCENES[0]) -> Scenario:
    """A canonical planar scene, ``scenarios/<name>.toml`` (default: the Table-3 fit, ``paper_fitted``).

    Raises:
        PreviewctlError: ``name`` is not one of :data:`CANONICAL_SCENES`.
    """
    if name not in CANONICAL_SCENES:
        raise PreviewctlError(f"unknown canonical scene {name!r}; valid: {', '.join(CANONICAL_SCENES)}")
    return load_scenario(shipped_scenarios_dir() / f"{name}.toml")


def with_controller(scenario: Scenario, name: str) -> Scenario:
    """``scenario`` with controller ``name`` and the paper's parameters for it."""
    if name not in PAPER_CONTROLLERS:
        raise PreviewctlError(f"unknown controller {name!r}; valid: {', '.join(PAPER_CONTROLLERS)}")
    params = dataclasses.replace(scenario.controller.params, **PAPER_CONTROLLERS[name])
    return dataclasses.replace(scenario, controller=ControllerSpec(name, params))


def run_paper(
    out_dir: str | os.PathLike[str],
    *,
    controllers: Sequence[str] = tuple(PAPER_CONTROLLERS),
    seed: int | None = None,
    scenario: Scenario | None = None,
    progress: Callable[[str], Callable[[float, float], None]] | None = None,
    after_run: Callable[[str, Scenario, RunResult, Path], None] | None = None,
    tolerance: float | None = None,
) -> dict[str, dict[str, Any]]:
    """Run one scene with each controller; write each run and ``summary.json``.

    Args:
        out_dir: output folder; each controller's log goes to ``out_dir/<name>/``.
        controllers: which controllers, in order.
        seed: random seed (default: the scenario's).
        scenario: the scene (default :func:`canonical_scenario`, the Table-3 fit).
        progress: ``progress(name)`` returns the progress callback of that controller's run.
        after_run: called after each run with (name, scenario, result, folder), e.g. to draw figures.
        tolerance: largest hand error [m] of a successful run (default: the scenario's).

    Returns:
        The summary per controller (also written, atomically, to ``out_dir/summary.json``).
    """
    base = scenario or canonical_scenario()
    out = Path(out_dir)
    summaries: dict[str, dict[str, Any]] = {}
    for name in controllers:
        run_scenario = with_controller(base, name)
        result = simulate(run_scenario, name, progress=progress(name) if progress else None, seed=seed,
                          tolerance=tolerance)
        folder = out / name
        save_run(result, folder)
        if after_run is not None:
            after_run(name, run_scenario, result, folder)
        summaries[name] = result.summary()
    text = (json.dumps(summaries, indent=2) + "\n").encode("utf-8")
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(out / "summary.json", text)
    return summaries


def run_paper_scenes(
    out_dir: str | os.PathLike[str],
    *,
    scenes: Sequence[str] = CANONICAL_SCENES,
    controllers: Sequence[str] = tuple(PAPER_CONTROLLERS),
    seed: int | None = None,
    progress: Callable[[str, str], Callable[[float, float], None]] | None = None,
    after_run: Callable[[str, Scenario, RunResult, Path], None] | None = None,
    tolerance: float | None = None,
) -> dict[str, dict[str, dict[str, Any]]]:
    """:func:`run_paper` on each canonical scene, into ``out_dir/<scene>/<controller>/``.

    Args:
        out_dir: output folder; ``out_dir/<scene>/summary.json`` per scene and ``out_dir/summary.json``
            with every scene.
        scenes: which canonical scenes, in order (names of :data:`CANONICAL_SCENES`).
        controllers: which controllers, in order.
        seed: random seed (default: each scenario's).
        progress: ``progress(scene, controller)`` returns the progress callback of that run.
        after_run: as in :func:`run_paper`.
        tolerance: as in :func:`run_paper`.

    Returns:
        ``{scene: {controller: summary}}`` (also written, atomically, to ``out_dir/summary.json``).

    Raises:
        PreviewctlError: an unknown scene or controller name (checked before anything runs).
    """
    for name in controllers:
        if name not in PAPER_CONTROLLERS:
            raise PreviewctlError(f"unknown controller {name!r}; valid: {', '.join(PAPER_CONTROLLERS)}")
    loaded = [canonical_scenario(scene) for scene in scenes]
    out = Path(out_dir)
    results: dict[str, dict[str, dict[str, Any]]] = {}
    for scene, scenario in zip(scenes, loaded, strict=True):
        per_run = None if progress is None else functools.partial(progress, scene)
        results[scene] = run_paper(
            out / scene, controllers=controllers, seed=seed, scenario=scenario, progress=per_run, after_run=after_run,
            tolerance=tolerance,
        )
    text = (json.dumps(results, indent=2) + "\n").encode("utf-8")
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(out / "summary.json", text)
    return results
