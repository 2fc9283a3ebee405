"""``axis_calibrate``'s ROS side: the capture session on the running system, and the executable itself.

:class:`CaptureSession` subscribes to ``ptz/state``, ``image_raw/compressed`` and ``laser/points`` and commands
the head through ``ptz/move_absolute`` (``wait=true``); what makes a still view out of what it received is
ROS-free (:func:`~axis_ptz_ros2.calibration.capture.still_view`,
:func:`~axis_ptz_ros2.calibration.capture.cloud_in_base`), as is the rest of the tool
(:mod:`axis_ptz_ros2.calibration.cli`: ``solve``, ``synth`` and ``capture``'s arguments and run). :func:`main`
is the ``axis_calibrate`` entry point: the ROS-free command line with this session plugged in for ``capture``.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CompressedImage, PointCloud2

from axis_ptz_interfaces.msg import PtzState
from axis_ptz_interfaces.srv import MovePtz
from axis_ptz_ros2.calibration import cli
from axis_ptz_ros2.calibration.capture import (
    CapturedView,
    CaptureError,
    PoseCommand,
    cloud_in_base,
    still_view,
)
from axis_ptz_ros2.nodes.common import LATCHED_QOS, STREAM_QOS
from axis_ptz_ros2.pointcloud import decode_cloud_msg
from axis_ptz_ros2.transforms import Transform


@dataclass(frozen=True, slots=True)
class _Stamped:
    t: float  # time.monotonic() at reception
    value: Any


#: ``laser_qos`` ``best_effort``: :data:`STREAM_QOS` (the newest scan only), best effort
_BEST_EFFORT_QOS = QoSProfile(
    depth=STREAM_QOS.depth, history=STREAM_QOS.history, reliability=ReliabilityPolicy.BEST_EFFORT
)


def _laser_qos(laser_qos: str) -> QoSProfile:
    if laser_qos == "reliable":  # matches reliable publishers; gets a latched scan at once
        return LATCHED_QOS
    if laser_qos == "best_effort":  # matches every publisher (sensor-data QoS scanners)
        return _BEST_EFFORT_QOS
    raise ValueError(f"laser_qos must be 'reliable' or 'best_effort', got {laser_qos!r}")


class CaptureSession:
    """Subscriptions and the service client of the capture tool on a caller-provided rclpy ``Node``.

    The node must be spun by an executor in another thread (the blocking methods wait on data that arrives
    through the node's callbacks). ``T_base_laser`` transforms the cloud into ``base_link`` when its
    ``frame_id`` is ``laser_frame`` (a cloud already in ``base_frame`` is taken as is; any other frame is
    refused). ``pan_offset``/``tilt_offset`` (rad) are the encoder offsets the PTZ node adds (its mount file);
    they are removed so the stored pan/tilt are the head's reported position.
    """

    def __init__(
        self,
        node: Node,
        *,
        T_base_laser: Transform,
        laser_frame: str = "laser_link",
        base_frame: str = "base_link",
        pan_offset: float = 0.0,
        tilt_offset: float = 0.0,
        laser_qos: str = "reliable",
        settle_s: float = 0.3,
        timeout_s: float = 15.0,
        still_tolerance: float = 2e-4,
    ) -> None:
        self.node = node
        self.T_base_laser = T_base_laser
        self.laser_frame = laser_frame
        self.base_frame = base_frame
        self.pan_offset = pan_offset
        self.tilt_offset = tilt_offset
        self.settle_s = settle_s
        self.timeout_s = timeout_s
        self.still_tolerance = still_tolerance
        self._lock = threading.Condition()
        self._states: list[_Stamped] = []
        self._image: _Stamped | None = None
        self._cloud: _Stamped | None = None
        lq = _laser_qos(laser_qos)
        self._subs = [
            node.create_subscription(PtzState, "ptz/state", self._on_state, STREAM_QOS),
            node.create_subscription(CompressedImage, "image_raw/compressed", self._on_image, STREAM_QOS),
            node.create_subscription(PointCloud2, "laser/points", self._on_cloud, lq),
        ]
        self._move = node.create_client(MovePtz, "ptz/move_absolute")

    # ---- callbacks (executor thread) ---------------------------------------------------------------
    def _on_state(self, msg: PtzState) -> None:
        with self._lock:
            self._states.append(_Stamped(time.monotonic(), msg))
            if len(self._states) > 400:
                del self._states[:200]
            self._lock.notify_all()

    def _on_image(self, msg: CompressedImage) -> None:
        with self._lock:
            self._image = _Stamped(time.monotonic(), bytes(msg.data))
            self._lock.notify_all()

    def _on_cloud(self, msg: PointCloud2) -> None:
        with self._lock:
            self._cloud = _Stamped(time.monotonic(), msg)
            self._lock.notify_all()

    # ---- blocking API (caller thread) --------------------------------------------------------------
    def _wait(self, what: str, pred: Callable[[], Any], timeout: float | None = None) -> Any:
        deadline = time.monotonic() + (self.timeout_s if timeout is None else timeout)
        with self._lock:
            while True:
                v = pred()
                if v:
                    return v
                left = deadline - time.monotonic()
                if left <= 0:
                    raise CaptureError(f"timed out after {self.timeout_s:.1f} s waiting for {what}")
                self._lock.wait(min(left, 0.1))

    def wait_ready(self, timeout: float | None = None) -> None:
        """Wait until PTZ state, a camera frame and a laser scan have been received."""
        self._wait("ptz/state", lambda: bool(self._states), timeout)
        self._wait("image_raw/compressed", lambda: self._image is not None, timeout)
        self._wait("laser/points", lambda: self._cloud is not None, timeout)

    def move(self, pose: PoseCommand) -> None:
        """Command an absolute pose and wait until the PTZ node reports the head arrived."""
        if not self._move.wait_for_service(timeout_sec=self.timeout_s):
            raise CaptureError("service ptz/move_absolute is not available (is the PTZ node running?)")
        req = MovePtz.Request()
        req.command.pan = float(pose.pan + self.pan_offset)
        req.command.tilt = float(pose.tilt + self.tilt_offset)
        req.command.zoom = float(pose.zoom)
        req.command.speed = math.nan
        req.wait = True
        req.timeout_s = float(self.timeout_s)
        fut = self._move.call_async(req)
        deadline = time.monotonic() + self.timeout_s + 5.0
        while not fut.done():
            if time.monotonic() > deadline:
                raise CaptureError("ptz/move_absolute did not answer")
            time.sleep(0.01)
        resp = fut.result()
        if resp is None or not resp.success:
            msg = "no response" if resp is None else resp.message
            raise CaptureError(
                f"move to pan {math.degrees(pose.pan):.2f}°, tilt {math.degrees(pose.tilt):.2f}°, "
                f"zoom {pose.zoom:g} failed: {msg}"
            )

    def capture(self, name: str, *, fresh_cloud: bool = True) -> CapturedView:
        """Record one view at the current (still) head position."""
        t0 = time.monotonic()
        # 1. A state received from now on that says the head stands still.
        self._wait(
            "a still ptz/state",
            lambda: any(s.t >= t0 and not s.value.moving for s in self._states),
        )
        t_still = time.monotonic()
        time.sleep(self.settle_s)
        t1 = time.monotonic()
        # 2. A frame received after the settle time, and a state after that frame.
        img = self._wait("a camera frame", lambda: self._image if self._image and self._image.t >= t1 else None)
        self._wait("ptz/state after the frame", lambda: any(s.t > img.t for s in self._states))
        # 3. A laser scan (received after the head stopped, unless fresh_cloud is False).
        t_cloud = t_still if fresh_cloud else -math.inf
        cloud_msg = self._wait(
            "laser/points", lambda: self._cloud if self._cloud and self._cloud.t >= t_cloud else None
        )
        with self._lock:
            window: Sequence[PtzState] = [s.value for s in self._states if t_still <= s.t]
        msg = cloud_msg.value
        cloud = cloud_in_base(
            decode_cloud_msg(msg),
            str(msg.header.frame_id),
            base_frame=self.base_frame,
            laser_frame=self.laser_frame,
            T_base_laser=self.T_base_laser,
        )
        return still_view(
            name,
            window,
            img.value,
            cloud,
            pan_offset=self.pan_offset,
            tilt_offset=self.tilt_offset,
            still_tolerance=self.still_tolerance,
            timings={"still": t_still - t0, "total": time.monotonic() - t0},
        )

    def close(self) -> None:
        """Destroy the subscriptions and the client (the node stays)."""
        for s in self._subs:
            self.node.destroy_subscription(s)
        self.node.destroy_client(self._move)


class RosCapture:
    """A private rclpy context, node and executor thread for a :class:`CaptureSession` (CLI use).

    DDS discovery follows the environment like every ROS 2 node (it must reach the robot's driver).
    """

    def __init__(self, namespace: str = "", **session_kwargs: Any) -> None:
        self.context = Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node("axis_calibrate_capture", namespace=namespace, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, name="axis_calibrate_spin", daemon=True)
        self._thread.start()
        try:
            self.session = CaptureSession(self.node, **session_kwargs)
        except BaseException:
            self.close()
            raise

    def _spin(self) -> None:
        while self.context.ok():
            try:
                self.executor.spin_once(timeout_sec=0.05)
            except Exception:  # noqa: BLE001 - the context was shut down under us while closing
                if not self.context.ok():
                    return
                raise

    def close(self) -> None:
        """Stop the executor and shut the context down."""
        session = getattr(self, "session", None)
        if session is not None:
            session.close()
        self.executor.shutdown(timeout_sec=2.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self._thread.join(timeout=2.0)

    def __enter__(self) -> RosCapture:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@contextmanager
def open_capture(namespace: str = "", **session_kwargs: Any) -> Iterator[CaptureSession]:
    """A :class:`CaptureSession` on a private context and node (``axis_calibrate capture``), closed after."""
    with RosCapture(namespace, **session_kwargs) as ros:
        yield ros.session


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``axis_calibrate`` console script (``capture`` on the running ROS system)."""
    return cli.main(argv, open_capture=open_capture)


if __name__ == "__main__":
    raise SystemExit(main())
