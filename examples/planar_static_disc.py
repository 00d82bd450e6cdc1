"""The paper's planar 4-link arm tracks a line past a static disc with multi-preview control, in your loop.

The hand moves from (1.91, 1.04) m to (0.80, 1.60) m in 8 s. A disc of radius 0.1 m (a vertical
cylinder) stands at (0.55, 1.80) m: plain tracking (``--controller none``) keeps the elbow up and
sweeps link 3 into it at 4.3 s. ``multi`` (eq. 21: three imaginary arms at t + 1, 2, 3 s) pulls the
arm along a route that the reachability DP plans, every 0.5 s, toward the best AMSIP peak of the future
hand targets that a collision-free motion reaches (each preview time has its own 1-step GA, one
generation per 33 ms camera frame); the route keeps the links clear of the disc.

Run: ``python examples/planar_static_disc.py [--duration 8] [--controller multi]`` (a few seconds).
"""

from __future__ import annotations

import argparse

import numpy as np

import previewctl as pc


def main(duration: float = 8.0, controller: str = "multi") -> dict[str, float | bool]:
    robot = pc.load_robot("planar4")  # 4 revolute z joints, 0.75 m links
    path = pc.HandPath([[1.9069, 1.0417], [0.80, 1.60]], duration=8.0)  # [m], [s]
    disc = pc.Obstacle("disc", pc.Cylinder(0.1, 0.4), pc.Static([0.55, 1.80, 0.0]))
    scene = pc.Scene((disc,))
    ctrl = pc.make_controller(controller, robot=robot, path=path, scene=scene, seed=0)
    check = pc.Evaluator(robot, scene)  # clearance of links 1-3 [m]

    q = np.array([0.6, 1.0, -1.2, -1.0])  # [rad]; the hand at the path start
    dt, worst, clearance, collided = 0.01, 0.0, np.inf, False
    for k in range(round(duration / dt) + 1):
        t = k * dt
        state = check(q, t)
        clearance, collided = min(clearance, state.min_distance[0]), collided or bool(state.collision[0])
        qdot = ctrl.step(q, t)  # [rad/s]
        worst = max(worst, ctrl.last_info.hand_error)
        q = pc.integrate(robot, q, qdot, dt)

    print(f"planar4, {controller}, {duration:g} s: max hand error {worst * 1e3:.2f} mm, "
          f"min clearance {clearance * 1e3:.0f} mm, collided: {collided}")
    return {"max_hand_error": worst, "min_clearance": float(clearance), "collided": collided}


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=8.0, help="simulated time [s] (default 8)")
    parser.add_argument("--controller", default="multi", choices=pc.CONTROLLER_NAMES, help="default: multi")
    args = parser.parse_args()
    main(args.duration, args.controller)
