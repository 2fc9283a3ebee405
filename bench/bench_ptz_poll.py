"""CPU of one state poll (``query=position``) by transport, paced at 20 Hz as in the node (cold caches).

The simulated camera runs in another process; each variant's figure is the polling thread's CPU time
(``time.thread_time``) per request, the variants interleaved so that load from elsewhere hits them alike:

* ``VapixClient`` over httpx's own transport (httpcore + h11),
* ``VapixClient`` over :class:`~axis_ptz_ros2.vapix.keepalive.KeepAliveTransport`, the full httpx path (auth flow,
  request and response objects, ``http.client``'s reply parsing),
* ``VapixClient`` over ``KeepAliveTransport``, its quick path (what the PTZ node polls with),
* a bare ``http.client`` keep-alive request (no auth, no checks).

    .venv/bin/python bench/bench_ptz_poll.py [--polls 200] [--auth none|digest]
"""

from __future__ import annotations

import argparse
import http.client
import statistics
import subprocess
import sys
import time
from collections.abc import Callable

from axis_ptz_ros2.vapix import CameraConfig, VapixClient
from axis_ptz_ros2.vapix.keepalive import KeepAliveTransport
from axis_ptz_ros2.vapix.models import PtzPosition

POSITION = "/axis-cgi/com/ptz.cgi?query=position"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--polls", type=int, default=200, help="polls per variant")
    ap.add_argument("--auth", choices=("none", "digest"), default="none", help="the simulated camera's auth")
    a = ap.parse_args()
    sim = (
        "import time\nfrom axis_ptz_ros2.sim.camera import SimulatedCamera\n"
        f"c = SimulatedCamera(port=0, auth={a.auth!r}).start()\nprint(c.port, flush=True)\ntime.sleep(3600)\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", sim], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        port = int(proc.stdout.readline())
        creds = {} if a.auth == "none" else {"username": "root", "password": "pass"}
        cfg = CameraConfig(port=port, **creds)
        full = VapixClient(cfg, transport=KeepAliveTransport())
        variants: dict[str, Callable[[], object]] = {
            "VapixClient, httpx transport": VapixClient(cfg).query_position,
            "VapixClient, KeepAlive, full path": lambda: PtzPosition.parse(full._get_text(POSITION)[1]),  # noqa: SLF001
            "VapixClient, KeepAlive, quick path": VapixClient(cfg, transport=KeepAliveTransport()).query_position,
        }
        if a.auth == "none":
            conn = http.client.HTTPConnection("127.0.0.1", port, timeout=5)

            def bare() -> bytes:
                conn.request("GET", POSITION)
                return conn.getresponse().read()

            variants["bare http.client"] = bare
        cpu: dict[str, list[float]] = {k: [] for k in variants}
        for f in variants.values():
            for _ in range(5):
                f()
        for _ in range(a.polls):
            for name, f in variants.items():
                time.sleep(0.05)
                t0 = time.thread_time()
                f()
                cpu[name].append(1000.0 * (time.thread_time() - t0))
        for name, v in cpu.items():
            print(
                f"{a.auth:6s} {name:36s} thread CPU per poll: median {statistics.median(v):.3f} ms, "
                f"mean {statistics.fmean(v):.3f} ms ({len(v)} polls at 20 Hz)"
            )
    finally:
        proc.kill()
    return 0


if __name__ == "__main__":
    sys.exit(main())
