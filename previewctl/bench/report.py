"""The benchmark report: success rates per robot, controller and execution mode, and preview against ``qp``.

Read from the results file alone, so a report can be remade at any time (``previewctl bench --report-only``).
"""

from __future__ import annotations

import re
import statistics
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any

from previewctl.bench.keep import CONTRAST, RUNS_FOLDER, contrasts, run_folder, runs_to_keep
from previewctl.bench.pink import BARRIER_GAINS
from previewctl.bench.provenance import UNKNOWN, now
from previewctl.bench.runs import INLINE, KNOWN, record_key
from previewctl.control import params as control_params
from previewctl.files import atomic_write_bytes
from previewctl.viz.bench import plot_success
from previewctl.viz.replay import REPLAY_NAME

REPORT_NAME = "report.md"
FIGURE_NAME = "success.png"
BASELINE = "qp"
"""The peer method preview is compared with: QP tracking with no null-space preference."""

LOOKING_AHEAD = (*control_params.PREVIEW_MODES, "horizon")
"""The causal controllers that read the future (the preview modes and ``horizon``): each is set against ``qp``."""


def _rate(rows: list[dict[str, Any]], key: str) -> float:
    return sum(bool(r[key]) for r in rows) / len(rows)


def _latency(record: dict[str, Any]) -> str:
    """A run's latency (a line written before runs had one is inline)."""
    return str(record.get("latency", INLINE))


def _sensing(record: dict[str, Any]) -> str:
    """A run's sensing (a line written before runs had one ran with perfect foresight)."""
    return str(record.get("sensing", KNOWN))


def _tagged(controller: str, latency: str, sensing: str) -> str:
    """The row label of ``controller`` run with ``latency`` and ``sensing``: e.g. ``multi``, ``multi (measured
    latency)``, ``multi (observed)``."""
    tags = ([] if latency == INLINE else [f"{latency} latency"]) + ([] if sensing == KNOWN else [sensing])
    return f"{controller} ({', '.join(tags)})" if tags else controller


def _label(record: dict[str, Any]) -> str:
    """A run's row: its controller, tagged when its plans took effect after their measured compute time or when it
    observed the obstacles (:func:`_tagged`)."""
    return _tagged(record["controller"], _latency(record), _sensing(record))


def _order(cell: tuple[str, str]) -> tuple[int, str, int, str]:
    """Controllers (each inline row, then its latency rows) and execution modes in the order the package lists them
    (unknown names last)."""
    controllers, executions = control_params.CONTROLLER_NAMES, control_params.EXECUTION_MODES
    label, execution = cell
    controller = label.split(" (")[0]
    return (controllers.index(controller) if controller in controllers else len(controllers), label,
            executions.index(execution) if execution in executions else len(executions), execution)


def _groups(records: list[dict[str, Any]]) -> dict[str, dict[tuple[str, str], list[dict[str, Any]]]]:
    """Records per robot (in the order they first appear), then per ``(row label, execution)`` (:func:`_label`,
    :func:`_order`)."""
    groups: dict[str, dict[tuple[str, str], list[dict[str, Any]]]] = defaultdict(lambda: defaultdict(list))
    for r in records:
        groups[r["robot"]][(_label(r), r["execution"])].append(r)
    return {robot: dict(sorted(cells.items(), key=lambda item: _order(item[0]))) for robot, cells in groups.items()}


def _self_free(rows: list[dict[str, Any]]) -> str:
    """The share of runs free of self-collision; ``n/a`` for results recorded before self pairs were checked."""
    known = [r for r in rows if "self_collision_free" in r]
    return f"{_rate(known, 'self_collision_free'):.0%}" if known else "n/a"


def _span(values: list[int]) -> str:
    """``0-29`` for a contiguous run of integers, else the sorted list."""
    ordered = sorted(set(values))
    if ordered == list(range(ordered[0], ordered[-1] + 1)) and len(ordered) > 2:
        return f"{ordered[0]}-{ordered[-1]}"
    return ", ".join(map(str, ordered))


