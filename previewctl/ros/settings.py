"""The node's settings: one frozen value object, read from ROS parameters (a ``--params-file`` YAML included).

Every field of :class:`NodeSettings` is a ROS parameter of the same name, declared with the field's default
(:func:`declare`), so ``ros2 param list /previewctl`` shows them all and a parameter file sets any of them::

    previewctl:
      ros__parameters:
        scenario: panda.toml
        rate: 100.0
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Annotated, Any, get_args, get_type_hints

from pydantic import Field

from previewctl.errors import RosError
from previewctl.validation import Checked, Finite, Integer, Positive, Text

Fraction = Annotated[Finite, Field(gt=0, le=1)]
"""A number in (0, 1]."""


@dataclass(frozen=True)
class NodeSettings(Checked):
    """What the node runs and how (the ROS parameters of ``previewctl ros``).

    Attributes:
        scenario: a scenario TOML file (robot, path, obstacles, controller); empty: ``robot`` + ``waypoints``.
        robot: without a scenario, the robot (a name of ``previewctl robots`` or a URDF file).
        waypoints: without a scenario, the hand path's waypoints [m], flattened: 3 numbers each (2 for a planar
            arm).
        duration: without a scenario, the time [s] the hand takes along ``waypoints``.
        controller: the controller name (default: the scenario's, or ``gradient``); those with something to plan
            plan in the background (``single``, ``multi``, ``reach``, ``horizon``, ``oracle``).
        seed: randomness of the searches.
        rate: the control rate [Hz]: a command per period.
        joint_names: the names in ``/joint_states`` of the robot's joints, in the robot's order (empty: the URDF's
            names); other joints in the message are ignored.
        joint_states_topic: where the joint states come from (``sensor_msgs/JointState``).
        commands_topic: where the joint velocities go (``std_msgs/Float64MultiArray``, one per joint, in the
            robot's order), ros2_control's forward command controller by default.
        frame_id: the frame the obstacle markers must be in (the robot's base); empty: any.
        max_hand_error: the hand error [m] beyond which the node stops the arm.
        stale_periods: joint states older than this many periods stop the arm.
        velocity_scale: the commands stay within this fraction of the URDF's joint speed limits.
        sensing_timeout: an obstacle marker not seen again for this long [s] is forgotten.
        path_speed: a path received on ``~/path`` is followed at this hand speed [m/s].
    """

    error = RosError

    scenario: Text = ""
    robot: Text = ""
    waypoints: tuple[Finite, ...] = ()
    duration: Positive = 10.0
    controller: Text = ""
    seed: Integer = 0
    rate: Positive = 50.0
    joint_names: tuple[Text, ...] = ()
    joint_states_topic: Text = "/joint_states"
    commands_topic: Text = "/forward_velocity_controller/commands"
    frame_id: Text = ""
    max_hand_error: Positive = 0.05
    stale_periods: Positive = 3.0
    velocity_scale: Fraction = 1.0
    sensing_timeout: Positive = 1.0
    path_speed: Positive = 0.05

    def check(self) -> None:
        """A scenario, or a robot with waypoints; not both."""
        if self.scenario and (self.robot or self.waypoints):
            raise RosError(f"scenario {self.scenario!r} and robot {self.robot!r} / waypoints both given: a scenario "
                           "file, or a robot and its hand path, not both")
        if not self.scenario and not (self.robot and self.waypoints):
            raise RosError("the node needs a scenario file (parameter 'scenario') or a robot and its hand path "
                           "(parameters 'robot' and 'waypoints')")

    @property
    def period(self) -> float:
        """The control period [s]."""
        return 1.0 / self.rate


def declare(node: Any) -> NodeSettings:
    """Declare every field of :class:`NodeSettings` as a parameter of ``node`` (an ``rclpy`` node) and read them.

    Raises:
        RosError: a parameter of the wrong type or value, or neither a scenario nor a robot with waypoints.
    """
    from rcl_interfaces.msg import ParameterDescriptor
    from rclpy.exceptions import ParameterException, ParameterUninitializedException
    from rclpy.parameter import Parameter

    hints = get_type_hints(NodeSettings)  # Annotated layers stripped: tuple[str, ...], tuple[float, ...]
    values: dict[str, Any] = {}
    for field in dataclasses.fields(NodeSettings):
        default: Any = field.default
        try:
            if isinstance(default, tuple):  # typed, without a value: an empty list would be taken for bytes
                item = get_args(hints[field.name])[0]
                node.declare_parameter(field.name, Parameter.Type.STRING_ARRAY if item is str
                                       else Parameter.Type.DOUBLE_ARRAY)
                try:
                    value = tuple(node.get_parameter(field.name).value)
                except ParameterUninitializedException:
                    value = default
            else:  # any type: 50 for 50.0 in a YAML file; NodeSettings checks it
                value = node.declare_parameter(field.name, default, ParameterDescriptor(dynamic_typing=True)).value
        except ParameterException as exc:
            raise RosError(f"parameter {field.name!r}: {exc}") from exc
        values[field.name] = value
    return NodeSettings(**values)
