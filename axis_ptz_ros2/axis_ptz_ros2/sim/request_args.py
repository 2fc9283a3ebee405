"""Integer arguments of the simulated camera's requests, checked as a real Axis checks them (ROS-free).

``image.cgi``/``video.cgi`` (:mod:`axis_ptz_ros2.sim.http.vapix`) and RTSP ``media.amp``
(:mod:`axis_ptz_ros2.sim.rtsp.media`) refuse a value that is not an integer or out of range with the same
``Invalid <name>: <value>`` reason; each protocol turns the :class:`ValueError` into its own reply.
"""

from __future__ import annotations

from collections.abc import Mapping


def int_arg(args: Mapping[str, str], name: str, lo: int, hi: int, default: int) -> int:
    """``args[name]`` as an integer in ``lo…hi`` (``default`` if absent); ValueError ``Invalid <name>: <value>``."""
    if name not in args:
        return default
    raw = args[name]
    try:
        value = int(raw)
    except ValueError as err:
        raise ValueError(f"Invalid {name}: {raw}") from err
    if not lo <= value <= hi:
        raise ValueError(f"Invalid {name}: {raw}")
    return value
