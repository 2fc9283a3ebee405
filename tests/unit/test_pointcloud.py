"""PointCloud2 payload decoding (one decoder for the web console, visualizer and calibration capture)."""

from types import SimpleNamespace

import numpy as np
import pytest

from axis_ptz_ros2.pointcloud import CloudField, decode_cloud_msg

pytestmark = pytest.mark.unit


def _msg(points, *, width, height, row_pad=0, big=False, fields=("x", "y", "z")):
    dt = (">" if big else "<") + "f4"
    rows = []
    pts = np.asarray(points, dtype=dt).reshape(height, width, len(fields))
    for r in range(height):
        rows.append(pts[r].tobytes() + b"\xee" * row_pad)  # padding bytes that must never be read as points
    step = 4 * len(fields)
    return SimpleNamespace(
        width=width,
        height=height,
        point_step=step,
        row_step=width * step + row_pad,
        is_bigendian=big,
        data=b"".join(rows),
        fields=[SimpleNamespace(name=n, offset=4 * i, datatype=7) for i, n in enumerate(fields)],
    )


def test_padded_rows_big_endian_and_missing_intensity():
    pts = np.arange(2 * 3 * 3, dtype=np.float64).reshape(6, 3)
    out = decode_cloud_msg(_msg(pts, width=3, height=2, row_pad=8, big=True))
    assert out.shape == (6, 4)
    assert out[:, :3] == pytest.approx(pts)
    assert np.isnan(out[:, 3]).all()  # no intensity field


def test_nan_points_dropped_intensity_kept_and_bad_clouds_refused():
    pts = np.array([[1, 2, 3, 9], [np.nan, 0, 0, 9], [4, 5, 6, 7]], dtype=np.float64)
    out = decode_cloud_msg(_msg(pts, width=3, height=1, fields=("x", "y", "z", "intensity")))
    assert out == pytest.approx(np.array([[1, 2, 3, 9], [4, 5, 6, 7]], dtype=np.float64))
    assert decode_cloud_msg(_msg(np.zeros((0, 3)), width=0, height=1)).shape == (0, 4)
    with pytest.raises(ValueError, match="no 'z' field"):
        decode_cloud_msg(_msg(np.zeros((2, 2)), width=2, height=1, fields=("x", "y")))
    assert CloudField("x", 0, 7).datatype == 7
