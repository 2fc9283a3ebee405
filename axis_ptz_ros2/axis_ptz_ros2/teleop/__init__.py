"""axis_ptz_ros2.teleop."""
