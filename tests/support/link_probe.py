"""A measuring subscriber for the two-host test tier and ``bench/bench_link.py`` (test tooling, not shipped).

``python -m tests.support.link_probe`` (from the repository root) prints one JSON line per message received,
flushed at once, so the parent process (in another network namespace) sees arrivals live:

- ``{"t": "image", "rx": <time_ns at receipt>, "stamp": <header stamp ns>, "seq": <sim seq>, "sim": <sim send
  time_ns>, "bytes": <JPEG size>, "w": <width>, "h": <height>}`` (``seq``/``sim`` from the simulated camera's
  JPEG comment; both namespaces share one clock, so ``rx - sim`` is the frame's age at the operator)
- ``{"t": "ptz/state", "rx": ..., "stamp": ..., "pan": ..., "tilt": ..., "zoom": ...}``
- ``{"t": "joint_states", "rx": ..., "names": [...]}``
- ``{"t": "video/params", "rx": ..., "fps": ..., "resolution": ..., "compression": ..., "source": ...}``

It reports what it receives on ``video/feedback`` like any operator-side viewer (``--no-feedback``: not).

Commands arrive as JSON lines on stdin: ``{"cmd": "relative" | "absolute", "pan": <rad>, "tilt": <rad>,
"zoom": <units>, "id": <n>}`` publishes ``ptz/cmd/relative`` / ``ptz/cmd/absolute`` (absolute: a missing axis
is kept) and prints ``{"t": "sent", "id": n, "tx": <time_ns>}``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import threading
import time
from typing import Any

import rclpy
from rclpy.node import Node
from sensor_msgs.msg import CompressedImage, JointState

from axis_ptz_interfaces.msg import PtzCommand, PtzState, VideoParams
from axis_ptz_ros2.nodes.common import COMMAND_QOS, LATCHED_QOS, STREAM_QOS, publisher
from axis_ptz_ros2.nodes.link_monitor import FeedbackPublisher
from axis_ptz_ros2.streaming import jpeg_size
from tests.support.spin import spin_until_stopped
from tests.support.stamps import sim_stamp

_lock = threading.Lock()


def _emit(record: dict[str, Any]) -> None:
    line = json.dumps(record, separators=(",", ":"))
    with _lock:
        sys.stdout.write(line + "\n")
        sys.stdout.flush()


def _ns(stamp: Any) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


class LinkProbe(Node):
    """Subscribes to what an operator station uses and reports every arrival."""

    def __init__(self, topics: set[str], image_qos: str, feedback: bool = True) -> None:
        super().__init__("link_probe")
        qos = STREAM_QOS
        if image_qos == "best_effort":
            from rclpy.qos import qos_profile_sensor_data

            qos = qos_profile_sensor_data
        if "image" in topics:
            self.create_subscription(CompressedImage, "image_raw/compressed", self._on_image, qos)
        if "ptz/state" in topics:
            self.create_subscription(PtzState, "ptz/state", self._on_state, STREAM_QOS)
        if "joint_states" in topics:
            self.create_subscription(JointState, "joint_states", self._on_joints, STREAM_QOS)
        if "video/params" in topics:
            self.create_subscription(VideoParams, "video/params", self._on_params, LATCHED_QOS)
        self._rel = publisher(self, PtzCommand, "ptz/cmd/relative", COMMAND_QOS)
        self._abs = publisher(self, PtzCommand, "ptz/cmd/absolute", COMMAND_QOS)
        # the operator's viewer reports what it receives, as the web console does (video/feedback)
        self.feedback = FeedbackPublisher(self) if feedback and "image" in topics else None
        if self.feedback is not None:
            self.feedback.watch()

    def _on_image(self, msg: CompressedImage) -> None:
        rx = time.time_ns()
        data = bytes(msg.data)
        if self.feedback is not None:
            self.feedback.add(msg, len(data))
        st = sim_stamp(data)
        size = jpeg_size(data) or (0, 0)
        _emit(
            {
                "t": "image",
                "rx": rx,
                "stamp": _ns(msg.header.stamp),
                "seq": st[0] if st else -1,
                "sim": st[1] if st else 0,
                "bytes": len(data),
                "w": size[0],
                "h": size[1],
            }
        )

    def _on_state(self, msg: PtzState) -> None:
        rx = time.time_ns()
        _emit(
            {
                "t": "ptz/state",
                "rx": rx,
                "stamp": _ns(msg.header.stamp),
                "pan": msg.pan,
                "tilt": msg.tilt,
                "zoom": msg.zoom,
            }
        )

    def _on_joints(self, msg: JointState) -> None:
        _emit({"t": "joint_states", "rx": time.time_ns(), "names": list(msg.name)})

    def _on_params(self, msg: VideoParams) -> None:
        _emit(
            {
                "t": "video/params",
                "rx": time.time_ns(),
                "stamp": _ns(msg.header.stamp),  # when the stream node switched (its clock)
                "fps": msg.fps,
                "resolution": msg.resolution,
                "compression": msg.compression,
                "budget": msg.max_bitrate_kbps,
                "source": msg.source,
            }
        )

    def send_command(self, cmd: dict[str, Any]) -> None:
        """Publish a relative or absolute PTZ command (absolute: NaN keeps an axis)."""
        keep = 0.0 if cmd["cmd"] == "relative" else math.nan
        msg = PtzCommand()
        msg.pan = float(cmd.get("pan", keep))
        msg.tilt = float(cmd.get("tilt", keep))
        msg.zoom = float(cmd.get("zoom", keep))
        msg.speed = math.nan
        tx = time.time_ns()
        (self._rel if cmd["cmd"] == "relative" else self._abs).publish(msg)
        _emit({"t": "sent", "id": cmd.get("id", 0), "tx": tx})


def _read_commands(node: LinkProbe) -> None:
    for line in sys.stdin:
        line = line.strip()
        if not line:
            continue
        try:
            cmd = json.loads(line)
        except ValueError:
            _emit({"t": "error", "what": f"bad command line {line[:80]!r}"})
            continue
        if cmd.get("cmd") in ("relative", "absolute"):
            node.send_command(cmd)


def main(argv: list[str] | None = None) -> int:
    """Run until stdin closes (or Ctrl-C / SIGTERM)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--topics", default="image,ptz/state,joint_states,video/params")
    ap.add_argument("--image-qos", choices=("reliable", "best_effort"), default="reliable")
    ap.add_argument("--no-feedback", action="store_true", help="do not publish video/feedback")
    args, ros_args = ap.parse_known_args(argv)
    rclpy.init(args=["link_probe", *ros_args])
    node = LinkProbe(set(args.topics.split(",")), args.image_qos, feedback=not args.no_feedback)
    threading.Thread(target=_read_commands, args=(node,), daemon=True).start()
    _emit({"t": "ready", "rx": time.time_ns()})
    spin_until_stopped(node)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
