"""The stream node's ``camera_info``: one message with every frame, built once per (size, zoom) and restamped.

K (and D, P where measured) come from the camera model at the zoom reported on ``ptz/state`` (a PTZ node runs) or
else the ``zoom`` parameter, at the frame's own size; a calibration stored through ``~/set_camera_info``
(:class:`~axis_ptz_ros2.nodes.camera_info_service.CameraInfoService`) goes over the model's. ROS glue: the
optics are :mod:`axis_ptz_ros2.camera_models`' and :mod:`axis_ptz_ros2.camera_info`'s.
"""

from __future__ import annotations

from collections.abc import Callable

from builtin_interfaces.msg import Time
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.subscription import Subscription
from sensor_msgs.msg import CameraInfo

from axis_ptz_interfaces.msg import PtzState
from axis_ptz_ros2.camera_info import fill_camera_info_msg
from axis_ptz_ros2.config import CameraModel
from axis_ptz_ros2.nodes.camera_info_service import CameraInfoService
from axis_ptz_ros2.nodes.common import STREAM_QOS, camera_info_msg, publisher

_MAX_CACHED = 64  # (size, zoom) pairs; a zooming head makes new ones all the time


class CameraInfoOutput:
    """``camera_info`` publisher, ``ptz/state`` zoom, ``camera_info_url`` + ``~/set_camera_info``."""

    def __init__(
        self,
        node: Node,
        model: CameraModel,
        frame_id: str,
        zoom: float,
        calibration: tuple[str, str],
        stream_size: Callable[[], tuple[int, int]],
        *,
        events: PublisherEventCallbacks,
    ) -> None:
        """``model``: until the camera has said what it is (:meth:`set_model`); ``zoom``: the ``zoom`` parameter;
        ``calibration``: (``camera_info_url``, ``camera_name``); ``stream_size()``: the size requested."""
        self._frame_id = frame_id
        self._model = model
        self._zoom_param = zoom
        self._zoom_ptz: float | None = None
        self._cache: dict[tuple[int, int, float], CameraInfo] = {}
        self._calibration = CameraInfoService(  # camera_info_url + set_camera_info, as camera_info_manager
            node, calibration[0], calibration[1], stream_size, self.zoom, self._cache.clear
        )
        self.pub: Publisher = publisher(node, CameraInfo, "camera_info", STREAM_QOS, event_callbacks=events)
        self._node = node
        self._ptz_sub: Subscription | None = node.create_subscription(
            PtzState, "ptz/state", self._on_ptz_state, STREAM_QOS
        )

    @property
    def model(self) -> CameraModel:
        """The camera model in use."""
        return self._model

    def set_model(self, model: CameraModel) -> None:
        """The camera said what it is (discovery thread)."""
        self._model = model
        self._cache.clear()

    def zoom(self) -> float:
        """The zoom of K: the PTZ node's when it publishes, else the parameter's."""
        return self._zoom_ptz if self._zoom_ptz is not None else self._zoom_param

    def set_zoom_param(self, zoom: float) -> None:
        """The ``zoom`` parameter changed."""
        self._zoom_param = zoom

    def _on_ptz_state(self, msg: PtzState) -> None:
        self._zoom_ptz = float(msg.zoom)

    def direct_zoom(self) -> Callable[[float], None]:
        """For a PTZ node in the same process (``axis_camera``): drop the ``ptz/state`` subscription and return
        the function that PTZ node calls with each polled zoom (VAPIX units) instead. The subscription
        deserialised 20 messages a second for one number: most of what the composed process cost over its two
        nodes alone (bench/bench_cpu.py)."""
        if self._ptz_sub is not None:
            self._node.destroy_subscription(self._ptz_sub)
            self._ptz_sub = None
        return self._set_zoom_ptz

    def _set_zoom_ptz(self, zoom: float) -> None:
        self._zoom_ptz = float(zoom)  # one attribute store: safe from the PTZ node's poll thread

    def publish(self, width: int, height: int, stamp: Time) -> None:
        """Hot path (reader thread): the camera_info of a ``width`` x ``height`` frame, restamped."""
        zoom = self.zoom()
        key = (width, height, zoom)
        info = self._cache.get(key)
        if info is None:
            if len(self._cache) > _MAX_CACHED:
                self._cache.clear()
            model = self._calibration.apply(self._model)  # a stored calibration (set_camera_info) first
            calib = model.camera_info_at(zoom, width, height)  # measured K, D, P if configured
            info = fill_camera_info_msg(camera_info_msg(calib.intrinsics(), self._frame_id, stamp), calib)
            self._cache[key] = info
        info.header.stamp = stamp
        self.pub.publish(info)
