"""axis_ptz_ros2: ROS 2 driver suite for Axis PTZ network cameras."""

__version__ = "0.1.0"
