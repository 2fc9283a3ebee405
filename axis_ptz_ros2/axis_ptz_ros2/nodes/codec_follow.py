"""ROS side of :mod:`axis_ptz_ros2.codec_follow`: feed a consumer's :class:`CodecFollower` from ``video/params``.

Used by ``axis_link_monitor``, ``axis_web_console`` and ``axis_republish`` (their ``codec``/``input`` parameter
``auto``): the stream node publishes ``video/params`` latched (reliable, transient local, depth 1,
:data:`~axis_ptz_ros2.nodes.common.LATCHED_QOS`), so a consumer started after it hears the codec in effect at once
and every later change as it happens.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node

from axis_ptz_interfaces.msg import VideoParams
from axis_ptz_ros2.codec_follow import CodecFollower
from axis_ptz_ros2.nodes.common import LATCHED_QOS


def follow_stream_codec(
    node: Node,
    choice: str,
    on_change: Callable[[str], None],
    callback_group: Any = None,  # noqa: ANN401 - an rclpy callback group
    topic: str = "video/params",
) -> CodecFollower:
    """A :class:`CodecFollower` for ``choice`` (ValueError if it is none). In ``auto`` it subscribes to ``topic``
    and calls ``on_change(codec)`` (on the executor) each time the codec to watch changes (``""``: none); until
    the first announcement it logs once what it waits for. With an explicit choice it subscribes to nothing."""
    follower = CodecFollower(choice)
    if not follower.follows:
        return follower
    log = node.get_logger()
    log.info(f"codec auto: {follower.describe()} ({node.resolve_topic_name(topic)})")
    told = {"problem": ""}

    def on_params(msg: VideoParams) -> None:
        changed = follower.announce(str(msg.codec))
        if follower.problem and follower.problem != told["problem"]:
            log.warning(f"codec auto: {follower.describe()}")
        told["problem"] = follower.problem
        if changed:
            if follower.codec:
                log.info(f"codec auto: {follower.describe()}")
            on_change(follower.codec)

    node.create_subscription(VideoParams, topic, on_params, LATCHED_QOS, callback_group=callback_group)
    return follower


def no_events() -> SubscriptionEventCallbacks:
    """Event callbacks for a video subscription a consumer drops when the codec changes: none. rclpy's default
    QoS-event handler is a waitable of its own, and destroying it while another executor thread builds the wait
    set crashes the executor (``InvalidHandle``; the console's note in :mod:`~axis_ptz_ros2.nodes.web_streams`)."""
    return SubscriptionEventCallbacks(use_default_callbacks=False)
