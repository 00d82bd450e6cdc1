"""Launch previewctl's node next to a running ros2_control Panda (real, or simulated with mock hardware).

    ros2 launch examples/ros/panda.launch.py                    # the robot's own launch already runs
    ros2 launch examples/ros/panda.launch.py loopback:=true     # a trial on this machine only (domain 42)

It activates ``forward_velocity_controller`` (examples/ros/controllers.yaml must be in the robot's controllers
file) and starts ``previewctl ros`` with examples/ros/panda.yaml. Needs a ROS 2 install (launch, launch_ros,
controller_manager) besides ``pip install 'previewctl[ros]'``; see docs/guide/ros.md.
"""

from pathlib import Path

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, ExecuteProcess
from launch.conditions import IfCondition, UnlessCondition
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

HERE = Path(__file__).resolve().parent


def generate_launch_description() -> LaunchDescription:
    """The spawner of the velocity controller and previewctl's node."""
    params = str(HERE / "panda.yaml")
    loopback = LaunchConfiguration("loopback")
    return LaunchDescription([
        DeclareLaunchArgument("loopback", default_value="false",
                              description="keep DDS on this machine (previewctl ros --loopback 42)"),
        Node(package="controller_manager", executable="spawner", arguments=["forward_velocity_controller"]),
        ExecuteProcess(cmd=["previewctl", "ros", "--params-file", params], cwd=str(HERE.parents[1]),
                       output="screen", condition=UnlessCondition(loopback)),
        ExecuteProcess(cmd=["previewctl", "ros", "--params-file", params, "--loopback", "42"],
                       cwd=str(HERE.parents[1]), output="screen", condition=IfCondition(loopback)),
    ])
