"""The documentation's parameter tables (docs/nodes.md, docs/simulator.md) are generated from the nodes' ParamSpec
lists and must not drift."""

import importlib
import re
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[2]
NODE_MODULES = (
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
    "axis_ptz_ros2.nodes.joy_teleop",
)


def _generator():  # noqa: ANN202
    import sys

    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        return importlib.import_module("gen_readme_params")
    finally:
        sys.path.pop(0)


def test_parameter_tables_match_the_node_specs():
    gen = _generator()
    docs = gen.documents(ROOT)
    assert ROOT / "docs" / "nodes.md" in docs
    documented: dict[str, list[str]] = {}
    for doc in docs:
        text = doc.read_text(encoding="utf-8")
        for module in re.findall(r"<!-- PARAMS ([\w.]+) -->", text):
            documented.setdefault(module, []).append(doc.name)
        assert gen.render(text) == text, f"{doc.name}: parameter tables are stale: run scripts/gen_readme_params.py"
    missing = [m for m in NODE_MODULES if m not in documented]
    assert not missing, f"no parameter table for {missing}"
    twice = {m: where for m, where in documented.items() if len(where) > 1}
    assert not twice, f"parameter tables documented more than once: {twice}"
    nodes_md = (ROOT / "docs" / "nodes.md").read_text(encoding="utf-8")
    for m in ("stream_node", "ptz_node", "web_console", "link_monitor", "republish", "keyboard_teleop", "joy_teleop"):
        assert f"<!-- PARAMS axis_ptz_ros2.nodes.{m} -->" in nodes_md, f"docs/nodes.md lacks the {m} table"


def test_the_check_mode_fails_on_a_stale_table(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    gen = _generator()
    (tmp_path / "docs").mkdir()
    (tmp_path / "README.md").write_text("# t\n", encoding="utf-8")
    stale = "<!-- PARAMS axis_ptz_ros2.nodes.republish -->\n| old |\n<!-- /PARAMS -->\n"
    (tmp_path / "docs" / "nodes.md").write_text(stale, encoding="utf-8")
    monkeypatch.setattr(gen, "ROOT", tmp_path)
    monkeypatch.setattr(gen.sys, "argv", ["gen_readme_params.py", "--check"])
    assert gen.main() == 1
    monkeypatch.setattr(gen.sys, "argv", ["gen_readme_params.py"])
    assert gen.main() == 0
    assert "`input`" in (tmp_path / "docs" / "nodes.md").read_text(encoding="utf-8")
    monkeypatch.setattr(gen.sys, "argv", ["gen_readme_params.py", "--check"])
    assert gen.main() == 0


def test_every_declared_parameter_has_a_description_and_unit_where_numeric():
    for mod in NODE_MODULES:
        for spec in importlib.import_module(mod).PARAMS:
            assert spec.description.strip(), f"{mod}: {spec.name} has no description"
            # no parameter may carry a secret
            assert "password" not in spec.name or spec.name.endswith("_file"), f"{mod}: {spec.name}"
