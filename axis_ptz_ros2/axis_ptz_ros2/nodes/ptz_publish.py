"""What the PTZ node publishes about the head: ``ptz/state``, ``joint_states``, ``ptz/transform``, ``ptz/mount``
and, with ``publish_tf``, the mount on ``/tf_static`` and the pan/tilt head on ``/tf``.

Called from the state loop's thread with each sample (publishing is thread-safe in rclpy); each topic is filled
only while someone listens. ROS glue: the pose is the sample's in joint coordinates
(:class:`~axis_ptz_ros2.ptz.control.JointOffsets`), the optics and the kinematic chain are the camera model's.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

from geometry_msgs.msg import TransformStamped
from rclpy.node import Node
from sensor_msgs.msg import JointState

from axis_ptz_interfaces.msg import PtzState
from axis_ptz_ros2.config import CameraModel, MountConfig
from axis_ptz_ros2.nodes.common import LATCHED_QOS, STREAM_QOS, pose_msg, publisher, stamp_from_ns, transform_msg
from axis_ptz_ros2.nodes.tf_publish import make_tf_broadcasters
from axis_ptz_ros2.ptz.backend import PtzLimitsRos
from axis_ptz_ros2.ptz.commander import Commander
from axis_ptz_ros2.ptz.control import JointOffsets
from axis_ptz_ros2.ptz.state import StateSample
from axis_ptz_ros2.transforms import Pose


@dataclass(frozen=True, slots=True)
class PtzFrames:
    """The head's frame and joint names (with the ``frame_prefix``)."""

    base: str  #: the mount's parent (base_link)
    ptz_base: str
    optical: str
    pan_joint: str
    tilt_joint: str


class PtzStatePublisher:
    """The head's state, joints and transforms (see the module docstring)."""

    def __init__(
        self,
        node: Node,
        model: CameraModel,
        mount: MountConfig,
        offsets: JointOffsets,
        frames: PtzFrames,
        *,
        publish_tf: bool,
        cmd: Commander,
        limits: Callable[[], PtzLimitsRos],
        image_size: Callable[[], tuple[int, int]],
        drive_zoom_cap: Callable[[], float],
    ) -> None:
        """Publish the mount at once (latched); ``image_size()``: the stream size of hfov/vfov;
        ``drive_zoom_cap()``: the drive-safe zoom cap in force (NaN when drive-safe zoom is off)."""
        self._model = model
        self._mount = mount
        self._offsets = offsets
        self._frames = frames
        self._cmd = cmd
        self._limits = limits
        self._image_size = image_size
        self._drive_zoom_cap = drive_zoom_cap
        self._state_pub = publisher(node, PtzState, "ptz/state", STREAM_QOS)
        self._joint_pub = publisher(node, JointState, "joint_states", STREAM_QOS)
        self._tf_pub = publisher(node, TransformStamped, "ptz/transform", STREAM_QOS)
        self._mount_pub = publisher(node, TransformStamped, "ptz/mount", LATCHED_QOS)
        self._mount_pose = Pose.from_transform(mount.transform)
        self._tf, self._tf_static = make_tf_broadcasters(node, publish_tf)
        now = stamp_from_ns(time.time_ns())
        mount_msg = transform_msg(mount.transform, frames.base, frames.ptz_base, now)
        self._mount_pub.publish(mount_msg)
        if self._tf_static is not None:
            self._tf_static.sendTransform(mount_msg)

    def state_msg(self, sample: StateSample) -> PtzState:
        """``ptz/state`` of a sample (also the state in service answers and action feedback)."""
        r = self._offsets.from_head(sample.reading)
        w, h = self._image_size()
        intr = self._model.zoom.intrinsics(r.zoom, w, h)
        lim = self._limits()
        m = PtzState()
        m.header.stamp = stamp_from_ns(r.stamp_ns)
        m.header.frame_id = self._frames.ptz_base
        m.pan, m.tilt, m.zoom = float(r.pan), float(r.tilt), float(r.zoom)
        m.magnification = float(self._model.zoom.magnification(r.zoom))
        m.hfov, m.vfov = float(intr.hfov), float(intr.vfov)
        m.moving = bool(sample.head_moving or self._cmd.moving_expected(r))
        m.pan_min, m.pan_max, m.tilt_min, m.tilt_max = lim.pan_min, lim.pan_max, lim.tilt_min, lim.tilt_max
        m.zoom_min, m.zoom_max = lim.zoom_min, lim.zoom_max
        cap, requested = self._cmd.zoom_cap, self._cmd.requested_zoom
        m.zoom_capped = cap is not None
        m.zoom_cap = self._drive_zoom_cap()
        m.requested_zoom = float(requested) if requested is not None else math.nan
        return m

    def publish(self, sample: StateSample) -> None:
        """ptz/state, joint_states, ptz/transform and /tf (with ``publish_tf``), each only while someone listens."""
        if self._state_pub.get_subscription_count() > 0:
            self._state_pub.publish(self.state_msg(sample))
        want_joints = self._joint_pub.get_subscription_count() > 0
        want_tf = self._tf_pub.get_subscription_count() > 0
        # /tf is volatile (a listener gets what is sent after it joined), so nobody misses what is not sent
        # while nobody listens; building and publishing it anyway was a third of the idle node's CPU
        want_head = self._tf is not None and self._tf.get_subscription_count() > 0
        if not (want_joints or want_tf or want_head):
            return  # nothing built: the stamp message alone costs what the three counts cost
        r = self._offsets.from_head(sample.reading)
        stamp = stamp_from_ns(r.stamp_ns)
        frames = self._frames
        if want_joints:
            js = JointState()
            js.header.stamp = stamp
            js.name = [frames.pan_joint, frames.tilt_joint]
            js.position = [float(r.pan), float(r.tilt)]
            js.velocity = [float(sample.pan_rate), float(sample.tilt_rate)]
            self._joint_pub.publish(js)
        if want_tf or want_head:
            P_opt = self._model.head.optical_pose(r.pan, r.tilt)  # plain floats: numpy was 0.4 ms a message
            if want_tf:
                self._tf_pub.publish(pose_msg(self._mount_pose @ P_opt, frames.base, frames.optical, stamp))
            if want_head and self._tf is not None:
                self._tf.sendTransform(pose_msg(P_opt, frames.ptz_base, frames.optical, stamp))
