"""``previewctl map``: global AMSIP map over the redundancy space of a hand target."""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np

from previewctl.cli.common import parse_vector
from previewctl.errors import PreviewctlError
from previewctl.index.amsi import IndexParams
from previewctl.index.evaluator import Evaluator
from previewctl.index.potential import Potential
from previewctl.robot.load import load_robot
from previewctl.scene.file import load_scene
from previewctl.scene.shapes import Scene
from previewctl.search.explore import explore
from previewctl.search.genes import Candidate


def cmd_map(args: argparse.Namespace) -> int:
    """Global AMSIP map over the redundancy space of one hand target: best, peaks, optional PNG."""
    from pathlib import Path


    scenario_file = getattr(args, "scenario", None)
    if scenario_file:
        if args.scene or args.robot:
            raise PreviewctlError("give either --scenario or --robot/--scene, not both")
        from previewctl.sim.scenario import load_scenario

        scenario = load_scenario(scenario_file)
        robot, scene = scenario.robot, scenario.scene
        index, potential = scenario.index, scenario.potential
        target = parse_vector(args.target, "target") if args.target else scenario.path.position(args.time)
    else:
        if not args.target:
            raise PreviewctlError("--target X,Y (or X,Y,Z) is required unless --scenario is given")
        robot = load_robot(args.robot or "planar4", geometry=args.geometry)
        scene = load_scene(args.scene) if args.scene else Scene()
        index, potential = IndexParams(length_unit=args.length_unit), Potential(influence_distance=args.influence)
        target = parse_vector(args.target, "target")
    if args.surface and not args.out:
        raise PreviewctlError("--surface needs --out FILE.png (the surface goes to FILE_surface.png)")
    evaluator = Evaluator(robot, scene, index, potential)
    landscape = explore(robot, evaluator, target, args.time, resolution_deg=args.resolution, top_k=args.top_k,
                        samples=args.samples, rng=np.random.default_rng(args.seed))

    def row(candidate: Candidate) -> dict[str, Any]:
        return {
            "genes_deg": [round(float(v), 4) for v in np.degrees(np.mod(candidate.genes, 2 * np.pi))],
            "branch": candidate.branch,
            "q": [float(v) for v in candidate.q],
            "q_deg": [round(float(v), 4) for v in np.degrees(candidate.q)],
            "S": candidate.S,
        }

    written: list[str] = []
    if args.out:
        from previewctl.viz.landscapes import plot_landscape, plot_surface

        out = Path(args.out)
        written.append(str(plot_landscape(landscape, robot, scene, out)))
        if args.surface:
            written.append(str(plot_surface(landscape, out.with_name(f"{out.stem}_surface{out.suffix or '.png'}"))))
    report: dict[str, Any] = {
        "robot": robot.name,
        "target": [float(v) for v in np.asarray(target, float)],
        "time": float(args.time),
        "method": landscape.method,
        "candidates": int(landscape.S.size),
        "reachable_fraction": float(landscape.reachable.mean()),
        "collision_free_fraction": float((landscape.S >= 0).mean()),
        "best": row(landscape.best),
        "peaks": [row(p) for p in landscape.peaks],
        "files": written,
    }
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    print(f"robot {robot.name}  hand target {report['target']} [m]  t = {args.time:g} s  ({landscape.method}: "
          f"{report['candidates']} candidates, {100 * report['reachable_fraction']:.1f}% reach the target, "
          f"{100 * report['collision_free_fraction']:.1f}% with S >= 0)")
    print(f"{'':<8}{'genes [deg]':<22}{'branch':>7}  {'q [deg]':<40}{'S':>12}")
    for label, item in [("best", report["best"]), *((f"peak {k}", p) for k, p in enumerate(report["peaks"], 1))]:
        genes = ", ".join(f"{v:.1f}" for v in item["genes_deg"][:4]) + (" ..." if len(item["genes_deg"]) > 4 else "")
        qs = ", ".join(f"{v:.1f}" for v in item["q_deg"])
        print(f"{label:<8}{genes:<22}{item['branch']:>7}  {qs:<40}{item['S']:>12.2f}")
    for path in written:
        print(f"written {path}")
    return 0
