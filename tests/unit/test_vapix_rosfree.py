"""axis_ptz_ros2.vapix must import without ROS (style.md item 1)."""

import subprocess
import sys

import pytest

pytestmark = pytest.mark.unit

PROBE = """
import sys
class _Blocker:
    def find_spec(self, name, path=None, target=None):
        root = name.split(".")[0]
        if root in {"rclpy", "sensor_msgs", "std_msgs", "axis_ptz_interfaces", "rosidl_runtime_py"}:
            raise ImportError(f"ROS module {name} imported by the ROS-free layer")
        return None
sys.meta_path.insert(0, _Blocker())
sys.modules["rclpy"] = None  # blocked: any 'import rclpy' raises ImportError
import axis_ptz_ros2.vapix as v
import axis_ptz_ros2.vapix.client, axis_ptz_ros2.vapix.mjpeg, axis_ptz_ros2.vapix.auth
assert v.VapixClient and v.MjpegParser
ros = {"sensor_msgs", "std_msgs", "axis_ptz_interfaces"}
loaded = sorted(m for m in sys.modules if m.split(".")[0] in ros)
assert not loaded, loaded
print("ok")
"""


def test_vapix_imports_with_rclpy_blocked():
    # A fresh interpreter, so modules already imported by other tests cannot hide a ROS import.
    result = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "ok"