def _provenance(records: list[dict[str, Any]]) -> list[str]:
    """When and at which commits the records were measured, and the scenes and seeds they cover."""
    commits: dict[str, int] = defaultdict(int)
    for r in records:
        commits[r.get("commit", UNKNOWN)] += 1
    dates = sorted(r["measured"] for r in records if "measured" in r)
    loads = sorted(float(r["host"].rsplit(" ", 1)[1]) for r in records if "host" in r)
    when = f"between {dates[0]} and {dates[-1]}" if dates else "at dates not recorded"
    at = ", ".join(f"`{commit}` ({count} runs)" for commit, count in sorted(commits.items(), key=lambda c: -c[1]))
    lines = [f"Generated {now()} by `previewctl bench` from {len(records)} runs measured {when}, at commit {at}"
             + (f" (`{UNKNOWN}`: recorded before runs carried their commit)" if UNKNOWN in commits else "") + "."
             + (f" Load average of the host as runs finished: {loads[0]:.1f} to {loads[-1]:.1f} (cycle and CPU times "
                "are slower on a loaded host)." if loads else ""), "",
             "| robot | scenes | scene seed | controller seeds | controllers | executions | reproduce |",
             "|---|---|---|---|---|---|---|"]
    for robot, cells in _groups(records).items():
        rows = [r for cell in cells.values() for r in cell]
        for scene_seed in sorted({r.get("scene_seed", 0) for r in rows}):
            mine = [r for r in rows if r.get("scene_seed", 0) == scene_seed]
            scenes = sorted({r["scene"] for r in mine})
            controllers = sorted({r["controller"] for r in mine}, key=lambda c: _order((c, ""))[0])
            executions = sorted({r["execution"] for r in mine})
            command = f"previewctl bench --robot {robot} --scenes {scenes[-1] + 1} --scene-seed {scene_seed}"
            latencies = sorted({_latency(r) for r in mine})
            command += f" --latency {','.join(latencies)}" if latencies != [INLINE] else ""
            every = set(control_params.CONTROLLER_NAMES), set(control_params.EXECUTION_MODES)  # the defaults
            command += f" --controller {','.join(controllers)}" if set(controllers) != every[0] else ""
            command += f" --execution {','.join(executions)}" if set(executions) != every[1] else ""
            sensings = sorted({_sensing(r) for r in mine})
            command += f" --sensing {','.join(sensings)}" if sensings != [KNOWN] else ""
            motions = sorted({r.get("motions", "constant") for r in mine})
            command += f" --motions {','.join(motions)}" if motions != ["constant"] else ""
            histories = sorted({float(r.get("history", 0.0)) for r in mine})
            command += f" --history {','.join(f'{h:g}' for h in histories)}" if histories != [0.0] else ""
            lines.append(f"| {robot} | {_span(scenes)} | {scene_seed} | {_span([r['seed'] for r in mine])} | "
                         f"{', '.join(controllers)} | {', '.join(executions)} | `{command}` |")
    return [*lines, ""]


