"""Node and tool code never narrows DDS discovery: on a robot the driver must be discoverable from the
operator's machine. Only our own scripts (the demo, ``scripts/demo.py``), tests and benches set
ROS_AUTOMATIC_DISCOVERY_RANGE."""

from __future__ import annotations

from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "axis_ptz_ros2"


def test_no_package_module_sets_the_discovery_range() -> None:
    offenders = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for lineno, line in enumerate(path.read_text().splitlines(), 1):
            if "ROS_AUTOMATIC_DISCOVERY_RANGE" in line and "os.environ" in line:
                offenders.append(f"{path.relative_to(PACKAGE.parent)}:{lineno}: {line.strip()}")
    assert offenders == [], "node code must obey the environment:\n" + "\n".join(offenders)
