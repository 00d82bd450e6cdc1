"""``previewctl ros``: the ROS 2 node (the ``[ros]`` extra)."""

from __future__ import annotations

import argparse

from previewctl.cli.common import Commands, ExitCode


def add_parser(commands: Commands) -> None:
    """The ``ros`` subcommand and its options."""
    ros = commands.add_parser(
        "ros",
        help="run the ROS 2 node: joint velocities for a ros2_control robot (the [ros] extra)",
        description="Run previewctl as a ROS 2 node (needs pip install 'previewctl[ros]'). It reads /joint_states "
        "and obstacle markers on ~/obstacles (visualization_msgs/MarkerArray: spheres, cubes, cylinders), steps a "
        "controller at the parameter 'rate' and publishes joint velocities (std_msgs/Float64MultiArray) on "
        "/forward_velocity_controller/commands, the imaginary arms on ~/imaginary_arms and its status on "
        "~/status. It publishes zero velocity, and says why on ~/status, when the joint states are older than 3 "
        "periods, the hand error exceeds max_hand_error, the planning worker failed or a cycle raised. Parameters "
        "(a scenario file, or robot + waypoints + duration; rate, topics, joint_names, limits) come from a ROS "
        "parameter file whose top key is the node name, 'previewctl' (see examples/ros/panda.yaml and "
        "docs/guide/ros.md). Ctrl-C or SIGTERM: a zero command, then exit 0.",
    )
    ros.add_argument("--params-file", metavar="YAML", help="ROS parameter file of the node (previewctl: "
                     "ros__parameters: ...)")
    ros.add_argument("--loopback", metavar="DOMAIN_ID", type=int, default=None,
                     help="keep DDS on this machine (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, the packaged Fast DDS "
                     "profile: shared memory and UDP on 127.0.0.1) on ROS domain DOMAIN_ID (0-101)")
    ros.add_argument("--fake-robot", action="store_true",
                     help="also run a fake robot that integrates the commands and publishes /joint_states, from the "
                     "scenario's start (a trial without a robot)")
    ros.add_argument("ros_args", nargs=argparse.REMAINDER, metavar="--ros-args ...",
                     help="ROS arguments for the node, e.g. --ros-args -p rate:=100.0")
    ros.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from previewctl.ros.run import spin

    ros_args = list(args.ros_args)
    if ros_args[:1] == ["--ros-args"]:
        ros_args = ros_args[1:]
    spin(args.params_file, ros_args, loopback=args.loopback, fake_robot=args.fake_robot)
    return ExitCode.OK
