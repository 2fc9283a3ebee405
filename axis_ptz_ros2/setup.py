"""ament_python build of the ``axis_ptz_ros2`` ROS package (what ``colcon build`` runs in this folder).

The repository's top-level ``pyproject.toml`` is the one place that names the console scripts, the version and the
package data; this file reads it so a colcon build and the PyPI bootstrap (``pip install -e .`` at the top) install
the same executables. ``setup.cfg`` puts them in ``lib/axis_ptz_ros2`` where ``ros2 run`` looks; the launch files,
URDF and ``config/`` (a link to the top-level ``config/``) go to ``share/axis_ptz_ros2`` where ``ros2 launch`` and
``FindPackageShare`` look.
Runtime dependencies come from ``package.xml`` through rosdep, not from here.
"""

import tomllib
from glob import glob
from pathlib import Path

from setuptools import find_packages, setup

PKG = "axis_ptz_ros2"
HERE = Path(__file__).resolve().parent
PYPROJECT = tomllib.loads((HERE.parent / "pyproject.toml").read_text(encoding="utf-8"))
PROJECT = PYPROJECT["project"]
PACKAGE_DATA = PYPROJECT["tool"]["setuptools"]["package-data"]


def _rel(pattern: str) -> list[str]:
    """Files matching ``pattern`` (relative to this folder), as the relative paths setuptools wants."""
    return sorted(glob(pattern, root_dir=HERE))


setup(
    name=PROJECT["name"],
    version=PROJECT["version"],
    description=PROJECT["description"],
    license=PROJECT["license"]["text"],
    packages=find_packages(where=".", include=[PKG, f"{PKG}.*"]),
    package_data=PACKAGE_DATA,
    zip_safe=False,
    entry_points={"console_scripts": [f"{k} = {v}" for k, v in PROJECT["scripts"].items()]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PKG}"]),
        (f"share/{PKG}", ["package.xml"]),
        (f"share/{PKG}/config", _rel("config/*.yaml") + _rel("config/*.xml")),
        (f"share/{PKG}/launch", _rel("launch/*.launch.py")),
        (f"share/{PKG}/urdf", _rel("urdf/*.urdf") + _rel("urdf/*.xacro")),
    ],
)
