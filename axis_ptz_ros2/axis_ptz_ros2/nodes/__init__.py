"""axis_ptz_ros2.nodes."""
