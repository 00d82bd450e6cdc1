"""previewctl: on-line trajectory tracking with obstacle avoidance for redundant arms.

Implements "Multi-Preview Configuration Control for Redundant Manipulator by Future Reachability
Evaluation": avoidance manipulability (AMSI), AMSIP on true Coal distances, a 1-step GA over the
redundancy space and single/multi-preview control, for any arm described by a URDF.
"""

from previewctl.amsip import Evaluation, Evaluator, Potential, evaluate
from previewctl.avoidance import AvoidanceResult, IndexParams, avoidance, unit_ball_volume
from previewctl.errors import (
    ConfigurationError,
    PreviewctlError,
    RobotLoadError,
    ScenarioError,
    SceneError,
    TrajectoryError,
    UnknownNameError,
    UnreachableTargetError,
)
from previewctl.robot import Robot, load_robot
from previewctl.scene import Box, Capsule, Cylinder, Halfspace, Mesh, Obstacle, Plane, Scene, Sphere, load_scene

__version__ = "0.1.0"

__all__ = [
    "AvoidanceResult",
    "Box",
    "Capsule",
    "ConfigurationError",
    "Cylinder",
    "Evaluation",
    "Evaluator",
    "Halfspace",
    "IndexParams",
    "Mesh",
    "Obstacle",
    "Plane",
    "Potential",
    "PreviewctlError",
    "Robot",
    "RobotLoadError",
    "ScenarioError",
    "Scene",
    "SceneError",
    "Sphere",
    "TrajectoryError",
    "UnknownNameError",
    "UnreachableTargetError",
    "avoidance",
    "evaluate",
    "load_robot",
    "load_scene",
    "unit_ball_volume",
]
