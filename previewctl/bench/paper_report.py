"""The report of the paper's scenes (``previewctl paper --publish``): one table per canonical scene, with the date,
the commit and the seed it was measured at."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from previewctl.bench.provenance import now, source_commit
from previewctl.files import atomic_write_bytes
from previewctl.sim.verdict import verdict_text


def _millimetres(value: float | None) -> str:
    return "-" if value is None else f"{value * 1e3:.1f}"


def _table(summaries: dict[str, dict[str, Any]]) -> list[str]:
    lines = ["| run | success | max hand error [mm] | min clearance [mm] | min self distance [mm] | mean S | min S | "
             "cycle p50 / p99 / max [ms] |", "|---|---|---|---|---|---|---|---|"]
    for label, s in summaries.items():
        cycle = " / ".join(f"{s[key] * 1e3:.2f}" for key in ("cycle_time_median", "cycle_time_p99", "cycle_time_max"))
        lines.append(f"| {label} | {verdict_text(s, digits=2)} | {s['max_hand_error'] * 1e3:.2f} | "
                     f"{_millimetres(s['min_clearance'])} | {_millimetres(s['min_self_distance'])} | "
                     f"{s['mean_S']:.0f} | {s['min_S']:.0f} | {cycle} |")
    return lines


def write_paper_report(results: dict[str, dict[str, dict[str, Any]]], path: Path, seed: int | None) -> Path:
    """Write the report of ``results`` (``{scene: {label: summary}}``, as :func:`~previewctl.sim.paper.
    run_paper_scenes` returns them) to the Markdown file ``path``.

    Args:
        results: the runs' summaries.
        path: the report file (its folder is created).
        seed: the seed the runs were made with (``None``: each scenario's own).
    """
    command = "previewctl paper" + (f" --seed {seed}" if seed is not None else "")
    lines = ["# The paper's scenes", "",
             f"Generated {now()} by `{command}` at commit `{source_commit()}`, seed "
             f"{seed if seed is not None else 'of each scenario file'}. Success = no collision with an obstacle or "
             "of the arm with itself, and the hand within the scene's tolerance over the whole run. A label "
             "`<name>-pinv` is the controller executed by the paper's pseudo-inverse (eq. 19); the others run under "
             "the QP. Cycle times are wall-clock times of `Controller.step` on the machine that made the report.", ""]
    for scene, summaries in results.items():
        first = next(iter(summaries.values()))
        lines += [f"## {scene}", "", f"`scenarios/{scene}.toml`, {first['duration']:g} s, tolerance "
                  f"{first['tolerance'] * 1e3:g} mm.", "", *_table(summaries), ""]
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, "\n".join(lines).encode("utf-8"))
    return path
