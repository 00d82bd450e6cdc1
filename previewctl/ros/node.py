"""The ``previewctl`` ROS 2 node: a controller stepped at a fixed rate from joint states and observed obstacles.

Subscribes:

* ``joint_states_topic`` (``sensor_msgs/JointState``): matched by joint name (``joint_names``); extra joints are
  ignored, a missing one stops the arm and is reported. A joint state's age is judged from its header's stamp (its
  arrival when unstamped), so one delivered late counts as old: the robot's clock and the node's must agree (one
  machine, or synchronised clocks);
* ``~/obstacles`` (``visualization_msgs/MarkerArray``): sphere, cube and cylinder markers named ``<ns>/<id>``
  (:mod:`~previewctl.ros.markers`), observed by the controller (``Controller.observe``, ``forget``, ``forget_all``);
* ``~/path`` (``nav_msgs/Path``) and ``~/path_poses`` (``geometry_msgs/PoseArray``): a new hand path, from where
  the hand is through the poses' positions at ``path_speed``; the controller is made anew for it (its observed
  obstacles come back with the next markers).

Publishes:

* ``commands_topic`` (``std_msgs/Float64MultiArray``): the joint velocities [rad/s], one per joint in the robot's
  order, each period; zero when the arm must stop (:mod:`~previewctl.ros.safety`);
* ``~/imaginary_arms`` (``visualization_msgs/MarkerArray``): each imaginary arm as a line through its joints, at
  every camera frame;
* ``~/status`` (``diagnostic_msgs/DiagnosticArray``): each period, one status: level OK (running), WARN (running on
  the fallback, or a bad marker just came) or ERROR (stopped), the reason as its message, and the values
  ``state``, ``path_time``, ``plan_age``, ``fallback``, ``least_clearance``, ``hand_error``, ``cycle_time``,
  ``obstacles``, ``bad_markers`` and ``last_marker_error``.

The path's clock starts when the first joint state has come and, with background planning, the worker has answered
the start state (a robot holds still until its planner is ready); until then the node publishes zero.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pinocchio as pin
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, PoseArray
from nav_msgs.msg import Path
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from visualization_msgs.msg import Marker, MarkerArray

from previewctl.control.base import ControlInfo
from previewctl.control.tracking import effective_velocity_limits
from previewctl.errors import PreviewctlError, RosError
from previewctl.index.evaluator import Evaluator
from previewctl.ros.build import controller_for, path_from, setup_of
from previewctl.ros.markers import Forget, ForgetAll, Observe, request_of
from previewctl.ros.safety import stop_reason, within_limits
from previewctl.ros.settings import declare
from previewctl.types import Array

NODE_NAME = "previewctl"


class ControllerNode(Node):
    """The node (module docstring); its settings are its ROS parameters
    (:class:`~previewctl.ros.settings.NodeSettings`).

    Args:
        name: the node's name.
        kwargs: passed to ``rclpy.node.Node`` (``parameter_overrides``, ``context``, ...).

    Raises:
        RosError, PreviewctlError: settings it cannot run with (named in the message).
    """

    def __init__(self, name: str = NODE_NAME, **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        self.settings = declare(self)
        self.setup = setup_of(self.settings)
        robot = self.setup.robot
        self.limits = effective_velocity_limits(robot, self.settings.velocity_scale)
        self.joint_names = self.settings.joint_names or robot.joint_names
        if len(self.joint_names) != robot.nv:
            raise RosError(f"joint_names has {len(self.joint_names)} names, robot {robot.name!r} has {robot.nv} "
                           f"joints: {', '.join(robot.joint_names)}")
        self.controller = controller_for(self.setup, self.settings, self.setup.path)
        self._data = robot.model.createData()
        self._evaluator: Evaluator | None = None
        self._q: Array | None = None
        self._received: float | None = None  # [s] node clock, the last joint state's stamp (or arrival, unstamped)
        self._joint_error: str | None = None
        self._start: float | None = None  # [s] node clock, when the path's clock started
        self._bad_markers, self._reported_bad, self._marker_error = 0, 0, ""
        self._commands = self.create_publisher(Float64MultiArray, self.settings.commands_topic, 10)
        self._status = self.create_publisher(DiagnosticArray, "~/status", 10)
        self._arms = self.create_publisher(MarkerArray, "~/imaginary_arms", 10)
        # depth 1: only the latest joint state matters; a queue would feed a late node old states first
        self.create_subscription(JointState, self.settings.joint_states_topic, self._on_joint_state, 1)
        self.create_subscription(MarkerArray, "~/obstacles", self._on_markers, 10)
        self.create_subscription(Path, "~/path", lambda msg: self._on_path([p.pose for p in msg.poses]), 10)
        self.create_subscription(PoseArray, "~/path_poses", lambda msg: self._on_path(list(msg.poses)), 10)
        self._timer = self.create_timer(self.settings.period, self.cycle)
        # the first log call of a process is slow (tens of ms): made here, not in a control period
        self.get_logger().info(f"{self.controller.name} on {robot.name} at {self.settings.rate:g} Hz, commands on "
                               f"{self.settings.commands_topic}")

    def now(self) -> float:
        """The node clock [s]."""
        return float(self.get_clock().now().nanoseconds) * 1e-9

    def path_time(self, stamp: float) -> float:
        """The path-clock time [s] of node-clock time ``stamp`` (0 before the path's clock starts)."""
        return 0.0 if self._start is None else stamp - self._start

    def cycle(self) -> None:
        """One control period: step the controller, publish the command (zero when the arm must stop) and the
        status. Any exception stops the arm for this period and is reported; the node goes on."""
        begin = time.perf_counter()
        info: ControlInfo | None = None
        try:
            qdot, reason, info = self._control(self.now())
        except Exception as exc:  # any exception: stop, report, go on (issue 34)
            qdot, reason = np.zeros(self.setup.robot.nv), f"exception: {type(exc).__name__}: {exc}"
        self._publish(qdot)
        if info is not None and info.targets is not None and info.frame_due:
            self._publish_arms(info.targets)
        self._publish_status(reason, info, time.perf_counter() - begin)

    def stop(self) -> None:
        """Publish a zero command and end the planning worker (on shutdown)."""
        self._publish(np.zeros(self.setup.robot.nv))
        self.controller.close()

    def _control(self, now: float) -> tuple[Array, str | None, ControlInfo | None]:
        """The command, why the arm stops (or ``None``) and the cycle's info."""
        zero, settings = np.zeros(self.setup.robot.nv), self.settings
        if self._joint_error is not None:
            return zero, self._joint_error, None
        age = None if self._received is None else now - self._received
        early = stop_reason(age, settings.period, settings.stale_periods, 0.0, np.inf, None)
        if early is not None or self._q is None:
            return zero, early, None
        controller = self.controller
        if self._start is None:  # a robot holds still until its planner is ready
            controller.step(self._q, 0.0, settings.period)
            info = controller.last_info
            if controller.planning is not None and info.plan_age is None and info.worker_error is None:
                return zero, "waiting for the planning worker's first result", info
            self._start = now
        qdot = controller.step(self._q, now - self._start)  # applied until the next cycle: the period elapsed
        info = controller.last_info
        reason = stop_reason(age, settings.period, settings.stale_periods, info.hand_error, settings.max_hand_error,
                             info.worker_error)
        if reason is not None:
            return zero, reason, info
        qdot, note = within_limits(qdot, self.limits)
        if note is not None and not np.any(qdot):
            return qdot, note, info
        return qdot, None, info

    def _publish(self, qdot: Array) -> None:
        self._commands.publish(Float64MultiArray(data=[float(v) for v in qdot]))

    def _on_joint_state(self, msg: JointState) -> None:
        """Take the positions of the robot's joints, by name."""
        index = {name: i for i, name in enumerate(msg.name)}
        missing = [name for name in self.joint_names if name not in index]
        if missing or len(msg.position) < len(msg.name):
            self._joint_error = (f"joint states lack joints {', '.join(missing)} (got: {', '.join(msg.name)})"
                                 if missing else f"joint states with {len(msg.name)} names but {len(msg.position)} "
                                 "positions")
            return
        angles = np.array([msg.position[index[name]] for name in self.joint_names], dtype=float)
        self._q = self.setup.robot.configuration_from_angles(angles)
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        self._received, self._joint_error = stamp if stamp > 0 else self.now(), None

    def _on_markers(self, msg: MarkerArray) -> None:
        """Observe, forget or forget all, per marker; a bad marker is counted and reported, the others still
        apply."""
        for marker in msg.markers:
            try:
                self._apply(marker)
            except PreviewctlError as exc:
                self._bad_markers += 1
                self._marker_error = str(exc)
                self.get_logger().warning(f"bad marker: {exc}", throttle_duration_sec=1.0)  # all on ~/status

    def _apply(self, marker: Marker) -> None:
        frame = self.settings.frame_id
        if frame and marker.header.frame_id != frame:
            raise RosError(f"marker '{marker.ns}/{marker.id}' is in frame {marker.header.frame_id!r}, the node "
                           f"takes markers in {frame!r} (frame_id)")
        request = request_of(marker)
        if isinstance(request, ForgetAll):
            self.controller.forget_all()
        elif isinstance(request, Forget):
            self.controller.forget(request.name)
        elif isinstance(request, Observe):
            stamp = request.stamp if request.stamp > 0 else self.now()
            self.controller.observe(request.name, request.position, self.path_time(stamp),
                                    rotation=request.rotation, shape=request.shape)

    def _on_path(self, poses: list[Any]) -> None:
        """Follow a new hand path from where the hand is; the controller is made anew for it."""
        try:
            if self._q is None:
                raise RosError("a new path came before any joint state: the node cannot tell where the hand is")
            robot = self.setup.robot
            pin.framesForwardKinematics(robot.model, self._data, self._q)
            hand = self._data.oMf[robot.tip_frame_id].translation
            points = np.array([[p.position.x, p.position.y, p.position.z] for p in poses], dtype=float)
            path = path_from(robot, hand, points.reshape(-1, 3), self.settings.path_speed)
            controller = controller_for(self.setup, self.settings, path)
        except PreviewctlError as exc:
            self._marker_error = f"path refused: {exc}"
            self.get_logger().warning(self._marker_error, throttle_duration_sec=1.0)
            return
        self.controller.close()
        self.controller, self._start, self._evaluator = controller, None, None

    def _publish_arms(self, targets: Array) -> None:
        """Each imaginary arm as a line strip through its joints' origins and its hand."""
        robot, data, stamp = self.setup.robot, self._data, self.get_clock().now().to_msg()
        frame = self.settings.frame_id or "world"
        markers = []
        for i, q in enumerate(targets):
            pin.framesForwardKinematics(robot.model, data, q)
            points = [data.oMi[j].translation for j in range(1, robot.model.njoints)]
            points.append(data.oMf[robot.tip_frame_id].translation)
            marker = Marker(type=Marker.LINE_STRIP, action=Marker.ADD, ns="imaginary_arms", id=i)
            marker.header.frame_id, marker.header.stamp = frame, stamp
            marker.scale.x = 0.01
            marker.color.r, marker.color.g, marker.color.b, marker.color.a = 0.2, 0.6, 1.0, 0.6
            marker.pose.orientation.w = 1.0
            marker.points = [Point(x=float(p[0]), y=float(p[1]), z=float(p[2])) for p in points]
            markers.append(marker)
        self._arms.publish(MarkerArray(markers=markers))

    def _least_clearance(self, info: ControlInfo) -> float:
        """The smallest distance [m] between the arm and the controller's obstacles (the observed ones as
        predicted now)."""
        observed = self.controller.observed
        if observed is None or self._q is None:
            return float("nan")
        if self._evaluator is None or info.obstacles_added or info.obstacles_dropped:
            self._evaluator = Evaluator(self.setup.robot, observed.world.scene)
        return float(self._evaluator(self._q[None], self.path_time(self.now())).min_distance[0])

    def _publish_status(self, reason: str | None, info: ControlInfo | None, cycle: float) -> None:
        fresh_bad, self._reported_bad = self._bad_markers > self._reported_bad, self._bad_markers
        level = DiagnosticStatus.ERROR if reason is not None else (
            DiagnosticStatus.WARN if fresh_bad or (info is not None and info.fallback) else DiagnosticStatus.OK)
        state = "stopped" if reason is not None else "waiting" if self._start is None else "running"
        values = {
            "state": state,
            "path_time": self.path_time(self.now()),
            "plan_age": None if info is None else info.plan_age,
            "fallback": None if info is None else info.fallback,
            "least_clearance": None if info is None else self._least_clearance(info),
            "hand_error": None if info is None else info.hand_error,
            "cycle_time": cycle,
            "obstacles": "" if self.controller.observed is None else " ".join(self.controller.observed.world.observed),
            "bad_markers": self._bad_markers,
            "last_marker_error": self._marker_error,
        }
        pairs = [KeyValue(key=key, value="" if value is None else str(value)) for key, value in values.items()]
        status = DiagnosticStatus(level=level, name=NODE_NAME, hardware_id=self.setup.robot.name,
                                  message=reason or state, values=pairs)
        message = DiagnosticArray(status=[status])
        message.header.stamp = self.get_clock().now().to_msg()
        self._status.publish(message)
