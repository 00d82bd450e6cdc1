"""``previewctl map``: global AMSIP map over the redundancy space of a hand target."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from previewctl.cli.common import (
    Commands,
    add_evaluation_options,
    add_json_option,
    parse_vector,
    print_json,
    seed_value,
)
from previewctl.errors import PreviewctlError
from previewctl.files import check_output_file
from previewctl.index.amsi import IndexParams
from previewctl.index.evaluator import Evaluator
from previewctl.index.load import load_robot
from previewctl.index.potential import Potential
from previewctl.robot.joints import FULL_TURN
from previewctl.robot.model import Robot
from previewctl.scene.file import load_scene
from previewctl.scene.shapes import Scene
from previewctl.search.explore import Landscape, explore
from previewctl.search.genes import Candidate
from previewctl.types import Array


def add_parser(commands: Commands) -> None:
    """The ``map`` subcommand and its options."""
    map_ = commands.add_parser(
        "map",
        help="global AMSIP map over the redundancy space of a hand target",
        description="Evaluate S over the redundancy space of one hand target (planar4: a grid over (q1, q2) "
        "x both elbow branches; other arms: Halton samples of the Newton map) and print the best "
        "configuration and the distinct peaks; --out writes the heat map (S < 0 black) and the arm.",
    )
    map_.add_argument("--robot", help="URDF path, shipped or example-robot-data name (default planar4)")
    map_.add_argument("--target", help="hand target, comma-separated [m]: X,Y (planar) or X,Y,Z")
    map_.add_argument("--scenario", help="scenario TOML file: robot, scene, index and (at --time) the target")
    map_.add_argument("--out", help="write the map to this PNG file")
    map_.add_argument("--surface", action="store_true", help="also write the 3-D surface to <out>_surface.png")
    add_json_option(map_, "the best configuration and the peaks (genes in degrees, q, S)")
    map_.add_argument("--resolution", type=float, default=1.0, help="grid step [deg] (default 1)")
    map_.add_argument("--top-k", type=int, default=4, help="number of peaks to report (default 4)")
    map_.add_argument("--samples", type=int, help="Halton samples for arms with more than two genes")
    map_.add_argument("--seed", type=seed_value, default=0, help="random shift of the samples (default 0)")
    add_evaluation_options(map_)
    map_.set_defaults(func=cmd_map)


def cmd_map(args: argparse.Namespace) -> int:
    """Global AMSIP map over the redundancy space of one hand target: best, peaks, optional PNG."""
    robot, evaluator, target = _inputs(args)
    if args.surface and not args.out:
        raise PreviewctlError("--surface needs --out FILE.png (the surface goes to FILE_surface.png)")
    if args.out:
        check_output_file(args.out)
    landscape = explore(robot, evaluator, target, args.time, resolution_deg=args.resolution, top_k=args.top_k,
                        samples=args.samples, rng=np.random.default_rng(args.seed))
    written = _write_figures(args, landscape, robot, evaluator.scene) if args.out else []
    report: dict[str, Any] = {
        "robot": robot.name,
        "target": [float(v) for v in np.asarray(target, float)],
        "time": float(args.time),
        "method": landscape.method,
        "candidates": int(landscape.S.size),
        "reachable_fraction": float(landscape.reachable.mean()),
        "collision_free_fraction": float((landscape.S >= 0).mean()),
        "best": _row(landscape.best, robot),
        "peaks": [_row(p, robot) for p in landscape.peaks],
        "files": written,
    }
    if args.json:
        print_json(report)
    else:
        _print_table(report)
    return 0


def _inputs(args: argparse.Namespace) -> tuple[Robot, Evaluator, Array]:
    """The robot, the AMSIP evaluator and the hand target [m], from ``--scenario`` or from ``--robot`` and
    ``--target`` (with ``--scene`` and the index options)."""
    if args.scenario:
        if args.scene or args.robot:
            raise PreviewctlError("give either --scenario or --robot/--scene, not both")
        from previewctl.sim.scenario import load_scenario

        scenario = load_scenario(args.scenario)
        target = parse_vector(args.target, "target") if args.target else scenario.path.position(args.time)
        evaluator = Evaluator(scenario.robot, scenario.scene, scenario.index, scenario.potential)
        return scenario.robot, evaluator, target
    if not args.target:
        raise PreviewctlError("--target X,Y (or X,Y,Z) is required unless --scenario is given")
    robot = load_robot(args.robot or "planar4", geometry=args.geometry)
    scene = load_scene(args.scene) if args.scene else Scene()
    index, potential = IndexParams(length_unit=args.length_unit), Potential(influence_distance=args.influence)
    return robot, Evaluator(robot, scene, index, potential), parse_vector(args.target, "target")


def _write_figures(args: argparse.Namespace, landscape: Landscape, robot: Robot, scene: Scene) -> list[str]:
    """Write the heat map to ``--out`` (and the surface with ``--surface``); the paths written."""
    from previewctl.viz.landscapes import plot_landscape, plot_surface

    out = Path(args.out)
    written = [str(plot_landscape(landscape, robot, scene, out))]
    if args.surface:
        written.append(str(plot_surface(landscape, out.with_name(f"{out.stem}_surface{out.suffix or '.png'}"))))
    return written


def _row(candidate: Candidate, robot: Robot) -> dict[str, Any]:
    """A candidate for the report: genes in ``[0, 360)`` [deg], branch, ``q`` (the ``nq`` entries), the joint
    angles in [deg] (a continuous joint's angle, not its cos and sin), ``S``."""
    return {
        "genes_deg": [round(float(v), 4) for v in np.degrees(np.mod(candidate.genes, FULL_TURN))],
        "branch": candidate.branch,
        "q": [float(v) for v in candidate.q],
        "q_deg": [round(float(v), 4) for v in np.degrees(robot.angles_of(np.asarray(candidate.q)[None])[0])],
        "S": candidate.S,
    }


def _print_table(report: dict[str, Any]) -> None:
    """The report as a text table: one line per candidate (best, then the peaks) and the files written."""
    print(f"robot {report['robot']}  hand target {report['target']} [m]  t = {report['time']:g} s  "
          f"({report['method']}: {report['candidates']} candidates, "
          f"{100 * report['reachable_fraction']:.1f}% reach the target, "
          f"{100 * report['collision_free_fraction']:.1f}% with S >= 0)")
    print(f"{'':<8}{'genes [deg]':<22}{'branch':>7}  {'q [deg]':<40}{'S':>12}")
    for label, item in [("best", report["best"]), *((f"peak {k}", p) for k, p in enumerate(report["peaks"], 1))]:
        genes = ", ".join(f"{v:.1f}" for v in item["genes_deg"][:4]) + (" ..." if len(item["genes_deg"]) > 4 else "")
        qs = ", ".join(f"{v:.1f}" for v in item["q_deg"])
        print(f"{label:<8}{genes:<22}{item['branch']:>7}  {qs:<40}{item['S']:>12.2f}")
    for path in report["files"]:
        print(f"written {path}")
