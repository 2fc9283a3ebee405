"""The README's parameter tables are generated from the nodes' ParamSpec lists and must not drift."""

import importlib
import re
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[2]


def test_readme_parameter_tables_match_the_node_specs():
    import sys

    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        gen = importlib.import_module("gen_readme_params")
    finally:
        sys.path.pop(0)
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"<!-- PARAMS ([\w.]+) -->", text)
    assert len(blocks) >= 8, "every node's parameters are documented in the README"
    assert gen.render(text) == text, "README parameter tables are stale: run scripts/gen_readme_params.py"


def test_every_declared_parameter_has_a_description_and_unit_where_numeric():
    for mod in (
        "axis_ptz_ros2.nodes.stream_node",
        "axis_ptz_ros2.nodes.ptz_node",
        "axis_ptz_ros2.nodes.web_console",
        "axis_ptz_ros2.nodes.visualizer",
        "axis_ptz_ros2.nodes.virtual_camera",
        "axis_ptz_ros2.nodes.panorama_sim",
        "axis_ptz_ros2.nodes.laser_sim",
        "axis_ptz_ros2.nodes.link_monitor",
        "axis_ptz_ros2.nodes.republish",
        "axis_ptz_ros2.nodes.keyboard_teleop",
    ):
        for spec in importlib.import_module(mod).PARAMS:
            assert spec.description.strip(), f"{mod}: {spec.name} has no description"
            # no parameter may carry a secret
            assert "password" not in spec.name or spec.name.endswith("_file"), f"{mod}: {spec.name}"
