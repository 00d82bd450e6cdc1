"""``previewctl index``: avoidance manipulability and AMSIP of one configuration."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from previewctl.cli.common import (
    Commands,
    add_evaluation_options,
    add_json_option,
    finite_or_none,
    parse_vector,
    print_json,
)
from previewctl.errors import ConfigurationError
from previewctl.index.amsi import IndexParams, avoidance
from previewctl.index.evaluator import Evaluator
from previewctl.index.load import load_robot
from previewctl.index.potential import Potential
from previewctl.robot.model import Robot
from previewctl.scene.file import load_scene
from previewctl.scene.shapes import Scene
from previewctl.types import Array


def add_parser(commands: Commands) -> None:
    """The ``index`` subcommand and its options."""
    index = commands.add_parser(
        "index",
        help="avoidance manipulability and AMSIP of one configuration",
        description="Print the per-control-point avoidance table (rank, singular values, volume V_i), "
        "the per-link clearance and S = E + U for one configuration.",
    )
    index.add_argument("--robot", default="planar4",
                       help="URDF path, shipped or example-robot-data name (default planar4)")
    index.add_argument("--q", required=True,
                       help="configuration, comma-separated [rad], e.g. 1.2,1.8,-2.9,1.5: one angle per joint, or the "
                       "nq entries of q (a continuous joint's cos, sin); within the joint limits")
    index.add_argument("--degrees", action="store_true", help="read the joint angles of --q in degrees")
    add_evaluation_options(index)
    add_json_option(index, "the avoidance table, the clearances and S")
    index.set_defaults(func=cmd_index)


def cmd_index(args: argparse.Namespace) -> int:
    """Print the per-point avoidance table and AMSIP for one configuration."""
    robot = load_robot(args.robot, geometry=args.geometry)
    q = _configuration(robot, parse_vector(args.q, "q"), args.degrees)
    scene = load_scene(args.scene) if args.scene else Scene()
    index = IndexParams(length_unit=args.length_unit)
    potential = Potential(influence_distance=args.influence)
    result = avoidance(robot, q, index)
    ev = Evaluator(robot, scene, index, potential)(q, args.time)
    report: dict[str, Any] = {
        "robot": robot.name,
        "q": [float(v) for v in q],
        "tip_position": [float(v) for v in ev.tip_position[0]],
        "control_points": [
            {
                "joint": name,
                "rank": int(result.ranks[i]),
                "structural_rank": int(result.structural_ranks[i]),
                "singular_values": [float(s) for s in result.singular_values[i]],
                "volume": float(result.volumes[i]),
            }
            for i, name in enumerate(robot.control_points)
        ],
        "links": [
            {"link": name, "min_distance": finite_or_none(ev.link_distances[0, i])}
            for i, name in enumerate(robot.guarded_links)
        ],
        "amsi": float(ev.amsi[0]),
        "U": float(ev.U[0]),
        "S": float(ev.S[0]),
        "min_distance": finite_or_none(ev.min_distance[0]),
        "collision": bool(ev.collision[0]),
        "self_distance": finite_or_none(ev.self_distance[0]),
        "self_pair": list(robot.self_pairs.pair_names(int(ev.self_pair[0]))) if ev.self_pair[0] >= 0 else None,
        "self_collision": bool(ev.self_collision[0]),
        "length_unit_m": index.length_unit,
    }
    if args.json:
        print_json(report)
        return 0
    hand = np.round(ev.tip_position[0], 4)
    angles = np.array2string(robot.angles_of(q[None])[0], precision=4)
    print(f"robot {robot.name}  joint angles = {angles} [rad]  hand at {hand} [m]")
    print(f"{'control point':<22}{'rank':>5}{'p':>3}  {'singular values [m/rad]':<30}{'V_i [m^p]':>12}")
    for row in report["control_points"]:
        sv = ", ".join(f"{s:.4f}" for s in row["singular_values"])
        print(f"{row['joint']:<22}{row['rank']:>5}{row['structural_rank']:>3}  {sv:<30}{row['volume']:>12.5f}")
    print(f"{'guarded link':<22}{'min distance [m]':>18}")
    for row in report["links"]:
        d = row["min_distance"]
        print(f"{row['link']:<22}{'-' if d is None else f'{d:.4f}':>18}")
    unit = "cm" if np.isclose(index.length_unit, 0.01) else f"{index.length_unit} m"
    reach = potential.self_influence_distance
    if report["self_pair"] is not None and report["self_distance"] < reach:
        a, b = report["self_pair"]
        print(f"nearest self pair {a} / {b}: {report['self_distance']:.4f} m"
              f"{' (SELF-COLLISION)' if report['self_collision'] else ''}")
    elif report["self_pair"] is not None:
        print(f"no self pair within {reach} m ({len(robot.self_pairs.links)} link pairs checked)")
    print(f"AMSI E = {report['amsi']:.2f} (unit {unit})   U = {report['U']:.2f}   S = {report['S']:.2f}"
          f"   {'COLLISION' if report['collision'] else 'collision-free'}")
    return 0


def _configuration(robot: Robot, values: Array, degrees: bool) -> Array:
    """``q`` ``(nq,)`` from one angle per joint [rad, or deg] or from the ``nq`` entries; checked against the limits.

    Raises:
        ConfigurationError: a wrong count, a bad (cos, sin) pair, or a joint outside its limits.
    """
    if len(values) == robot.nv:
        q = robot.configuration_from_angles(np.radians(values) if degrees else values)
    elif len(values) == robot.nq and not degrees:
        q = values
    else:
        entries = "" if robot.nq == robot.nv or degrees else f" or the {robot.nq} entries of q"
        raise ConfigurationError(f"--q has {len(values)} values; robot {robot.name!r} needs one angle per joint "
                                 f"({robot.nv}: {', '.join(robot.joint_names)}){entries}")
    robot.check_configurations(q)
    robot.check_limits(q)
    return q
