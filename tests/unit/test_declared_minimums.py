"""The minimum versions ``pyproject.toml`` declares are the ones the code is tested on (issue 37).

``scripts/min_env`` builds ``.venv-min`` with the lowest release of each declared series (``>=X.Y`` → ``==X.Y.*``),
and ``./scripts/test`` runs the H.264, console, republisher and link-monitor tests in it with
``AXIS_MIN_ENV=1``: there, :func:`test_this_run_uses_the_declared_minimums` checks that the versions imported are
those series, so a minimum raised or lowered in one place but not tested fails. Everywhere, the declared minimums
must agree with what the code itself checks (PyAV: ``media/pyav.py``) and with what Ubuntu 24.04 ships where that is
enough (the versions a Jazzy user gets from rosdep's apt keys).
"""

from __future__ import annotations

import importlib.metadata
import os
import re
import sys
import tomllib
from pathlib import Path

import pytest

from axis_ptz_ros2.media import pyav

pytestmark = pytest.mark.unit

ROOT = Path(__file__).resolve().parents[2]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
# Ubuntu 24.04 (noble): the version its apt package (a rosdep key of package.xml) installs
NOBLE = {
    "httpx": (0, 26),
    "numpy": (1, 26),
    "opencv-python-headless": (4, 6),
    "pyyaml": (6, 0),
    "scipy": (1, 11),
    "cryptography": (41, 0),
}
IMPORT_NAME = {"opencv-python-headless": "cv2", "pyyaml": "yaml", "av": "av"}


def minimums() -> dict[str, tuple[int, ...]]:
    out = {}
    for dep in PYPROJECT["project"]["dependencies"]:
        m = re.fullmatch(r"([A-Za-z0-9_.-]+)>=([0-9]+(?:\.[0-9]+)*)", dep.replace(" ", ""))
        assert m, f"{dep!r}: every runtime dependency has a plain '>=' minimum (scripts/min_env reads it)"
        out[m.group(1).lower()] = tuple(int(x) for x in m.group(2).split("."))
    return out


def test_every_dependency_has_a_minimum_and_noble_satisfies_the_apt_ones() -> None:
    mins = minimums()
    assert set(mins) == {*NOBLE, "av"}
    for name, noble in NOBLE.items():
        assert mins[name] <= noble, f"{name}: declared {mins[name]}, but a Jazzy robot gets {noble} from apt"


def test_the_pyav_minimum_is_the_one_the_code_checks() -> None:
    assert minimums()["av"] == pyav.MIN_VERSION
    assert pyav._parse("11.0.0-4build1") < pyav.MIN_VERSION  # noble's python3-av is refused
    assert pyav._parse("18.0.0") >= pyav.MIN_VERSION


def test_package_xml_names_the_pyav_key_our_rosdep_source_defines() -> None:
    xml = (ROOT / "axis_ptz_ros2" / "package.xml").read_text(encoding="utf-8")
    rosdep = (ROOT / "axis_ptz_ros2" / "rosdep.yaml").read_text(encoding="utf-8")
    assert "<exec_depend>python3-av-pip</exec_depend>" in xml
    assert "<exec_depend>python3-av</exec_depend>" not in xml  # no such key in ROS's rosdep database
    assert re.search(r"^python3-av-pip:", rosdep, re.MULTILINE)


def test_this_run_uses_versions_the_declarations_allow() -> None:
    """In ``.venv-min`` (``AXIS_MIN_ENV=1``): exactly the declared minimum series, imported from that environment.
    Elsewhere: nothing older than declared."""
    in_min_env = os.environ.get("AXIS_MIN_ENV") == "1"
    for name, low in minimums().items():
        got = importlib.metadata.version(name)
        series = tuple(int(x) for x in re.findall(r"\d+", got)[: len(low)])
        if in_min_env:
            assert series == low, f"{name} {got} is not the declared minimum series {low}"
            module = __import__(IMPORT_NAME.get(name, name))
            where = Path(module.__file__ or "")
            assert where.is_relative_to(Path(sys.prefix)), f"{name} imported from {where}, not {sys.prefix}"
        else:
            assert series >= low, f"{name} {got} is older than the declared minimum {low}"
