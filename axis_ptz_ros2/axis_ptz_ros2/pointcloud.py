"""Decoding ``sensor_msgs/PointCloud2`` payloads into numpy (ROS-free: messages are duck-typed).

One decoder for every consumer of the laser cloud (web console click depth, visualizer, calibration capture):
any numeric x/y/z(/intensity) field types, either endianness, padded rows; points with a non-finite
coordinate are dropped.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from axis_ptz_ros2.transforms import FloatArray

#: sensor_msgs/PointField datatypes → numpy type characters
_PF_TYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}


@dataclass(frozen=True, slots=True)
class CloudField:
    """One ``sensor_msgs/PointField``: name, byte offset, datatype code (7 = FLOAT32, 8 = FLOAT64)."""

    name: str
    offset: int
    datatype: int


def decode_cloud(
    data: bytes, fields: Sequence[CloudField], point_step: int, n_points: int, is_bigendian: bool = False
) -> FloatArray:
    """(N, 4) float64 x, y, z, intensity (NaN if the cloud has no ``intensity``) of a PointCloud2 payload;
    points with a non-finite coordinate are dropped."""
    by_name = {f.name: f for f in fields}
    for req in ("x", "y", "z"):
        if req not in by_name:
            raise ValueError(f"point cloud has no {req!r} field (fields: {sorted(by_name)})")
    if point_step <= 0 or len(data) < point_step * n_points:
        raise ValueError(f"point cloud payload of {len(data)} bytes is too short for {n_points}×{point_step}")
    endian = ">" if is_bigendian else "<"
    names, formats, offsets = [], [], []
    for name in ("x", "y", "z", "intensity"):
        f = by_name.get(name)
        if f is None:
            continue
        if f.datatype not in _PF_TYPES:
            raise ValueError(f"point cloud field {name!r} has unsupported datatype {f.datatype}")
        names.append(name)
        formats.append(endian + _PF_TYPES[f.datatype])
        offsets.append(f.offset)
    dt = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": point_step})
    rec = np.frombuffer(data, dtype=dt, count=n_points)
    out = np.full((n_points, 4), np.nan)
    for k, name in enumerate(("x", "y", "z", "intensity")):
        if name in names:
            out[:, k] = rec[name].astype(np.float64)
    ok = np.isfinite(out[:, :3]).all(axis=1)
    return np.asarray(out[ok], dtype=np.float64)


def decode_cloud_msg(msg: Any) -> FloatArray:
    """:func:`decode_cloud` of a ``sensor_msgs/PointCloud2`` message (rows padded beyond
    ``width·point_step`` are unpadded first)."""
    width, height, step = int(msg.width), int(msg.height), int(msg.point_step)
    n = width * height
    if n == 0:
        return np.zeros((0, 4))
    data = bytes(msg.data)
    row, row_step = width * step, int(msg.row_step)
    if height > 1 and row_step > row:  # padded rows: keep each row's points only
        data = b"".join(data[r * row_step : r * row_step + row] for r in range(height))
    fields = [CloudField(str(f.name), int(f.offset), int(f.datatype)) for f in msg.fields]
    return decode_cloud(data, fields, step, n, bool(msg.is_bigendian))