def _rates_table(robot: str, cells: dict[tuple[str, str], list[dict[str, Any]]]) -> list[str]:
    scenes = len({(r["scene"], r["seed"]) for rows in cells.values() for r in rows})
    lines = [f"### {robot} ({scenes} scene-seed pairs)", "",
             "| controller | execution | runs | success < 1 mm | success < 5 mm | collision-free | "
             "self-collision-free | median max error [mm] | cycle median / p95 [ms] | CPU per run [s] |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for (controller, execution), rows in cells.items():
        error = statistics.median(r["max_hand_error"] for r in rows) * 1e3
        cycle = statistics.median(r["cycle_time_median"] for r in rows) * 1e3
        p95 = statistics.median(r["cycle_time_p95"] for r in rows) * 1e3
        cost = statistics.mean(r["cpu_time"] for r in rows)
        lines.append(f"| {controller} | {execution} | {len(rows)} | {_rate(rows, 'success_1mm'):.0%} | "
                     f"{_rate(rows, 'success_5mm'):.0%} | {_rate(rows, 'collision_free'):.0%} | "
                     f"{_self_free(rows)} | {error:.2f} | "
                     f"{cycle:.2f} / {p95:.2f} | {cost:.1f} |")
    return [*lines, ""]


def _plan_costs(groups: dict[str, dict[tuple[str, str], list[dict[str, Any]]]]) -> list[str]:
    """Per row that made plans: the plans per run and their CPU time (the medians over the runs of each run's p50
    and p95, and the largest), from the runs that recorded them."""
    lines = ["## Plan CPU time per row (each run's median and p95, their medians over the runs; the max over all)", "",
             "| robot | controller | execution | runs | plans per run | plan CPU p50 [s] | p95 [s] | max [s] |",
             "|---|---|---|---|---|---|---|---|"]
    rows = 0
    for robot, cells in groups.items():
        for (label, execution), records in cells.items():
            timed = [r for r in records if "plan_cpu_p50" in r]
            if not timed:
                continue
            rows += 1
            lines.append(f"| {robot} | {label} | {execution} | {len(timed)} | "
                         f"{statistics.median(r['plans'] for r in timed):.0f} | "
                         f"{statistics.median(r['plan_cpu_p50'] for r in timed):.3f} | "
                         f"{statistics.median(r['plan_cpu_p95'] for r in timed):.3f} | "
                         f"{max(r['plan_cpu_max'] for r in timed):.3f} |")
    return [*lines, ""] if rows else []


def _against_baseline(records: list[dict[str, Any]], baseline: str = BASELINE,
                      contenders: tuple[str, ...] = (*LOOKING_AHEAD, *BARRIER_GAINS)) -> list[str]:
    """Scenes where a contender (by default a controller that looks ahead, or a pink baseline) succeeds (< 1 mm) and
    ``baseline`` fails, and the reverse, per robot and execution of the contender (``qp`` and the pink baselines are
    always a QP, and the same run for every seed)."""
    outcome = {(r["robot"], r["scene"], r["seed"], _label(r), r["execution"]): r for r in records}
    pink = any(r["controller"] in contenders and r["controller"] in BARRIER_GAINS for r in records)
    what = "Preview and pink" if pink else "Preview"
    lines = [f"## {what} against the `{baseline}` baseline (success < 1 mm, same scene; the baseline is always "
             "executed by the QP and draws no random numbers: its seed-0 run stands for every seed)", ""]
    if not any(r["controller"] == baseline for r in records):
        return [*lines, f"No `{baseline}` runs in these results: nothing to compare with.", ""]
    lines += [f"| robot | controller | execution | beats {baseline} on (scene:seed) | loses to {baseline} on "
              "(scene:seed) |", "|---|---|---|---|---|"]
    pairs: dict[tuple[str, str, str], tuple[list[str], list[str]]] = defaultdict(lambda: ([], []))
    for (robot, scene, seed, controller, execution), r in sorted(outcome.items()):
        base = outcome.get((robot, scene, control_params.run_seed(baseline, seed),
                            _tagged(baseline, INLINE, _sensing(r)), "qp"))  # the baseline fed what the row was fed
        if r["controller"] not in contenders or base is None or r["success_1mm"] == base["success_1mm"]:
            continue
        pairs[(robot, controller, execution)][0 if r["success_1mm"] else 1].append(f"{scene}:{seed}")
    for (robot, controller, execution), (wins, losses) in sorted(pairs.items()):
        lines.append(f"| {robot} | {controller} | {execution} | {', '.join(wins) or '-'} | "
                     f"{', '.join(losses) or '-'} |")
    return [*lines, ""]


def _pink_note(records: list[dict[str, Any]]) -> list[str]:
    """When pink baselines ran: what they are and model, their gains, and their cycle time beside previewctl's
    (the medians over the runs of each run's median control cycle [ms], per robot)."""
    names = [name for name in BARRIER_GAINS if any(r["controller"] == name for r in records)]
    if not names:
        return []
    gains = ", ".join(f"`{name}` γ = {BARRIER_GAINS[name]:g} 1/s" for name in names)
    lines = ["## The pink baselines", "",
             f"Rows {', '.join(f'`{name}`' for name in names)} are [pink](https://github.com/stephane-caron/pink)'s "
             "differential IK (`solve_ik`) as its examples use it, stepped by the same simulator and checked by the "
             "same exact check: a position-only `FrameTask` on the hand (target `r_d(t + dt)`: pink's tasks take no "
             "velocity feed-forward), a small `PostureTask`, pink's default configuration and velocity limits, and a "
             "`SelfCollisionBarrier` over the guarded link-obstacle pairs and the arm's self pairs, DAQP as the "
             "solver. The barrier keeps each pair's distance above `d_min` (the QP's safety distance) by "
             "`ḣ ≥ −γ h`: it models distances only. Each obstacle is placed where it is at the cycle's time and "
             "counts as still within the cycle: unlike the `qp` baseline's dampers, the barrier does not know how "
             "fast an obstacle comes. The barrier gain has no counterpart in previewctl; each gain pink's examples "
             f"use ran as its own row, nothing tuned on these scenes: {gains}. A cycle where pink found no solution "
             "commands q̇ = 0.", "",
             "Control cycle, the medians over the runs of each run's median [ms] (a pink cycle also computes "
             "eq. 19's reference, which the log records and pink does not read; *pink's share* is the time "
             "inside pink's calls alone):", "",
             "| robot | controller | runs | cycle median [ms] | pink's share [ms] | cycles without a solution |",
             "|---|---|---|---|---|---|"]
    for robot, cells in _groups(records).items():
        for (label, _), rows in cells.items():
            pink = label in BARRIER_GAINS
            if not pink and label not in (BASELINE, *LOOKING_AHEAD):
                continue
            share = f"{statistics.median(r['pink_time_median'] for r in rows) * 1e3:.2f}" if pink else "-"
            missed = str(sum(r["pink_no_solution"] for r in rows)) if pink else "-"
            lines.append(f"| {robot} | {label} | {len(rows)} | "
                         f"{statistics.median(r['cycle_time_median'] for r in rows) * 1e3:.2f} | {share} | "
                         f"{missed} |")
    return [*lines, ""]


def _observed_against_known(records: list[dict[str, Any]]) -> list[str]:
    """Per robot, row and execution: success (< 1 mm) with perfect foresight and with observations on the same scenes
    and seeds (the runs that have both), and the difference in points."""
    known: dict[tuple[Any, ...], dict[str, Any]] = {}
    observed: dict[tuple[Any, ...], dict[str, Any]] = {}
    for r in records:
        key = (r["robot"], r["controller"], _latency(r), r["execution"], r.get("settings"), r["scene"], r["seed"])
        (known if _sensing(r) == KNOWN else observed)[key] = r
    pairs: dict[tuple[str, str, str], list[tuple[bool, bool]]] = defaultdict(list)
    for key, r in observed.items():
        if key in known:
            robot, controller, latency, execution = key[:4]
            pairs[(robot, _tagged(controller, latency, KNOWN), execution)].append(
                (bool(known[key]["success_1mm"]), bool(r["success_1mm"])))
    if not pairs:
        return []
    fed = Counter(str(r.get("sensing_settings", "settings not recorded")) for r in observed.values())
    lines = ["## Observed against perfect foresight (success < 1 mm, same scenes and seeds)", "",
             "Observed runs: " + "; and ".join(f"{n} with {settings}" for settings, n in sorted(fed.items())) + ".",
             "",
             "| robot | controller | execution | scene-seed pairs | perfect foresight | observed | "
             "difference [points] |",
             "|---|---|---|---|---|---|---|"]
    for (robot, label, execution), outcomes in sorted(pairs.items(), key=lambda item: (item[0][0],
                                                                                         _order(item[0][1:]))):
        foresight = sum(k for k, _ in outcomes) / len(outcomes)
        seen = sum(o for _, o in outcomes) / len(outcomes)
        lines.append(f"| {robot} | {label} | {execution} | {len(outcomes)} | {foresight:.0%} | {seen:.0%} | "
                     f"{100 * (seen - foresight):+.0f} |")
    return [*lines, ""]


def _kept(records: list[dict[str, Any]], out: Path) -> list[str]:
    """The kept runs that are on disk: the multi-vs-qp contrasts side by side, then the list with replays."""
    present = [r for r in runs_to_keep(records) if (out / RUNS_FOLDER / run_folder(r) / REPLAY_NAME).is_file()]
    if not present:
        return []
    lines = ["## Kept runs (log, figures and 3-D replay in `runs/`)", ""]
    preview, baseline = CONTRAST
    for (robot, wins), pair in sorted(contrasts(records).items()):
        folders = [f"{RUNS_FOLDER}/{run_folder(r)}" for r in pair]
        if not all((out / folder / "strobe.png").is_file() for folder in folders):
            continue
        verb = "succeeds where" if wins else "fails where"
        lines += [f"{robot}, scene {pair[0]['scene']}: `{preview}` {verb} `{baseline}` "
                  f"{'fails' if wins else 'succeeds'} (both under the QP). Left `{preview}`, right `{baseline}`.", "",
                  f"![{preview}]({folders[0]}/strobe.png) ![{baseline}]({folders[1]}/strobe.png)", ""]
    lines += ["| run | success < 5 mm | replay |", "|---|---|---|"]
    for r in present:
        folder = f"{RUNS_FOLDER}/{run_folder(r)}"
        verdict = "yes" if r["success_5mm"] else "no"
        lines.append(f"| {run_folder(r)} | {verdict} | [{REPLAY_NAME}]({folder}/{REPLAY_NAME}) |")
    return [*lines, ""]


def write_report(records: list[dict[str, Any]], scenes: list[dict[str, Any]], out: Path, report_name: str = REPORT_NAME,
                 figure_name: str = FIGURE_NAME, kept: bool = True) -> tuple[Path, Path]:
    """Write the report (``out/report_name``) and its figure (``out/figure_name``) from the result and scene
    records: provenance (dates, commits, scenes and seeds), success rates, preview against ``qp``, and the kept
    runs of ``out/runs/`` when ``kept`` (a report published elsewhere, e.g. in the docs, leaves them out)."""
    records = list({record_key(r): r for r in reversed(records)}.values())[::-1]  # a run twice (two sweeps
    # appending to one folder at once) counts once: its first line
    groups = _groups(records)
    lines = [f"# previewctl bench: {', '.join(groups)}", "", *_provenance(records),
             f"{len(records)} runs. Success = no collision of a guarded link with an obstacle, no collision of the "
             "arm with itself (its self pairs; exact geometry) AND max hand error below the tolerance over the whole "
             "run. `none` runs under the pseudo-inverse only and `qp` under the QP only, and a controller that draws "
             "no random numbers runs for seed 0 only.", ""]
    for robot in groups:
        drawn = [s for s in scenes if s["robot"] == robot]
        if drawn:
            rejected = sum(s["rejected"] for s in drawn)
            how = re.split("[:(]", drawn[0]["witness"])[0].strip()
            how += ", then a motion found by the sampled search" if "sampled search:" in drawn[0]["witness"] else ""
            how += ", then followed by the oracle" if "the oracle followed it" in drawn[0]["witness"] else ""
            lines += [f"{robot}: {len(drawn)} scenes generated, {rejected} draws rejected by the solvability "
                      f"witness on the way ({how}).", ""]
    if any(r["controller"] == "oracle" for r in records) and any(s.get("oracle_run") for s in scenes):
        lines += ["The witness's oracle run is the `oracle` QP run of its scene (recorded, not run again; its "
                  "CPU time includes the plan). The `oracle`'s other runs follow that plan: their CPU time leaves the "
                  "planning out.", ""]
    if any(_latency(r) != INLINE for r in records):
        lines += ["Rows marked *(measured latency)* (`previewctl bench --latency measured`): each plan took effect "
                  "after its own measured CPU time (`time.process_time`, rounded up to whole control periods), the "
                  "previous plan until then, and the next plan was made once it had arrived, as a planner beside the "
                  "loop would. These rows depend on the host's speed and load: they are not bit-reproducible.", ""]
    if any(_sensing(r) != KNOWN for r in records):
        lines += ["Rows marked *(observed)* (`previewctl bench --sensing observed`): the controller did not read the "
                  "moving obstacles' motion; the simulator observed it (noise, latency) and fed it the observations, "
                  "from which it predicted (`[sensing]`; by default two constant-velocity Kalman filters, cruising and "
                  "manoeuvring, mixed). The check and the verdict use the true motion; `none` and `oracle` always run "
                  "with perfect foresight.", ""]
    lines += ["## Success rates", ""]
    for robot, cells in groups.items():
        lines += _rates_table(robot, cells)
    lines += _plan_costs(groups)
    lines += _observed_against_known(records)
    lines += _against_baseline(records)
    for name in BARRIER_GAINS:
        if any(r["controller"] == name for r in records):
            lines += _against_baseline(records, name, LOOKING_AHEAD)
    lines += _pink_note(records)
    if kept:
        lines += _kept(records, out)
    figure = plot_success({robot: {cell: _rate(rows, "success_1mm") for cell, rows in cells.items()}
                           for robot, cells in groups.items()}, out / figure_name)
    lines += [f"![success rates]({figure_name})", ""]
    report = out / report_name
    atomic_write_bytes(report, "\n".join(lines).encode("utf-8"))
    return report, figure
