"""The virtual camera: a perspective view cut from the robot's panorama behind the same PTZ interface as the
Axis camera (so the teleops, the web console and the visualizer drive it unchanged).

    ros2 launch axis_ptz_ros2 virtual_camera.launch.py namespace:=virtual
    ros2 launch axis_ptz_ros2 virtual_camera.launch.py simulate_panorama:=true     # no robot: a simulated panorama

Arguments:
  params_file        parameters of axis_virtual_camera and its PTZ node (config/virtual_camera.params.yaml)
  namespace          namespace of the virtual camera (default: none; use one when the Axis camera runs too,
                     both serve ptz/* and image_raw/compressed)
  panorama_topic     the panorama image topic (base name; default panorama/image_raw, as the robot's)
  simulate_panorama  true: also run axis_panorama_sim (the simulated robot's omnidirectional camera)
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare


def generate_launch_description() -> LaunchDescription:
    share = FindPackageShare("axis_ptz_ros2")
    return LaunchDescription(
        [
            DeclareLaunchArgument(
                "params_file",
                default_value=PathJoinSubstitution([share, "config", "virtual_camera.params.yaml"]),
                description="parameters of axis_virtual_camera and axis_virtual_camera_ptz",
            ),
            DeclareLaunchArgument("namespace", default_value="", description="namespace of the virtual camera"),
            DeclareLaunchArgument(
                "panorama_topic", default_value="/panorama/image_raw", description="panorama topic (base name)"
            ),
            DeclareLaunchArgument(
                "simulate_panorama", default_value="false", description="also run the simulated panorama camera"
            ),
            Node(
                package="axis_ptz_ros2",
                executable="axis_virtual_camera",
                namespace=LaunchConfiguration("namespace"),
                output="screen",
                parameters=[
                    LaunchConfiguration("params_file"),
                    {"panorama_topic": LaunchConfiguration("panorama_topic")},
                ],
            ),
            Node(
                package="axis_ptz_ros2",
                executable="axis_panorama_sim",
                output="screen",
                condition=IfCondition(LaunchConfiguration("simulate_panorama")),
            ),
        ]
    )
