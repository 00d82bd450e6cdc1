"""previewctl: on-line trajectory tracking with obstacle avoidance for redundant arms.

Implements "Multi-Preview Configuration Control for Redundant Manipulator by Future Reachability
Evaluation": avoidance manipulability (AMSI), AMSIP on true Coal distances, a 1-step GA over the
redundancy space and single/multi-preview control, for any arm described by a URDF.
"""

from previewctl.errors import (
    ConfigurationError,
    ParameterError,
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
from previewctl.index.potential import Potential
from previewctl.robot.load import load_robot
from previewctl.robot.model import Robot
from previewctl.scene.file import load_scene
from previewctl.scene.shapes import Box, Capsule, Cylinder, Halfspace, Mesh, Obstacle, Plane, Scene, Sphere

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
    "ParameterError",
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
