"""``axis_virtual_camera``: a virtual PTZ camera — a perspective view cut from the equirectangular panorama,
driven through exactly the same interface as the real PTZ node.

Two nodes in one process:

* :class:`~axis_ptz_ros2.nodes.ptz_node.PtzNode` (name ``axis_virtual_camera_ptz``) over a
  :class:`~axis_ptz_ros2.virtual.backend.VirtualPtzBackend`: ``ptz/cmd/*``, ``ptz/state``, ``joint_states``,
  ``ptz/transform``, ``ptz/move_absolute`` … exactly as for the Axis head, so the keyboard teleop, the web
  console and the visualizer drive it unchanged.
* :class:`VirtualCameraNode` (name ``axis_virtual_camera``): subscribes to the panorama (``CompressedImage``
  or ``Image``), renders the view of the head's current pose with
  :class:`~axis_ptz_ros2.virtual.render.VirtualCameraRenderer` (cached fixed-point maps) and publishes
  ``image_raw/compressed`` (JPEG) + ``camera_info`` whose K is exactly the K of the render
  (:attr:`ViewSpec.intrinsics <axis_ptz_ros2.virtual.render.ViewSpec.intrinsics>`).

The view sits at the panorama's origin; its pan/tilt are REP-103 angles about ``base_link`` axes (the
``virtual_camera_base`` frame is ``base_link`` translated to the panorama origin), so the renderer gets
``R_pano_base`` from the panorama pose in ``config/robot.yaml``. A panorama frame is decoded once (when it is
first needed: :mod:`axis_ptz_ros2.virtual.decode`) and kept; a view is rendered only when the panorama or the
pose changed (or a new subscriber came, or ``min_rate`` asks for a refresh), at most at ``rate`` Hz, and only
while ``image_raw/compressed`` or ``camera_info`` has a subscriber (:class:`~axis_ptz_ros2.virtual.camera.RenderGate`;
the square-pixel camera model is :func:`~axis_ptz_ros2.virtual.camera.view_model_dict`). Images are stamped with
the time the pose was read (the pose they show; ``ptz/transform`` at that stamp).
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt
import yaml
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import CameraInfo, CompressedImage, Image

from axis_ptz_ros2.config import (
    MountConfig,
    camera_model_from_dict,
    default_config_path,
    load_robot,
)
from axis_ptz_ros2.nodes.common import (
    STREAM_QOS,
    ParamSpec,
    camera_info_msg,
    jpeg_image_msg,
    publisher,
    stamp_from_ns,
)
from axis_ptz_ros2.nodes.live_params import LiveParams, Params
from axis_ptz_ros2.nodes.ptz_node import FRAME_PARAMS, PtzNode
from axis_ptz_ros2.nodes.runner import run_nodes
from axis_ptz_ros2.transforms import Transform
from axis_ptz_ros2.virtual.backend import VirtualPtzBackend, dynamics_from_model, limits_from_model
from axis_ptz_ros2.virtual.camera import RenderGate, view_model_dict
from axis_ptz_ros2.virtual.decode import U8, decode_compressed, decode_raw
from axis_ptz_ros2.virtual.render import ViewSpec, VirtualCameraRenderer

_PTZ_FRAMES = {s.name: s for s in FRAME_PARAMS}
#: The PTZ node's frame and joint parameters, with the virtual camera's defaults; handed on to its PTZ node.
_FRAME_PARAMS: tuple[ParamSpec, ...] = (
    _PTZ_FRAMES["frame_prefix"],
    replace(_PTZ_FRAMES["ptz_base_frame"], default="virtual_camera_base",
            description="pan/tilt base frame at the panorama origin"),
    replace(_PTZ_FRAMES["optical_frame"], default="virtual_camera_optical_frame",
            description="optical frame of the view"),
    replace(_PTZ_FRAMES["pan_joint"], default="virtual_camera_pan_joint"),
    replace(_PTZ_FRAMES["tilt_joint"], default="virtual_camera_tilt_joint"),
)  # fmt: skip

PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec("camera_model", "", "virtual camera model YAML ('' = config/virtual_camera.yaml)", read_only=True),
    ParamSpec("robot_file", "", "robot frames YAML: the panorama pose ('' = config/robot.yaml)", read_only=True),
    ParamSpec("width", 640, "width of the rendered view", "px", int_range=(16, 4096), read_only=True),
    ParamSpec("height", 480, "height of the rendered view", "px", int_range=(16, 4096), read_only=True),
    ParamSpec("rate", 15.0, "maximum rendering rate", "Hz", float_range=(0.5, 60.0), read_only=True),
    ParamSpec(
        "min_rate",
        1.0,
        "re-render a still view at least this often (0 = only on change)",
        "Hz",
        float_range=(0.0, 30.0),
    ),
    ParamSpec("jpeg_quality", 90, "JPEG quality of image_raw/compressed", "", int_range=(1, 100)),
    ParamSpec("panorama_topic", "panorama/image_raw", "panorama image topic (base name)", read_only=True),
    ParamSpec(
        "panorama_transport",
        "compressed",
        "subscribe to <panorama_topic>/compressed (CompressedImage) or <panorama_topic> (Image)",
        choices=("compressed", "raw"),
        read_only=True,
    ),
    *_FRAME_PARAMS,
    ParamSpec("ptz_node_name", "axis_virtual_camera_ptz", "name of the PTZ node in this process", read_only=True),
)
#: PtzNode parameters this process fixes (the view size is the render size; frames from the panorama pose).
_FIXED_PTZ_PARAMS = ("image_width", "image_height", "follow_video_params")

FloatArray = npt.NDArray[np.float64]


@dataclass
class RenderStats:
    """Counters of the render part (monotonic)."""

    panoramas_received: int = 0
    panoramas_decoded: int = 0
    decode_failures: int = 0
    frames_published: int = 0
    render_s: float = 0.0  # of the last frame: remap
    encode_s: float = 0.0  # of the last frame: JPEG encoding
    decode_s: float = 0.0  # of the last decoded panorama


class VirtualCameraNode(Node):
    """Renders and publishes the virtual PTZ view; creates the :class:`PtzNode` that drives it (``.ptz``).

    The PTZ node is created with the same ``kwargs`` (context, parameter overrides …) but is *not* owned for
    destruction: spin and destroy both nodes (``main`` does; tests add both to their executor).
    """

    def __init__(self, *, node_name: str = "axis_virtual_camera", **kwargs: Any) -> None:
        """Declare parameters, build the virtual head and its PTZ node, subscribe to the panorama."""
        super().__init__(node_name, **kwargs)
        self._live = LiveParams(self, PARAMS)  # min_rate, jpeg_quality: read from the snapshot at each frame
        p = self._live.params
        self.width, self.height = int(p["width"]), int(p["height"])

        model_path = Path(p["camera_model"]) if p["camera_model"] else default_config_path("virtual_camera.yaml")
        raw = view_model_dict(yaml.safe_load(model_path.read_text(encoding="utf-8")) or {}, self.width, self.height)
        self.model = camera_model_from_dict(raw, str(model_path))
        self.zoom_model = self.model.zoom
        robot = load_robot(p["robot_file"] or None)
        T_base_pano = robot.panorama.pose
        self.R_pano_base: FloatArray = np.asarray(T_base_pano.R.T, dtype=np.float64)
        self.backend = VirtualPtzBackend(
            limits_from_model(self.model), self.zoom_model, dynamics_from_model(self.model, raw.get("dynamics"))
        )
        mount = MountConfig(
            transform=Transform(np.eye(3), np.asarray(T_base_pano.t, dtype=np.float64).copy()),
            parent_frame=robot.base_frame,
            child_frame=str(p["ptz_base_frame"]),
            comment="virtual camera: base_link axes at the panorama origin",
        )
        self.ptz = self._make_ptz_node(raw, mount, kwargs)
        self.optical_frame = str(p["frame_prefix"]) + str(p["optical_frame"])

        self._group = MutuallyExclusiveCallbackGroup()  # panorama callback and render timer never overlap
        self._image_pub = publisher(self, CompressedImage, "image_raw/compressed", STREAM_QOS)
        self._info_pub = publisher(self, CameraInfo, "camera_info", STREAM_QOS)
        topic = str(p["panorama_topic"])
        if p["panorama_transport"] == "compressed":
            self.panorama_topic = topic.rstrip("/") + "/compressed"
            self.create_subscription(
                CompressedImage, self.panorama_topic, self._on_panorama, STREAM_QOS, callback_group=self._group
            )
        else:
            self.panorama_topic = topic
            self.create_subscription(Image, topic, self._on_panorama, STREAM_QOS, callback_group=self._group)

        self.stats = RenderStats()
        self._pending: CompressedImage | Image | None = None  # newest panorama not decoded yet
        self._pano: U8 | None = None
        self._pano_seq = 0
        self._renderer: VirtualCameraRenderer | None = None
        self._out: U8 | None = None
        self._gate = RenderGate()
        self.last_view: ViewSpec | None = None
        self._timer = self.create_timer(1.0 / float(p["rate"]), self._on_timer, callback_group=self._group)
        self.get_logger().info(
            f"virtual camera {self.width}x{self.height} from {self.panorama_topic}, "
            f"hfov {math.degrees(self.zoom_model.hfov(self.zoom_model.min_zoom)):.1f}.."
            f"{math.degrees(self.zoom_model.hfov(self.zoom_model.max_zoom)):.2f} deg, "
            f"panorama at {np.round(T_base_pano.t, 3).tolist()} in {robot.base_frame}"
        )

    # ------------------------------------------------------------------------------------------------
    def _make_ptz_node(self, raw: dict[str, Any], mount: MountConfig, kwargs: dict[str, Any]) -> PtzNode:
        """The PTZ node over the virtual head: its camera model (square-pixel zoom model, no head offsets) and
        mount (the panorama origin) are handed over directly; the rest through its ordinary parameters."""
        p = self._live.params
        forced = {
            "image_width": self.width,
            "image_height": self.height,
            "follow_video_params": False,  # video/params of another camera must not resize this view
            "base_frame": "",  # the mount's parent: the robot base frame
            **{s.name: str(p[s.name]) for s in _FRAME_PARAMS},
        }
        overrides = [o for o in (kwargs.get("parameter_overrides") or []) if o.name not in forced]
        overrides += [Parameter(k, value=v) for k, v in forced.items()]
        ptz_kwargs = {**kwargs, "parameter_overrides": overrides}
        ptz = PtzNode(
            backend=self.backend,
            model=camera_model_from_dict(raw),
            mount=mount,
            node_name=str(p["ptz_node_name"]),
            **ptz_kwargs,
        )
        ptz.live_params.add_validator(self._refuse_ptz_resize)
        return ptz

    @staticmethod
    def _refuse_ptz_resize(_candidate: Params, names: frozenset[str]) -> str | None:
        """A rule of the PTZ node's parameters in this process: its view size is the render's."""
        for name in _FIXED_PTZ_PARAMS:
            if name in names:
                return f"{name} is fixed by the virtual camera (its width/height parameters)"
        return None

    @property
    def live_params(self) -> LiveParams:
        """The node's parameters: ``.params`` is the snapshot in effect (what ``ros2 param get`` tells)."""
        return self._live

    # ------------------------------------------------------------------------------------------------
    @property
    def subscribers(self) -> int:
        """Subscribers of the image and camera_info topics together."""
        return int(self._image_pub.get_subscription_count() + self._info_pub.get_subscription_count())

    def _on_panorama(self, msg: CompressedImage | Image) -> None:
        self._pending = msg  # decoded by the render timer, only if someone is watching
        self.stats.panoramas_received += 1

    def _decode_pending(self) -> None:
        msg, self._pending = self._pending, None
        if msg is None:
            return
        t0 = time.perf_counter()
        if isinstance(msg, CompressedImage):
            img = decode_compressed(bytes(msg.data))
        else:
            img = decode_raw(bytes(msg.data), msg.encoding, msg.width, msg.height, msg.step)
        if img is None or img.shape[0] < 2 or img.shape[1] < 2:
            self.stats.decode_failures += 1
            fmt = msg.format if isinstance(msg, CompressedImage) else msg.encoding
            self.get_logger().warn(f"cannot decode the panorama ({fmt!r}): dropped", throttle_duration_sec=5.0)
            return
        self.stats.decode_s = time.perf_counter() - t0
        self.stats.panoramas_decoded += 1
        h, w = img.shape[:2]
        if self._renderer is None or (self._renderer.pano_height, self._renderer.pano_width) != (h, w):
            if w != 2 * h:
                self.get_logger().warn(f"panorama is {w}x{h}, not 2:1: rendering it as equirectangular anyway")
            self._renderer = VirtualCameraRenderer(w, h, self.R_pano_base)
        if self._pano is not None and self._pano.ndim != img.ndim:
            self._out = None
        self._pano = img
        self._pano_seq += 1

    def view(self) -> ViewSpec:
        """The view of the head's current pose."""
        pan, tilt, zoom, _ = self.backend.pose()
        return ViewSpec(self.width, self.height, pan, tilt, self.zoom_model.hfov(zoom))

    def _on_timer(self) -> None:
        if not self._gate.watch(self.subscribers):
            return
        self._decode_pending()
        if self._pano is None or self._renderer is None:
            return
        t_view_ns = time.time_ns()  # the image shows the pose read now: stamp it with this time, not the render's end
        view = self.view()
        key = (self._pano_seq, view)
        now = time.monotonic()
        if not self._gate.due(key, now, float(self._live.params["min_rate"])):
            return
        published = self._publish(self._pano, self._renderer, view, t_view_ns)
        self._gate.rendered(key, now if published else None)

    def _publish(self, pano: U8, renderer: VirtualCameraRenderer, view: ViewSpec, t_view_ns: int) -> bool:
        """Render, encode and publish ``view``; False when the JPEG encoding failed (nothing published)."""
        shape = (view.height, view.width, *pano.shape[2:])
        if self._out is None or self._out.shape != shape:
            self._out = np.empty(shape, np.uint8)
        t0 = time.perf_counter()
        img = renderer.render(pano, view, out=self._out)
        t1 = time.perf_counter()
        ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, int(self._live.params["jpeg_quality"])])
        t2 = time.perf_counter()
        if not ok:  # pragma: no cover - cv2 fails only on invalid images
            self.get_logger().error("JPEG encoding failed", throttle_duration_sec=5.0)
            return False
        stamp = stamp_from_ns(t_view_ns)
        msg = jpeg_image_msg(buf, self.optical_frame, stamp)
        self._info_pub.publish(camera_info_msg(view.intrinsics, self.optical_frame, stamp))
        self._image_pub.publish(msg)
        self.stats.render_s, self.stats.encode_s = t1 - t0, t2 - t1
        self.stats.frames_published += 1
        self.last_view = view
        return True


def main(args: list[str] | None = None) -> int:
    """``axis_virtual_camera``: the render node and its PTZ node in one process."""
    nodes: list[VirtualCameraNode] = []

    def render_node() -> VirtualCameraNode:
        nodes.append(VirtualCameraNode())
        return nodes[0]

    def ptz_node() -> PtzNode:
        return nodes[0].ptz

    return run_nodes([render_node, ptz_node], args if args is not None else sys.argv)


if __name__ == "__main__":
    sys.exit(main())
