"""The simulator's world file (config/sim_world.yaml), generated (issue 39): careless edits and bad image targets.

As tests/fuzz/test_config_files.py does for the driver's files: each property starts from the shipped world and
changes it the way a careless edit would (a value of another type or size, a missing or unknown key, a NaN), or
adds an ``image`` target with generated fields and generated file contents (valid pictures, truncated or flipped
bytes, random bytes, a missing file, a folder); the loader must answer with a world whose numbers are finite and
whose targets can be built, or with a ``ValueError`` that says what is wrong (naming the target, for a target's
fault) — never another exception.
"""

from __future__ import annotations

import atexit
import math
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

from axis_ptz_ros2.sim.scene import Target
from axis_ptz_ros2.sim.world import MAX_TARGET_SIZE_M, SimWorld, world_from_dict
from tests.fuzz.test_config_files import _finite, _mutated

pytestmark = pytest.mark.fuzz
CONFIG = Path(__file__).resolve().parents[2] / "config"
WORLD = yaml.safe_load((CONFIG / "sim_world.yaml").read_text(encoding="utf-8"))
#: the shipped world without its facade (the one texture that is slow to build) for the target-building check
_SMALL = {**WORLD, "targets": [t for t in WORLD["targets"] if t["kind"] != "facade"]}

_FILES = Path(tempfile.mkdtemp(prefix="axis_world_fuzz_"))
atexit.register(shutil.rmtree, _FILES, ignore_errors=True)
_IMG = np.random.default_rng(3).integers(0, 255, size=(24, 32, 3), dtype=np.uint8)
_PNG = cv2.imencode(".png", _IMG)[1].tobytes()
_JPG = cv2.imencode(".jpg", _IMG)[1].tobytes()
(_FILES / "folder.png").mkdir()


def _check_world(world: SimWorld, build: bool) -> None:
    for t in world.targets:
        assert _finite(t.center)
        assert _finite(t.size)
        assert all(0.0 < v <= MAX_TARGET_SIZE_M for v in t.size)
        assert t.normal is None or _finite(t.normal)
        if build:
            tgt = Target(t, world.pan_tilt_centre)
            assert np.all(np.isfinite(tgt.corners()))
            assert tgt.texture.ndim == 3
            assert tgt.texture.shape[2] == 4


def _load_or_refuse(doc: Any, build: bool = False, name: str | None = None) -> SimWorld | None:
    try:
        world = world_from_dict(doc, "fuzz_world.yaml", CONFIG)
    except ValueError as err:
        message = str(err)
        assert message.startswith("fuzz_world.yaml"), message
        if name is not None and "targets" not in message:
            assert repr(name) in message, message  # a target's fault names the target
        return None
    _check_world(world, build)
    return world


@given(_mutated(WORLD))
def test_world_file(doc: Any) -> None:
    _load_or_refuse(doc)


_number = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(min_value=-50, max_value=50),
    st.integers(min_value=-(10**30), max_value=10**30),
    st.sampled_from(["1", None, True, [1.0]]),
)
_size = st.one_of(
    st.lists(_number, min_size=0, max_size=3),
    st.tuples(st.floats(min_value=1e-4, max_value=1e4), st.floats(min_value=1e-4, max_value=1e4)).map(list),
)
_center = st.one_of(
    st.lists(_number, min_size=2, max_size=4),
    st.tuples(*[st.floats(min_value=-100, max_value=100)] * 3).map(list),
)


@st.composite
def _file(draw: st.DrawFn) -> str:
    """A path to generated file contents (or a missing file, a folder, an asset name, a bad path)."""
    kind = draw(st.sampled_from(["png", "jpg", "cut", "flip", "random", "missing", "folder", "asset", "text"]))
    if kind == "missing":
        return str(_FILES / "missing.png")
    if kind == "folder":
        return "folder.png" if draw(st.booleans()) else str(_FILES / "folder.png")
    if kind == "asset":
        return draw(st.sampled_from(["asset:acuity_chart.png", "asset:", "asset:../world.py", "asset:none.png"]))
    if kind == "text":
        return draw(st.text(max_size=8))
    data = _PNG if kind in ("png", "cut") or draw(st.booleans()) else _JPG
    if kind == "cut":
        data = data[: draw(st.integers(0, len(data) - 1))]
    elif kind == "flip":
        pos = draw(st.lists(st.integers(0, len(data) - 1), min_size=1, max_size=8))
        b = bytearray(data)
        for p in pos:
            b[p] ^= draw(st.integers(1, 255))
        data = bytes(b)
    elif kind == "random":
        data = draw(st.binary(max_size=300))
        if draw(st.booleans()):
            data = data[:0] + (b"\x89PNG\r\n\x1a\n" if draw(st.booleans()) else b"\xff\xd8") + data
    fd, name = tempfile.mkstemp(suffix=".img", dir=_FILES)
    with os.fdopen(fd, "wb") as fh:
        fh.write(data)
    path = Path(name)
    return str(path)


@st.composite
def _image_target(draw: st.DrawFn) -> dict[str, Any]:
    t: dict[str, Any] = {"name": "fuzz_board", "kind": "image"}
    if draw(st.integers(0, 9)):
        t["file"] = draw(_file())
    if draw(st.integers(0, 9)):
        t["center"] = draw(_center)
    if draw(st.integers(0, 9)):
        t["size"] = draw(_size)
    facing = draw(st.sampled_from([None, "ptz", "normal", "up", 3]))
    if facing is not None:
        t["facing"] = facing
    if draw(st.booleans()):
        t["normal"] = draw(st.lists(_number, min_size=3, max_size=3))
    if draw(st.booleans()):
        t["up"] = draw(st.lists(_number, min_size=2, max_size=3))
    if draw(st.integers(0, 5)) == 0:
        t[draw(st.sampled_from(["text", "color", "colour", "scale"]))] = draw(_number)
    return t


@given(_image_target())
def test_image_targets(target: dict[str, Any]) -> None:
    doc = {**_SMALL, "targets": [*_SMALL["targets"][:2], target]}
    world = _load_or_refuse(doc, build=True, name="fuzz_board")
    if world is not None:
        spec = world.targets[-1]
        assert Path(spec.file).is_file()
        assert spec.image_size[0] * spec.image_size[1] > 0


def test_the_generated_files_include_loadable_pictures() -> None:
    """The image property is not all refusals: a plain PNG, a JPEG and the shipped chart load and build."""
    for name, data in (("ok.png", _PNG), ("ok.jpg", _JPG)):
        (_FILES / name).write_bytes(data)
        target = {"name": "b", "kind": "image", "file": str(_FILES / name), "center": [5, 0, 1], "size": [1, 0.75]}
        world = _load_or_refuse({"targets": [target]}, build=True)
        assert world is not None
        assert world.targets[0].image_size == (32, 24)
    shipped = _load_or_refuse(_SMALL, build=True)
    assert shipped is not None
    assert math.isclose(shipped.targets[-1].size[0], 0.8)
