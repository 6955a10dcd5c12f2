"""Launches akd_node (a lifecycle node) with a parameters file, for ROS 2 installs with `launch_ros`.

    ros2 launch akd_ros akd.launch.py                         # the built-in virtual AKD (config/akd_sim.yaml)
    ros2 launch akd_ros akd.launch.py params_file:=my_akd.yaml

The node walks itself to active (parameter `autostart`); with `autostart: false` drive it through its lifecycle
services (`ros2 lifecycle set /akd_node configure`, then `activate`).
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import LifecycleNode


def generate_launch_description() -> LaunchDescription:
    """akd_node with the parameters file given as `params_file` (default: the package's akd_sim.yaml)."""
    default_params = os.path.join(get_package_share_directory("akd_ros"), "config", "akd_sim.yaml")
    return LaunchDescription(
        [
            DeclareLaunchArgument(
                "params_file",
                default_value=default_params,
                description="akd_node parameters file (see config/akd.yaml for a real drive)",
            ),
            DeclareLaunchArgument("namespace", default_value="", description="namespace of the node"),
            LifecycleNode(
                package="akd_ros",
                executable="akd_node",
                name="akd_node",
                namespace=LaunchConfiguration("namespace"),
                parameters=[LaunchConfiguration("params_file")],
                output="screen",
                # SIGINT first: the node disables the drive and returns the bus to Init before it exits.
                sigterm_timeout="10",
            ),
        ]
    )
