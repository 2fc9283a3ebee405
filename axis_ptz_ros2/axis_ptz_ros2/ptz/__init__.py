"""ROS-free PTZ control core: the backend protocol, the Axis backend, the latest-wins command slot, the state
poller and the state loop (poll thread, self-restart, health), the commander (targets recorded on acceptance,
velocity mode, presets, arrival, goal pre-emption), request checks and clamps, following orders (services,
goals, cancel), the drive-safe zoom cap and the pointing maths glue (everything in ROS units: radians REP-103,
VAPIX zoom units).

Nothing here imports ``rclpy`` or ROS messages; :class:`axis_ptz_ros2.nodes.ptz_node.PtzNode` is the thin ROS
layer on top, and the same node serves any :class:`~axis_ptz_ros2.ptz.backend.PtzBackend`.
"""
