"""Virtual PTZ camera: perspective views rendered from an equirectangular panorama (ROS-free)."""

from axis_ptz_ros2.virtual.render import ViewSpec, VirtualCameraRenderer, direction_pixel, equirect_maps

__all__ = ["ViewSpec", "VirtualCameraRenderer", "direction_pixel", "equirect_maps"]
