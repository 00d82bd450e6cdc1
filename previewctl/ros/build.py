"""What the node controls: the robot, its hand path and the controller, from the node's settings
(:class:`~previewctl.ros.settings.NodeSettings`).

The controller observes every obstacle it is told about on ``~/obstacles``
(:class:`~previewctl.sensing.options.Sensing`; a scenario's moving obstacles too, once observed; its static ones
stay known) and plans in the background when its
law has something to plan (``single``, ``multi``, ``reach``, ``horizon``, ``oracle``), as ``previewctl run
--realtime`` does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from previewctl.control.controller import Controller
from previewctl.control.factory import BACKGROUND_CONTROLLERS, make_controller
from previewctl.errors import RosError
from previewctl.index.load import load_robot
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.ros.settings import NodeSettings
from previewctl.scene.shapes import Scene
from previewctl.sensing.options import Sensing
from previewctl.sim.scenario import Scenario, load_scenario
from previewctl.types import Array

DEFAULT_CONTROLLER = "gradient"
"""The controller without a scenario naming one: the AMSIP gradient under the QP, nothing to plan."""


@dataclass(frozen=True)
class Setup:
    """The robot, its first hand path and where they came from.

    Attributes:
        robot: the arm.
        path: the hand path it starts with.
        scenario: the scenario file's content, or ``None`` (robot + waypoints).
        controller: the controller name.
    """

    robot: Robot
    path: HandPath
    scenario: Scenario | None
    controller: str


def setup_of(settings: NodeSettings) -> Setup:
    """Load the scenario, or the robot and the path of the waypoints.

    Raises:
        RosError: waypoints that are not whole points of the robot's task (2 numbers each on a planar arm, else 3).
        PreviewctlError: a scenario or robot that cannot be loaded, a path that cannot be built.
    """
    if settings.scenario:
        scenario = load_scenario(settings.scenario)
        return Setup(scenario.robot, scenario.path, scenario, settings.controller or scenario.controller.name)
    robot = load_robot(settings.robot)
    size = 2 if robot.task == "planar" else 3
    if len(settings.waypoints) % size or len(settings.waypoints) < 2 * size:
        raise RosError(f"waypoints must hold at least 2 points of {size} numbers [m] for robot {robot.name!r}, "
                       f"flattened; got {len(settings.waypoints)} numbers")
    path = HandPath(np.reshape(settings.waypoints, (-1, size)), duration=settings.duration)
    return Setup(robot, path, None, settings.controller or DEFAULT_CONTROLLER)


def controller_for(setup: Setup, settings: NodeSettings, path: HandPath) -> Controller:
    """A controller along ``path`` that observes obstacles, planning in the background if it has anything to plan."""
    planning = "background" if setup.controller in BACKGROUND_CONTROLLERS else "inline"
    sensing = Sensing(timeout=settings.sensing_timeout)
    if setup.scenario is not None:
        return make_controller(setup.scenario, name=setup.controller, path=path, seed=settings.seed,
                               dt=settings.period, planning=planning, sensing=sensing)
    return make_controller(setup.controller, robot=setup.robot, path=path, scene=Scene(), seed=settings.seed,
                           dt=settings.period, planning=planning, sensing=sensing)


def path_from(robot: Robot, hand: Array, points: Array, speed: float) -> HandPath:
    """A hand path from the hand's position ``hand`` [m] through ``points`` ``(K, 3)`` [m] at ``speed`` [m/s].

    Raises:
        RosError: no point, or points that are not finite.
    """
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or len(points) == 0 or not np.all(np.isfinite(points)):
        raise RosError(f"a path needs at least one finite point (x, y, z) [m], got {points.tolist()}")
    size = 2 if robot.task == "planar" else 3
    waypoints = np.vstack([np.asarray(hand, dtype=float)[:size], points[:, :size]])
    length = float(np.sum(np.linalg.norm(np.diff(waypoints, axis=0), axis=1)))
    return HandPath(waypoints, duration=max(length / speed, 1e-3))
