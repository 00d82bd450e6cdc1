"""``previewctl ros``: start ROS, run the node (and, for a trial without a robot, a fake one) until Ctrl-C or
SIGTERM, then publish a zero command and stop cleanly."""

from __future__ import annotations

import signal
from collections.abc import Sequence
from types import FrameType

import numpy as np

from previewctl.control.background import real_time_loop
from previewctl.extras import require
from previewctl.ros.environment import loopback_environment


def _interrupt(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt


def spin(params_file: str | None, ros_args: Sequence[str] = (), *, loopback: int | None = None,
         fake_robot: bool = False) -> None:
    """Run the node until interrupted.

    Args:
        params_file: a ROS parameter file (YAML) for the node, or ``None``.
        ros_args: more ROS arguments (``-p name:=value``, remappings), as after ``--ros-args``.
        loopback: set the loopback-only environment on this ROS domain first
            (:func:`~previewctl.ros.environment.loopback_environment`), or ``None``: the environment as it is.
        fake_robot: also run a :class:`~previewctl.ros.fake.FakeRobot` at the scenario's start (or the robot's
            neutral configuration) in the same executor.

    Raises:
        MissingExtraError: the ``[ros]`` extra is not installed.
        PreviewctlError: settings the node cannot run with.
    """
    if loopback is not None:
        loopback_environment(loopback)
    rclpy = require("rclpy", "ros", "previewctl ros")
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    from previewctl.ros.fake import FakeRobot
    from previewctl.ros.node import ControllerNode

    args = ["previewctl", "--ros-args", *(["--params-file", params_file] if params_file else []), *ros_args]
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)  # Ctrl-C reaches us: zero first
    # SIGINT too: a process started in the background of a shell inherits it ignored
    previous = {sig: signal.signal(sig, _interrupt) for sig in (signal.SIGINT, signal.SIGTERM)}
    node = None
    executor = SingleThreadedExecutor()
    try:
        node = ControllerNode()
        executor.add_node(node)
        if fake_robot:
            setup = node.setup
            q0 = setup.scenario.q0 if setup.scenario is not None else setup.robot.neutral()
            angles = setup.robot.angles_of(np.asarray(q0, dtype=float)[None])[0]
            executor.add_node(FakeRobot(node.joint_names, angles.tolist(), 4 * node.settings.rate,
                                        node.settings.commands_topic, node.settings.joint_states_topic))
        with real_time_loop() as granted:  # the node's loop on the core its workers leave free, real-time class
            for refusal in granted.refusals:
                node.get_logger().warning(refusal)
            executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.stop()
        executor.shutdown()
        for each in executor.get_nodes():
            each.destroy_node()
        rclpy.try_shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
