"""Stand-ins for the tests and the example: a fake robot and a sphere that moves across the arm.

* :class:`FakeRobot` integrates the velocity commands it receives (``q ← q + q̇ dt``) and publishes
  ``/joint_states`` at its rate, with one extra joint the node must ignore; like a drive's watchdog, it holds a
  command for at most ``command_timeout`` and then stops (a node stalled by a loaded host does not drive it
  blind). :meth:`FakeRobot.pause` stops its joint states (the node must then stop the arm).
* :class:`SphereMover` publishes a sphere marker moving at constant velocity, stamped with the time of its
  position, on the node's ``~/obstacles``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from visualization_msgs.msg import Marker, MarkerArray

from previewctl.errors import RosError
from previewctl.types import Array

EXTRA_JOINT = "fake_gripper_joint"
"""The extra joint the fake robot reports (the node ignores joints it does not control)."""


class FakeRobot(Node):
    """A robot that applies the joint velocities it is sent.

    Args:
        joint_names: its joints, in the order of the commands.
        q0: their start positions [rad].
        rate: how often it integrates and publishes [Hz].
        commands_topic: where the commands come from (``std_msgs/Float64MultiArray``).
        joint_states_topic: where its joint states go.
        command_timeout: how long [s] a command is applied without a new one.
        kwargs: passed to ``rclpy.node.Node`` (``context``, ...).
    """

    def __init__(self, joint_names: Sequence[str], q0: Sequence[float], rate: float = 200.0,
                 commands_topic: str = "/forward_velocity_controller/commands",
                 joint_states_topic: str = "/joint_states", command_timeout: float = 0.1, **kwargs: Any) -> None:
        super().__init__("fake_robot", **kwargs)
        if len(q0) != len(joint_names):
            raise RosError(f"q0 has {len(q0)} positions for {len(joint_names)} joints")
        self.joint_names = tuple(joint_names)
        self.q: Array = np.array(q0, dtype=float)
        self.qdot: Array = np.zeros(len(q0))
        self.period = 1.0 / rate
        self.paused = False
        self.command_timeout = command_timeout
        self._last: float | None = None
        self._commanded = -np.inf  # [s] node clock, when the last command came
        self._states = self.create_publisher(JointState, joint_states_topic, 10)
        self.create_subscription(Float64MultiArray, commands_topic, self._on_command, 10)
        self.create_timer(self.period, self._tick)

    def pause(self) -> None:
        """Stop publishing joint states (the arm still integrates the last command)."""
        self.paused = True

    def _on_command(self, msg: Float64MultiArray) -> None:
        if len(msg.data) == len(self.q):
            self.qdot = np.array(msg.data, dtype=float)
            self._commanded = float(self.get_clock().now().nanoseconds) * 1e-9

    def _tick(self) -> None:
        now = self.get_clock().now()
        t = float(now.nanoseconds) * 1e-9
        if self._last is not None and t - self._commanded <= self.command_timeout:
            self.q = self.q + self.qdot * (t - self._last)
        self._last = t
        if self.paused:
            return
        msg = JointState(name=[EXTRA_JOINT, *self.joint_names], position=[0.0, *map(float, self.q)])
        msg.header.stamp = now.to_msg()
        self._states.publish(msg)


class SphereMover(Node):
    """A sphere marker ``"<ns>/0"`` at ``start + velocity (t - t0)``, published at ``rate``.

    Args:
        start: its centre at the first tick [m], ``(3,)``.
        velocity: its velocity [m/s], ``(3,)``.
        radius: its radius [m].
        rate: how often it is published [Hz].
        topic: the node's obstacle topic.
        frame_id: the markers' frame.
        ns: the markers' namespace.
        kwargs: passed to ``rclpy.node.Node`` (``context``, ...).
    """

    def __init__(self, start: Sequence[float], velocity: Sequence[float], radius: float, rate: float = 30.0,
                 topic: str = "/previewctl/obstacles", frame_id: str = "world", ns: str = "mover",
                 **kwargs: Any) -> None:
        super().__init__("sphere_mover", **kwargs)
        self.start, self.velocity = np.array(start, dtype=float), np.array(velocity, dtype=float)
        self.radius, self.frame_id, self.ns = radius, frame_id, ns
        self.t0: float | None = None
        self._markers = self.create_publisher(MarkerArray, topic, 10)
        self.create_timer(1.0 / rate, self._tick)

    def position(self, t: float) -> Array:
        """Its centre [m] at node-clock time ``t`` [s]."""
        return self.start + self.velocity * (t - (t if self.t0 is None else self.t0))

    def _tick(self) -> None:
        now = self.get_clock().now()
        t = float(now.nanoseconds) * 1e-9
        if self.t0 is None:
            self.t0 = t
        p = self.position(t)
        marker = Marker(type=Marker.SPHERE, action=Marker.ADD, ns=self.ns, id=0)
        marker.header.frame_id, marker.header.stamp = self.frame_id, now.to_msg()
        marker.pose.position.x, marker.pose.position.y, marker.pose.position.z = map(float, p)
        marker.pose.orientation.w = 1.0
        marker.scale.x = marker.scale.y = marker.scale.z = 2 * self.radius
        marker.color.r, marker.color.a = 1.0, 0.8
        self._markers.publish(MarkerArray(markers=[marker]))
