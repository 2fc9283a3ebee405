"""The node reference (docs/nodes.md, linked from the README) documents the ROS conventions a Jazzy user relies on
(issue 23's targets), and the two-robot example (docs/launch-and-urdf.md) names keys that the shipped parameter file
has.

The generated parameter tables are checked against the nodes' specs elsewhere (``tests/ros/test_readme_params.py``);
these rows are hand-written, so without this test they could be deleted or drift with every test still green.
"""

from __future__ import annotations

import re
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
NODES = (ROOT / "docs" / "nodes.md").read_text(encoding="utf-8")
LAUNCH = (ROOT / "docs" / "launch-and-urdf.md").read_text(encoding="utf-8")


def table_rows() -> dict[str, str]:
    """First cell (without backticks and the ``(pub, …)`` note) → the whole row, for every docs/nodes.md table row."""
    rows: dict[str, str] = {}
    for line in NODES.splitlines():
        m = re.match(r"^\| `([^`]+)`[^|]*\|", line)
        if m:
            rows.setdefault(m.group(1), line)
    return rows


def test_topic_and_service_rows_for_tf_and_camera_info_manager() -> None:
    rows = table_rows()
    assert "tf2_msgs/TFMessage" in rows["/tf"]
    assert "volatile" in rows["/tf"]
    assert "tf2_msgs/TFMessage" in rows["/tf_static"]
    assert "transient local" in rows["/tf_static"]
    assert "sensor_msgs/SetCameraInfo" in rows["~/set_camera_info"]
    for name in ("camera_info_url", "camera_name", "frame_prefix", "frame_id"):
        assert name in rows, f"docs/nodes.md: no parameter row for {name}"


def test_qos_override_rows_name_every_policy() -> None:
    rows = table_rows()
    for policy in ("reliability", "durability", "history", "depth"):
        assert f"qos_overrides.<topic>.publisher.{policy}" in rows, policy


def test_root_topics_are_named_as_the_exception_to_relative_names() -> None:
    sentence = re.search(r"Every topic name\s+is relative.*?\n\n", NODES, re.S)
    assert sentence is not None
    for topic in ("/tf", "/tf_static", "/diagnostics"):
        assert f"`{topic}`" in sentence.group(0)


def test_the_two_robot_example_names_keys_of_the_shipped_file() -> None:
    """The example tells users to set frame_prefix in both sections and camera_name in the stream's."""
    doc = yaml.safe_load((ROOT / "config" / "axis_camera.params.yaml").read_text(encoding="utf-8"))
    stream = doc["/**/axis_stream"]["ros__parameters"]
    ptz = doc["/**/axis_ptz"]["ros__parameters"]
    assert "frame_prefix" in stream
    assert "frame_prefix" in ptz
    assert "camera_name" in stream
    example = LAUNCH[LAUNCH.index("Two robots, each with its own copy of the file") :][:1200]
    for needle in ("frame_prefix", "camera_name", "namespace:=robot2", "frame_prefix:=robot2/"):
        assert needle in example, needle
