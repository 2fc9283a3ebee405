"""``/tf`` and ``/tf_static`` (``tf2_msgs/TFMessage``) as tf2's broadcasters publish them, without ``tf2_ros``.

A PyPI install of rclpy has no ``tf2_ros``; ``tf2_msgs`` is built by ``scripts/bootstrap`` like our other
interfaces. The QoS is the one ``tf2_ros`` uses, so ``tf2`` listeners, rviz and ``robot_state_publisher``'s
consumers match:

* ``/tf``: reliable, volatile, keep last 100 (``tf2_ros.TransformBroadcaster``'s default);
* ``/tf_static``: reliable, transient local, keep last 1 (``tf2_ros.StaticTransformBroadcaster``): every
  static transform sent so far goes out again in one message, so a late joiner gets the whole set.

Both go through :func:`~axis_ptz_ros2.nodes.common.publisher`, so their QoS can be overridden like every other
publisher (``qos_overrides./tf.publisher.depth`` …).
"""

from __future__ import annotations

from collections.abc import Iterable

from geometry_msgs.msg import TransformStamped
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from tf2_msgs.msg import TFMessage

from axis_ptz_ros2.nodes.common import LATCHED_QOS, publisher, transform_msg
from axis_ptz_ros2.transforms import Transform

#: tf2_ros.TransformBroadcaster's QoS.
TF_QOS = QoSProfile(depth=100, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE)
#: tf2_ros.StaticTransformBroadcaster's QoS (tf2_ros.qos.StaticBroadcasterQoS: reliable, transient local, keep
#: last 1) is our latched QoS, value for value (tests/ros/test_tf_topics.py pins tf2's values).
TF_STATIC_QOS = LATCHED_QOS


def _as_list(transforms: TransformStamped | Iterable[TransformStamped]) -> list[TransformStamped]:
    return [transforms] if isinstance(transforms, TransformStamped) else list(transforms)


class TfBroadcaster:
    """Dynamic transforms on ``/tf`` (``sendTransform`` as ``tf2_ros.TransformBroadcaster``)."""

    def __init__(self, node: Node, topic: str = "/tf") -> None:
        """A ``TFMessage`` publisher on ``topic`` with tf2's QoS (overridable)."""
        self._pub = publisher(node, TFMessage, topic, TF_QOS)

    def sendTransform(self, transforms: TransformStamped | Iterable[TransformStamped]) -> None:  # noqa: N802
        """Publish one or several transforms in one message."""
        self._pub.publish(TFMessage(transforms=_as_list(transforms)))

    def get_subscription_count(self) -> int:
        """Subscriptions matched with ``/tf`` now (``/tf`` is volatile: a listener that joins later gets only
        what is sent after it joined, so a sender may skip the work while this is 0)."""
        return self._pub.get_subscription_count()


class StaticTfBroadcaster:
    """Static transforms on ``/tf_static``, latched (``sendTransform`` as ``tf2_ros.StaticTransformBroadcaster``:
    a transform replaces the one with the same child frame; every message carries all of them)."""

    def __init__(self, node: Node, topic: str = "/tf_static") -> None:
        """A latched ``TFMessage`` publisher on ``topic`` with tf2's static QoS (overridable)."""
        self._pub = publisher(node, TFMessage, topic, TF_STATIC_QOS)
        self._by_child: dict[str, TransformStamped] = {}

    def sendTransform(self, transforms: TransformStamped | Iterable[TransformStamped]) -> None:  # noqa: N802
        """Add or replace the transforms (by child frame) and publish the whole set."""
        for t in _as_list(transforms):
            self._by_child[t.child_frame_id] = t
        self._pub.publish(TFMessage(transforms=list(self._by_child.values())))


def make_tf_broadcasters(node: Node, enabled: bool = True) -> tuple[TfBroadcaster | None, StaticTfBroadcaster | None]:
    """(``/tf`` broadcaster, ``/tf_static`` broadcaster) of ``node``; (None, None) when not ``enabled``."""
    if not enabled:
        return None, None
    return TfBroadcaster(node), StaticTfBroadcaster(node)


def publish_fixed_transform(node: Node, T_parent_child: Transform, parent: str, child: str, topic: str) -> Publisher:
    """A fixed pose, sent once at start-up: latched as ``geometry_msgs/TransformStamped`` on ``topic`` and on
    ``/tf_static`` (a :class:`StaticTfBroadcaster` of ``node``), stamped now. Returns the ``topic`` publisher."""
    pub = publisher(node, TransformStamped, topic, LATCHED_QOS)
    msg = transform_msg(T_parent_child, parent, child, node.get_clock().now().to_msg())
    pub.publish(msg)
    StaticTfBroadcaster(node).sendTransform(msg)
    return pub
