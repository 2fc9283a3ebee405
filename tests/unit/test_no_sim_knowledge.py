"""The product reads nothing only our simulator writes (issue 38 item 3): the simulated camera stamps each JPEG with
an ``axsim seq=<n> t=<ns>`` comment for tests and benchmarks, and no module outside the simulator (``sim/`` and
the simulated robot's nodes) may know that comment, so a frame is stamped the same with the simulator as with a
real camera (the H.264 stage used to put the comment's time into its capture-stamp SEI)."""

from __future__ import annotations

from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / "axis_ptz_ros2" / "axis_ptz_ros2"
#: the simulator and the simulated robot's nodes (as tests/unit/test_package_imports.py's SIM_USERS)
SIMULATOR = ("sim/", "nodes/panorama_sim.py", "nodes/laser_sim.py")
pytestmark = pytest.mark.unit


def product_modules() -> list[Path]:
    return [p for p in sorted(PACKAGE.rglob("*.py")) if not p.relative_to(PACKAGE).as_posix().startswith(SIMULATOR)]


def test_the_package_is_where_this_test_looks() -> None:
    assert (PACKAGE / "sim" / "frames.py").read_text(encoding="utf-8").count("axsim") >= 1  # the writer
    assert len(product_modules()) > 50


def test_no_product_module_reads_the_simulators_jpeg_comment() -> None:
    knowing = [
        f"{p.relative_to(PACKAGE)}:{n}"
        for p in product_modules()
        for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
        if "axsim" in line
    ]
    assert not knowing, "product modules that know the simulator's JPEG comment:\n" + "\n".join(knowing)
