"""The camera driver on the robot: ``axis_camera`` (stream + PTZ in one process).

    ros2 launch axis_ptz_ros2 camera.launch.py params_file:=/path/to/my_camera.params.yaml
    ros2 launch axis_ptz_ros2 camera.launch.py namespace:=robot1 robot_state_publisher:=true
    ros2 launch axis_ptz_ros2 camera.launch.py simulated_camera:=true     # no camera: the simulated Axis 214

Arguments:
  params_file            parameters of axis_stream and axis_ptz (default: config/axis_camera.params.yaml,
                         which points at loopback: copy it and set your camera's hostname). Its sections are
                         keyed /**/axis_stream and /**/axis_ptz so they apply under any namespace
  namespace              ROS namespace of both nodes (default: none)
  robot_state_publisher  true: also run robot_state_publisher with urdf/axis_214.urdf.xacro (mount and head from
                         config/), fed by the PTZ node's joint_states; the PTZ node then leaves the head's /tf to it
                         (publish_tf false) so every frame has one parent. Needs the xacro and
                         robot_state_publisher packages.
  simulated_camera       true: also start the simulated Axis 214 PTZ (axis_camera_sim, MJPEG on 127.0.0.1:8080) and
                         point both nodes at it (hostname, port over the params file): the driver with no camera
  frame_prefix           robot_state_publisher's frame_prefix (default: none): set it to the params file's
                         frame_prefix (e.g. robot2/) when several robots share /tf
Credentials: AXIS_USERNAME / AXIS_PASSWORD in the environment of `ros2 launch`, or `password_file` in the params.
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition, UnlessCondition
from launch.substitutions import Command, LaunchConfiguration, PathJoinSubstitution, PythonExpression
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare

SIMULATED_PORT = 8080  # axis_camera_sim's default port


def generate_launch_description() -> LaunchDescription:
    share = FindPackageShare("axis_ptz_ros2")
    params_file = LaunchConfiguration("params_file")
    namespace = LaunchConfiguration("namespace")
    use_rsp = LaunchConfiguration("robot_state_publisher")
    frame_prefix = LaunchConfiguration("frame_prefix")
    simulated = LaunchConfiguration("simulated_camera")
    publish_tf = {"publish_tf": ParameterValue(PythonExpression(["'", use_rsp, "' != 'true'"]), value_type=bool)}
    return LaunchDescription(
        [
            DeclareLaunchArgument(
                "params_file",
                default_value=PathJoinSubstitution([share, "config", "axis_camera.params.yaml"]),
                description="parameters of axis_stream and axis_ptz",
            ),
            DeclareLaunchArgument("namespace", default_value="", description="namespace of the camera nodes"),
            DeclareLaunchArgument(
                "robot_state_publisher",
                default_value="false",
                description="publish the head's frames with robot_state_publisher from urdf/axis_214.urdf.xacro",
            ),
            DeclareLaunchArgument(
                "simulated_camera",
                default_value="false",
                description="true: start axis_camera_sim on 127.0.0.1:8080 and point the driver at it",
            ),
            DeclareLaunchArgument(
                "frame_prefix",
                default_value="",
                description="robot_state_publisher's frame_prefix: the params file's frame_prefix (e.g. robot2/)",
            ),
            # first: if robot_state_publisher is missing, launch fails before it has started axis_camera, which it
            # would otherwise leave running (an orphan: seen under the real Jazzy launch)
            Node(
                package="robot_state_publisher",
                executable="robot_state_publisher",
                namespace=namespace,
                output="screen",
                condition=IfCondition(use_rsp),
                parameters=[
                    {
                        "robot_description": ParameterValue(
                            Command(["xacro ", PathJoinSubstitution([share, "urdf", "axis_214.urdf.xacro"])]),
                            value_type=str,
                        ),
                        "frame_prefix": frame_prefix,
                    }
                ],
            ),
            Node(  # not a ROS node: an HTTP server that ignores the --ros-args launch may add
                package="axis_ptz_ros2",
                executable="axis_camera_sim",
                arguments=["--port", str(SIMULATED_PORT)],
                output="screen",
                condition=IfCondition(simulated),
            ),
            Node(
                package="axis_ptz_ros2",
                executable="axis_camera",
                namespace=namespace,
                output="screen",
                parameters=[params_file, publish_tf],
                condition=UnlessCondition(simulated),
            ),
            Node(
                package="axis_ptz_ros2",
                executable="axis_camera",
                namespace=namespace,
                output="screen",
                parameters=[params_file, publish_tf, {"hostname": "127.0.0.1", "port": SIMULATED_PORT}],
                condition=IfCondition(simulated),
            ),
        ]
    )
