"""previewctl: on-line trajectory tracking with obstacle avoidance for redundant arms.

Implements "Multi-Preview Configuration Control for Redundant Manipulator by Future Reachability
Evaluation": avoidance manipulability (AMSI), AMSIP on true Coal distances, a 1-step GA over the
redundancy space and single/multi-preview control, for any arm described by a URDF.

Everything a first run needs is here, one import::

    import previewctl as pc

    robot = pc.load_robot("planar4")
    path = pc.HandPath([[1.9069, 1.0417], [0.80, 1.60]], duration=8.0)
    scene = pc.Scene((pc.Obstacle("disc", pc.Cylinder(0.1, 0.4), pc.Static([0.55, 1.80, 0.0])),))
    ctrl = pc.make_controller("multi", robot=robot, path=path, scene=scene, seed=0)
    q, dt = [0.6, 1.0, -1.2, -1.0], 0.01
    for k in range(500):                       # your loop, your rate
        qdot = ctrl.step(q, k * dt)           # [rad/s]
        q = pc.integrate(robot, q, qdot, dt)

The subpackages hold the rest (``previewctl.robot``, ``index``, ``scene``, ``planar``, ``search``,
``control``, ``sim``, ``viz``, ``cli``); figures need ``previewctl.viz`` and the ``[viz]`` extra
(matplotlib), which this import does not load. Diagnostics go to the ``previewctl`` logger.
"""

import logging

from previewctl.control.base import ControlInfo
from previewctl.control.controller import Controller
from previewctl.control.factory import make_controller
from previewctl.control.params import CONTROLLER_NAMES, ControllerParams
from previewctl.errors import (
    ConfigurationError,
    ObservationError,
    ParameterError,
    PlanningWorkerError,
    PreviewctlError,
    RobotLoadError,
    ScenarioError,
    SceneError,
    TrajectoryError,
    UnknownNameError,
    UnreachableTargetError,
)
from previewctl.index.amsi import AvoidanceResult, IndexParams, avoidance, unit_ball_volume
from previewctl.index.evaluator import Evaluation, Evaluator, evaluate
from previewctl.index.load import load_robot
from previewctl.index.potential import Potential
from previewctl.kinematics import integrate
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.scene.file import load_scene
from previewctl.scene.motion import ConstantVelocity, Periodic, RandomWalk, SpeedChange, Static, Turn, Waypoints
from previewctl.scene.shapes import Box, Capsule, Cylinder, Halfspace, Mesh, Obstacle, Plane, Scene, Sphere
from previewctl.search.explore import Landscape, explore
from previewctl.search.ga import OneStepGA
from previewctl.search.genes import Candidate
from previewctl.search.maps import redundancy_map
from previewctl.sensing.options import Sensing
from previewctl.sensing.predictors import ConstantVelocityKalman, ManoeuvreKalman, Predictor, Stationary
from previewctl.sim.log import RunResult, load_run, save_run
from previewctl.sim.loop import simulate
from previewctl.sim.scenario import Scenario, load_scenario, scenario_from_dict

__version__ = "0.1.0"

logging.getLogger(__name__).addHandler(logging.NullHandler())  # diagnostics only where the application asks

__all__ = [
    "CONTROLLER_NAMES",
    "AvoidanceResult",
    "Box",
    "Candidate",
    "Capsule",
    "ConfigurationError",
    "ConstantVelocity",
    "ConstantVelocityKalman",
    "ControlInfo",
    "Controller",
    "ControllerParams",
    "Cylinder",
    "Evaluation",
    "Evaluator",
    "Halfspace",
    "HandPath",
    "IndexParams",
    "Landscape",
    "ManoeuvreKalman",
    "Mesh",
    "ObservationError",
    "Obstacle",
    "OneStepGA",
    "ParameterError",
    "Periodic",
    "Plane",
    "PlanningWorkerError",
    "Potential",
    "Predictor",
    "PreviewctlError",
    "RandomWalk",
    "Robot",
    "RobotLoadError",
    "RunResult",
    "Scenario",
    "ScenarioError",
    "Scene",
    "SceneError",
    "Sensing",
    "SpeedChange",
    "Sphere",
    "Static",
    "Stationary",
    "TrajectoryError",
    "Turn",
    "UnknownNameError",
    "UnreachableTargetError",
    "Waypoints",
    "avoidance",
    "evaluate",
    "explore",
    "integrate",
    "load_robot",
    "load_run",
    "load_scenario",
    "load_scene",
    "make_controller",
    "redundancy_map",
    "save_run",
    "scenario_from_dict",
    "simulate",
    "unit_ball_volume",
]
