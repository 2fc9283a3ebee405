"""The camera driver plus the operator tools: web console, visualizer, raw-image republisher, and optionally
a joystick (the ``joy`` package's game_controller_node + ``axis_joy_teleop``).

    ros2 launch axis_ptz_ros2 operator.launch.py camera_params:=/path/to/my_camera.params.yaml joystick:=true

On a real robot the tools usually run on the operator's computer: start camera.launch.py on the robot and this
file with camera:=false on the operator's side (same ROS_DOMAIN_ID). The keyboard teleop needs a terminal of its
own: `ros2 run axis_ptz_ros2 axis_keyboard_teleop`.

Arguments:
  camera         true: include camera.launch.py here (default true)
  camera_params  parameters of the camera driver (default: config/axis_camera.params.yaml)
  tools_params   parameters of the web console, visualizer and republisher (config/operator_tools.params.yaml)
  joystick       true: also run game_controller_node and axis_joy_teleop (default false)
  joy_params     parameters of axis_joy_teleop (default: config/joy_gamepad.params.yaml)
  namespace      namespace of every node (default: none)
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, IncludeLaunchDescription
from launch.conditions import IfCondition
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare


def generate_launch_description() -> LaunchDescription:
    share = FindPackageShare("axis_ptz_ros2")
    namespace = LaunchConfiguration("namespace")
    tools_params = LaunchConfiguration("tools_params")
    joystick = LaunchConfiguration("joystick")
    return LaunchDescription(
        [
            DeclareLaunchArgument("camera", default_value="true", description="include camera.launch.py"),
            DeclareLaunchArgument(
                "camera_params",
                default_value=PathJoinSubstitution([share, "config", "axis_camera.params.yaml"]),
                description="parameters of the camera driver",
            ),
            DeclareLaunchArgument(
                "tools_params",
                default_value=PathJoinSubstitution([share, "config", "operator_tools.params.yaml"]),
                description="parameters of the operator tools",
            ),
            DeclareLaunchArgument("joystick", default_value="false", description="run the joystick teleop"),
            DeclareLaunchArgument(
                "joy_params",
                default_value=PathJoinSubstitution([share, "config", "joy_gamepad.params.yaml"]),
                description="parameters of axis_joy_teleop",
            ),
            DeclareLaunchArgument("namespace", default_value="", description="namespace of every node"),
            IncludeLaunchDescription(
                PythonLaunchDescriptionSource(PathJoinSubstitution([share, "launch", "camera.launch.py"])),
                launch_arguments={
                    "params_file": LaunchConfiguration("camera_params"),
                    "namespace": namespace,
                }.items(),
                condition=IfCondition(LaunchConfiguration("camera")),
            ),
            Node(
                package="axis_ptz_ros2",
                executable="axis_web_console",
                namespace=namespace,
                output="screen",
                parameters=[tools_params],
            ),
            Node(
                package="axis_ptz_ros2",
                executable="axis_visualizer",
                namespace=namespace,
                output="screen",
                parameters=[tools_params],
            ),
            Node(
                package="axis_ptz_ros2",
                executable="axis_republish",
                namespace=namespace,
                output="screen",
                parameters=[tools_params],
            ),
            Node(
                package="joy",
                executable="game_controller_node",
                namespace=namespace,
                output="screen",
                condition=IfCondition(joystick),
                # joy's own parameters: repeat the last state at 20 Hz so a held stick keeps the head moving and
                # a dead joystick driver is noticed by axis_joy_teleop's joy_timeout
                parameters=[{"autorepeat_rate": 20.0, "deadzone": 0.05}],
            ),
            Node(
                package="axis_ptz_ros2",
                executable="axis_joy_teleop",
                namespace=namespace,
                output="screen",
                condition=IfCondition(joystick),
                parameters=[LaunchConfiguration("joy_params")],
            ),
        ]
    )
