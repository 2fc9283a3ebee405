"""The baseline for bench_stream.py: httpx stream -> split multipart -> publish CompressedImage + CameraInfo.

The same messages per frame as ``axis_stream`` (the image and a restamped, precomputed ``camera_info``) with
none of its work around them (no recovery, no watchdog, no budget, no diagnostics).

``--skip-unsubscribed``: like ``axis_stream`` with no subscriber, read every frame but publish only on topics
somebody subscribes to (subscriber counts refreshed at most every 0.5 s, as the node caches them); without
it every frame is published whether or not anyone listens.

``python bench/minimal_pipeline.py --port P [--fps 30] [--resolution 704x576] [--skip-unsubscribed]``
"""

import argparse
import os
import time

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
import httpx  # noqa: E402
import rclpy  # noqa: E402
from sensor_msgs.msg import CameraInfo, CompressedImage  # noqa: E402

from axis_ptz_ros2.nodes.common import STREAM_QOS  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("--port", type=int, required=True)
ap.add_argument("--fps", type=int, default=30)  # 0 = omit fps= (the camera's default)
ap.add_argument("--resolution", default="704x576")
ap.add_argument("--compression", type=int, default=30)
ap.add_argument("--ns", default="/minimal")
ap.add_argument("--skip-unsubscribed", action="store_true")
a = ap.parse_args()
rclpy.init()
node = rclpy.create_node("minimal_pipeline")
pub = node.create_publisher(CompressedImage, f"{a.ns}/image_raw/compressed", STREAM_QOS)
info_pub = node.create_publisher(CameraInfo, f"{a.ns}/camera_info", STREAM_QOS)
w, h = (int(v) for v in a.resolution.split("x"))
info = CameraInfo(width=w, height=h, distortion_model="plumb_bob")  # fixed intrinsics, restamped per frame
info.header.frame_id = "axis_ptz_optical_frame"
fx = w / 2.0
info.k = [fx, 0.0, w / 2.0, 0.0, fx, h / 2.0, 0.0, 0.0, 1.0]
info.p = [fx, 0.0, w / 2.0, 0.0, 0.0, fx, h / 2.0, 0.0, 0.0, 0.0, 1.0, 0.0]
query = f"resolution={a.resolution}&compression={a.compression}" + (f"&fps={a.fps}" if a.fps else "")
url = f"http://127.0.0.1:{a.port}/axis-cgi/mjpg/video.cgi?{query}"
want_image = want_info = True
checked = 0.0
try:
    with httpx.stream("GET", url, timeout=10.0, trust_env=False) as r:
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
                if a.skip_unsubscribed and time.monotonic() - checked >= 0.5:
                    checked = time.monotonic()
                    want_image = pub.get_subscription_count() > 0
                    want_info = info_pub.get_subscription_count() > 0
                if want_image:
                    msg = CompressedImage(format="jpeg", data=buf[end_hdr + 4 : end_hdr + 4 + length])
                    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t, 1_000_000_000)
                    pub.publish(msg)
                if want_info:
                    info.header.stamp.sec, info.header.stamp.nanosec = divmod(t, 1_000_000_000)
                    info_pub.publish(info)
                buf = buf[end_hdr + 4 + length :]
except KeyboardInterrupt:
    pass
