"""The baseline for bench_stream.py: httpx stream -> split multipart -> publish CompressedImage (no camera_info,
no recovery, no laziness). ``python bench/minimal_pipeline.py --port P [--fps 30] [--resolution 704x576]``."""

import argparse
import os
import time

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
import httpx  # noqa: E402
import rclpy  # noqa: E402
from sensor_msgs.msg import CompressedImage  # noqa: E402

from axis_ptz_ros2.nodes.common import STREAM_QOS  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("--port", type=int, required=True)
ap.add_argument("--fps", type=int, default=30)  # 0 = omit fps= (the camera's default)
ap.add_argument("--resolution", default="704x576")
ap.add_argument("--compression", type=int, default=30)
ap.add_argument("--topic", default="/minimal/image_raw/compressed")
a = ap.parse_args()
rclpy.init()
node = rclpy.create_node("minimal_pipeline")
pub = node.create_publisher(CompressedImage, a.topic, STREAM_QOS)
query = f"resolution={a.resolution}&compression={a.compression}" + (f"&fps={a.fps}" if a.fps else "")
url = f"http://127.0.0.1:{a.port}/axis-cgi/mjpg/video.cgi?{query}"
try:
    with httpx.stream("GET", url, timeout=10.0) as r:
        buf = b""
        for chunk in r.iter_raw():
            buf += chunk
            while True:
                start = buf.find(b"--myboundary")
                end_hdr = buf.find(b"\r\n\r\n", start)
                if start < 0 or end_hdr < 0:
                    break
                length = int(buf[start:end_hdr].lower().split(b"content-length:")[1].split(b"\r\n")[0])
                if len(buf) < end_hdr + 4 + length:
                    break
                t = time.time_ns()
                msg = CompressedImage(format="jpeg", data=buf[end_hdr + 4 : end_hdr + 4 + length])
                msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t, 1_000_000_000)
                pub.publish(msg)
                buf = buf[end_hdr + 4 + length :]
except KeyboardInterrupt:
    pass
