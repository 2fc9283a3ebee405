"""The simulated Axis 214 PTZ camera: world, renderer, VAPIX HTTP server and fault injection (ROS-free)."""

from axis_ptz_ros2.sim.camera import SimulatedCamera
from axis_ptz_ros2.sim.faults import FaultConfig
from axis_ptz_ros2.sim.ptz import PtzState, Speeds, ros_to_vapix, vapix_to_ros
from axis_ptz_ros2.sim.renderer import PtzRenderer
from axis_ptz_ros2.sim.scene import Scene, Target
from axis_ptz_ros2.sim.world import SimWorld, load_world

__all__ = [
    "FaultConfig",
    "PtzRenderer",
    "PtzState",
    "Scene",
    "SimWorld",
    "SimulatedCamera",
    "Speeds",
    "Target",
    "load_world",
    "ros_to_vapix",
    "vapix_to_ros",
]
