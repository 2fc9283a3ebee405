"""colcon/ament_python shim: metadata and console scripts live in pyproject.toml.

`colcon build --base-paths . axis_ptz_interfaces` on a real Jazzy install builds both packages; `ros2 run
axis_ptz_ros2 <executable>` finds the executables in lib/axis_ptz_ros2 (setup.cfg).
"""

from glob import glob

from setuptools import setup

PKG = "axis_ptz_ros2"

setup(
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PKG}"]),
        (f"share/{PKG}", ["package.xml"]),
        (f"share/{PKG}/config", glob("config/*.yaml") + glob("config/*.xml")),
        (f"share/{PKG}/launch", glob("launch/*.launch.py")),
        (f"share/{PKG}/urdf", glob("urdf/*.urdf") + glob("urdf/*.xacro")),
    ],
)
