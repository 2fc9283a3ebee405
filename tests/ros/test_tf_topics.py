"""axis_ptz publishes ``/tf_static`` (the mount) and ``/tf`` (the pan/tilt head) as tf2_msgs/TFMessage, without
tf2_ros, with tf2's QoS; a plain DDS subscriber receives the chain, and it equals the forward kinematics of the
shipped URDF computed by an independent library (yourdfpy) at several joint states, within 1e-6 m / 1e-6 rad.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

pytest.importorskip("rclpy")
yourdfpy = pytest.importorskip("yourdfpy", reason="scripts/bootstrap installs yourdfpy")

from builtin_interfaces.msg import Time  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from tf2_msgs.msg import TFMessage  # noqa: E402

from axis_ptz_ros2.nodes.common import STREAM_QOS, pose_msg, transform_from_msg, transform_msg  # noqa: E402
from axis_ptz_ros2.nodes.ptz_node import PtzNode  # noqa: E402
from axis_ptz_ros2.nodes.tf_publish import TF_QOS, TF_STATIC_QOS  # noqa: E402
from axis_ptz_ros2.sim.camera import SimulatedCamera  # noqa: E402
from axis_ptz_ros2.transforms import Pose, Transform  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(180)]

ROOT = Path(__file__).resolve().parents[2]
# VAPIX degrees (pan, tilt) the simulated head is put at
POSES = [(0.0, 0.0), (40.0, -20.0), (-120.0, 10.0), (170.0, -85.0), (-33.3, 5.5)]
POS_TOL_M = 1e-6
ROT_TOL_RAD = 1e-6


@pytest.fixture(scope="module")
def cam() -> Iterator[SimulatedCamera]:
    c = SimulatedCamera(port=0).start()
    try:
        yield c
    finally:
        c.stop()


def assert_same(a: np.ndarray, b: Transform, what: str) -> None:
    dt = float(np.linalg.norm(a[:3, 3] - b.t))
    angle = float(Rotation.from_matrix(a[:3, :3].T @ b.R).magnitude())
    assert dt <= POS_TOL_M, f"{what}: |dt| {dt:.3g} m"
    assert angle <= ROT_TOL_RAD, f"{what}: rotation {angle:.3g} rad"


class Inbox:
    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.items: list[Any] = []

    def __call__(self, msg: Any) -> None:
        with self.lock:
            self.items.append(msg)

    def snapshot(self) -> list[Any]:
        with self.lock:
            return list(self.items)


def stamp(msg: Any) -> int:
    return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec


def test_tf_static_qos_is_tf2s_static_broadcaster_qos() -> None:
    """tf2_ros.qos.StaticBroadcasterQoS, value for value (``TF_STATIC_QOS`` is ``LATCHED_QOS``: a change to that one
    must not change what tf2's listeners match)."""
    q = TF_STATIC_QOS
    assert (q.history, q.depth, q.reliability, q.durability) == (
        HistoryPolicy.KEEP_LAST,
        1,
        ReliabilityPolicy.RELIABLE,
        DurabilityPolicy.TRANSIENT_LOCAL,
    )


def test_tf_and_tf_static_match_the_urdf(ros: Any, cam: SimulatedCamera) -> None:
    overrides = [
        Parameter("port", value=cam.port),
        Parameter("camera_model", value=str(ROOT / "config" / "axis214.yaml")),
        Parameter("mount_file", value=str(ROOT / "config" / "mount.yaml")),
    ]
    node = ros.add(PtzNode(context=ros.context, parameter_overrides=overrides))
    ros.wait_for(lambda: node.poller.latest is not None, 10.0)
    robot = yourdfpy.URDF.load(str(ROOT / "axis_ptz_ros2" / "urdf" / "axis_214.urdf"), load_meshes=False,
                               build_collision_scene_graph=False)  # fmt: skip

    # a late joiner (created after the node published the mount) still gets /tf_static: transient local
    probe = ros.probe()
    static, dynamic, joints = Inbox(), Inbox(), Inbox()
    probe.create_subscription(TFMessage, "/tf_static", static, TF_STATIC_QOS)
    probe.create_subscription(TFMessage, "/tf", dynamic, TF_QOS)
    probe.create_subscription(JointState, "joint_states", joints, STREAM_QOS)
    ros.wait_for(lambda: static.snapshot(), 10.0)
    (mount,) = static.snapshot()[-1].transforms
    assert (mount.header.frame_id, mount.child_frame_id) == ("base_link", "axis_ptz_base")
    assert_same(robot.get_transform("axis_ptz_base", "base_link"), transform_from_msg(mount), "mount")

    # the QoS tf2's broadcasters use
    (info_static,) = probe.get_publishers_info_by_topic("/tf_static")
    assert info_static.qos_profile.reliability == ReliabilityPolicy.RELIABLE
    assert info_static.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
    (info_tf,) = probe.get_publishers_info_by_topic("/tf")
    assert info_tf.qos_profile.reliability == ReliabilityPolicy.RELIABLE
    assert info_tf.qos_profile.durability == DurabilityPolicy.VOLATILE

    checked = 0
    for pan, tilt in POSES:
        cam.teleport(pan, tilt, 1)
        n0 = len(joints.snapshot())

        def pair(n0: int = n0) -> tuple[JointState, Any] | None:
            """A joint state after the teleport and the /tf message of the same sample (same stamp)."""
            tfs = {stamp(t): t for m in dynamic.snapshot() for t in m.transforms}
            for js in reversed(joints.snapshot()[n0 + 1 :]):
                if stamp(js) in tfs:
                    return js, tfs[stamp(js)]
            return None

        js, tf = ros.wait_for(pair, 10.0)
        assert (tf.header.frame_id, tf.child_frame_id) == ("axis_ptz_base", "axis_ptz_optical_frame")
        pan_r, tilt_r = js.position
        assert abs(pan_r) + abs(tilt_r) > 0 or (pan, tilt) == (0.0, 0.0)
        robot.update_cfg({"axis_ptz_pan_joint": pan_r, "axis_ptz_tilt_joint": tilt_r})
        T_tf = transform_from_msg(tf)
        where = f"pan {pan}, tilt {tilt} (VAPIX deg)"
        assert_same(robot.get_transform("axis_ptz_optical_frame", "axis_ptz_base"), T_tf, f"/tf, {where}")
        # and the whole chain a tf2 listener composes: /tf_static then /tf
        assert_same(
            robot.get_transform("axis_ptz_optical_frame", "base_link"),
            transform_from_msg(mount) @ T_tf,
            f"base_link -> optical, {where}",
        )
        checked += 1
    assert checked == len(POSES)


def test_publish_tf_false_publishes_neither(ros: Any, cam: SimulatedCamera) -> None:
    overrides = [Parameter("port", value=cam.port), Parameter("publish_tf", value=False)]
    node = ros.add(PtzNode(context=ros.context, parameter_overrides=overrides))
    ros.wait_for(lambda: node.poller.latest is not None, 10.0)
    probe = ros.probe()
    assert probe.get_publishers_info_by_topic("/tf") == []
    assert probe.get_publishers_info_by_topic("/tf_static") == []


def test_transform_and_pose_messages_are_one_conversion() -> None:
    """``transform_msg`` (matrices) and ``pose_msg`` (the 20 Hz path's plain floats) build the same message, and
    ``transform_from_msg`` inverts it, for rotations all over SO(3) (scipy's, an independent implementation)."""
    rng = np.random.default_rng(7)
    stamp = Time(sec=3, nanosec=4)
    for R in Rotation.random(50, random_state=rng):
        T = Transform(R.as_matrix(), rng.uniform(-2.0, 2.0, 3))
        a = transform_msg(T, "base_link", "child", stamp)
        b = pose_msg(Pose.from_transform(T), "base_link", "child", stamp)
        assert (a.header.frame_id, a.child_frame_id, a.header.stamp) == ("base_link", "child", stamp)
        assert a == b
        q = a.transform.rotation
        assert abs(abs(np.dot([q.x, q.y, q.z, q.w], R.as_quat())) - 1.0) < 1e-12  # scipy: (x, y, z, w)
        back = transform_from_msg(a)
        assert np.allclose(back.R, T.R, atol=1e-12)
        assert np.allclose(back.t, T.t, atol=1e-12)
