"""``camera_info_url`` + ``set_camera_info``: camera_info_manager's behaviour on the stream node (ROS glue).

The ROS-free part is :class:`~axis_ptz_ros2.camera_info_store.CameraInfoStore` (URL resolution, the standard
calibration YAML, atomic writes, the refusals). This module adds the parameters, the
``sensor_msgs/srv/SetCameraInfo`` service and the hand-over to the zoom-aware camera model:

* At start-up the calibration at ``camera_info_url`` (if the file exists) becomes the camera's K and D at the
  zoom it was taken at; a malformed file or a refused URL is logged with the reason and the camera model's own
  calibration stays (as camera_info_manager: the node runs uncalibrated rather than not at all).
* ``~/set_camera_info`` (the node's private name, as Jazzy's camera_info_manager registers it; Humble's was
  ``set_camera_info`` beside the topics) stores the new calibration at the URL and applies it at once; ``success`` /
  ``status_message`` tell what happened. Refused (previous calibration kept): wrong matrix sizes, values the
  calibration model refuses, a size other than the stream's, an unusable URL, an unwritable file.
"""

from __future__ import annotations

from collections.abc import Callable

from rclpy.node import Node
from sensor_msgs.srv import SetCameraInfo

from axis_ptz_ros2.camera_info import CameraInfoError
from axis_ptz_ros2.camera_info_store import CameraInfoStore, CameraInfoUrlError, StoreResult
from axis_ptz_ros2.config import CameraModel
from axis_ptz_ros2.nodes.common import ParamSpec

PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec(
        "camera_info_url",
        "",
        "calibration file: file:///path/${NAME}.yaml or package://pkg/path.yaml ('' = "
        "${ROS_HOME}/camera_info/${NAME}.yaml); loaded at start, written by set_camera_info",
        read_only=True,
    ),
    ParamSpec(
        "camera_name", "axis_ptz", "camera name (${NAME} in camera_info_url; letters, digits, '_')", read_only=True
    ),
)


class CameraInfoService:
    """The stream node's calibration: ``apply(model)`` is the camera model with the stored calibration."""

    def __init__(
        self,
        node: Node,
        url: str,
        camera_name: str,
        stream_size: Callable[[], tuple[int, int]],
        zoom: Callable[[], float],
        on_change: Callable[[], None],
    ) -> None:
        """Load the calibration at ``url`` and offer ``set_camera_info``; ``stream_size``/``zoom`` are read when
        a calibration is stored, ``on_change`` is called after one was (e.g. to drop cached camera_info)."""
        self._node, self._stream_size, self._zoom, self._on_change = node, stream_size, zoom, on_change
        self._store: CameraInfoStore | None = None
        self._url_problem = ""
        log = node.get_logger()
        try:
            self._store = CameraInfoStore(url, camera_name)
        except CameraInfoUrlError as err:
            self._url_problem = str(err)
            log.error(f"camera_info_url refused: {err}; set_camera_info will refuse to store")
        if self._store is not None:
            try:
                if self._store.load():
                    log.info(f"calibration loaded from {self._store.path} (zoom {self._store.zoom})")
            except CameraInfoError as err:
                log.error(f"calibration not loaded: {err}; using the camera model's")
        node.create_service(SetCameraInfo, "~/set_camera_info", self._on_set)

    def apply(self, model: CameraModel) -> CameraModel:
        """``model`` with the stored calibration (unchanged when none is stored)."""
        store = self._store
        if store is None or store.calibration is None:
            return model
        return model.with_camera_info(store.calibration, store.zoom)

    def store(self, msg: object) -> StoreResult:
        """Store a ``sensor_msgs/CameraInfo`` at the URL and make it current (the service's body)."""
        if self._store is None:
            return StoreResult(False, f"refused: {self._url_problem}; nothing stored")
        result = self._store.store_msg(msg, self._stream_size(), self._zoom())
        if result.success:
            self._on_change()
        return result

    def _on_set(self, request: SetCameraInfo.Request, response: SetCameraInfo.Response) -> SetCameraInfo.Response:
        result = self.store(request.camera_info)
        response.success, response.status_message = result.success, result.status_message
        log = self._node.get_logger()
        if result.success:
            log.info(f"set_camera_info: {result.status_message}")
        else:
            log.warning(f"set_camera_info: {result.status_message}")
        return response
