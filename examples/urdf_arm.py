"""Your own arm from a URDF file: load it by path and step its controller from your loop.

``examples/robots/arm4.urdf`` is a small spatial arm: a base yaw joint, then shoulder, elbow and wrist
pitch joints, one cylinder per link. ``load_robot`` finds the rest itself: the hand frame ``tool0``,
a 3-D position task (so one degree of redundancy: the elbow swings in the arm's vertical plane),
the control points (elbow and wrist) and the guarded links. The hand moves 0.3 m sideways in 6 s
past a static ball of radius 6 cm; plain tracking (``none``) hits it at 3.6 s. ``multi`` steers the
elbow away through the null space, along a route that a sampled search plans.

Run: ``python examples/urdf_arm.py [--duration 6]`` (a few seconds).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import previewctl as pc

URDF = Path(__file__).resolve().parent / "robots" / "arm4.urdf"


def main(duration: float = 6.0) -> dict[str, float | bool]:
    robot = pc.load_robot(str(URDF))  # any URDF path; package:// meshes need package_dirs=
    print(f"{robot.name}: joints {robot.joint_names}, hand {robot.tip_frame!r}, task {robot.task}, "
          f"control points {robot.control_points}")
    scene = pc.Scene((pc.Obstacle("ball", pc.Sphere(0.06), pc.Static([0.25, 0.15, 0.52])),))
    check = pc.Evaluator(robot, scene)  # clearance of the links [m], and the hand position
    q = np.array([0.0, 0.6, 1.2, 0.9])  # [rad]
    start = check(q).tip_position[0]  # (0.63, 0, 0.27) m
    path = pc.HandPath([start, start + np.array([0.0, 0.3, 0.0])], duration=6.0)  # 0.3 m along +y in 6 s
    ctrl = pc.make_controller("multi", robot=robot, path=path, scene=scene, seed=0)

    dt, worst, clearance, collided = 0.01, 0.0, np.inf, False
    for k in range(round(duration / dt) + 1):
        t = k * dt
        state = check(q, t)
        clearance, collided = min(clearance, state.min_distance[0]), collided or bool(state.collision[0])
        qdot = ctrl.step(q, t)  # [rad/s]
        worst = max(worst, ctrl.last_info.hand_error)
        q = pc.integrate(robot, q, qdot, dt)

    print(f"{robot.name}, multi-preview, {duration:g} s: max hand error {worst * 1e3:.2f} mm, "
          f"min clearance {clearance * 1e3:.0f} mm, collided: {collided}")
    return {"max_hand_error": worst, "min_clearance": float(clearance), "collided": collided}


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=6.0, help="simulated time [s] (default 6)")
    main(parser.parse_args().duration)
