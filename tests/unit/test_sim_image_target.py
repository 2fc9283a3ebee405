"""The simulator's ``image`` targets (issue 39): a PNG/JPEG drawn on a target's rectangle, and what is refused.

The picture is checked in a rendered view against the source image warped by the target's projected corners
(computed here from the world file's numbers, not from the renderer), so a misplaced, mirrored, rotated or
wrongly scaled image fails. Bad files, sizes and paths are refused at load time naming the target.
"""

from __future__ import annotations

import math
import struct
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from axis_ptz_ros2.sim import textures
from axis_ptz_ros2.sim.renderer import PtzRenderer
from axis_ptz_ros2.sim.scene import Scene, Target
from axis_ptz_ros2.sim.world import MAX_TOTAL_TEXELS, WorldError, load_world, world_from_dict

CENTER = (6.0, 0.4, 1.3)
SIZE = (1.2, 0.9)


def _picture(w: int = 160, h: int = 120, seed: int = 1) -> np.ndarray:
    """An asymmetric colourful picture: blocks of random colour (smoothed a little) and a dark corner mark."""
    rng = np.random.default_rng(seed)
    blocks = rng.integers(30, 226, size=(6, 8, 3)).astype(np.uint8)
    img = cv2.resize(blocks, (w, h), interpolation=cv2.INTER_NEAREST)
    img = cv2.GaussianBlur(img, (0, 0), 2.0)
    img[: h // 6, : w // 8] = (10, 10, 10)  # top-left: a mirror or a rotation moves it
    return np.asarray(img, dtype=np.uint8)


def _yaml_number(v: float) -> str:
    return ".nan" if math.isnan(v) else (".inf" if v == math.inf else ("-.inf" if v == -math.inf else repr(v)))


def _world_yaml(tmp: Path, file: str, extra: str = "", size: tuple[float, float] = SIZE) -> Path:
    p = tmp / "world.yaml"
    yaml_size = "[" + ", ".join(_yaml_number(v) for v in size) + "]"
    p.write_text(
        "targets:\n"
        f"  - {{name: board, kind: image, file: {file!r}, center: {list(CENTER)}, size: {yaml_size}{extra}}}\n",
        encoding="utf-8",
    )
    return p


def _aim(world, point) -> tuple[float, float]:
    from axis_ptz_ros2.sim.ptz import ros_to_vapix

    pan, tilt = world.kinematics.look_at(world.T_base_ptz.inverse().apply(np.asarray(point, dtype=np.float64)))
    return ros_to_vapix(pan, tilt)


def _expected_corners(world) -> np.ndarray:
    """The target's outer corners (tl, tr, br, bl) in base_link, from the world's numbers: turned about the
    vertical towards the pan/tilt centre, up = +z."""
    c = np.array(CENTER)
    to_cam = world.pan_tilt_centre - c
    n = np.array([to_cam[0], to_cam[1], 0.0])
    n /= np.linalg.norm(n)
    right = np.cross([0.0, 0.0, 1.0], n)
    up = np.array([0.0, 0.0, 1.0])
    w, h = SIZE
    return np.array([c - right * w / 2 + up * h / 2, c + right * w / 2 + up * h / 2,
                     c + right * w / 2 - up * h / 2, c - right * w / 2 - up * h / 2])  # fmt: skip


@pytest.mark.parametrize("fmt", ["png", "jpg"])
def test_an_image_target_appears_in_the_view_where_its_corners_project(tmp_path, fmt):
    src = _picture()
    cv2.imwrite(str(tmp_path / f"board.{fmt}"), src, [cv2.IMWRITE_JPEG_QUALITY, 100])
    decoded = cv2.imread(str(tmp_path / f"board.{fmt}"))  # what the file holds (JPEG: after its coding)
    world = load_world(_world_yaml(tmp_path, f"board.{fmt}"))  # relative to the world file's folder
    assert world.targets[0].file == str(tmp_path / f"board.{fmt}")
    renderer = PtzRenderer(world, Scene(world))
    pan, tilt = _aim(world, CENTER)
    W, H = 704, 576
    zoom = 2000.0
    view = renderer.render(pan, tilt, zoom, W, H)
    T = renderer.camera_pose(pan, tilt)
    K = renderer.intrinsics(zoom, W, H)
    px = K.project(T.inverse().apply(_expected_corners(world)))
    h, w = src.shape[:2]
    outer = np.array([[-0.5, -0.5], [w - 0.5, -0.5], [w - 0.5, h - 0.5], [-0.5, h - 0.5]], np.float32)
    Hm = cv2.getPerspectiveTransform(outer, px.astype(np.float32))
    expected = cv2.warpPerspective(decoded, Hm, (W, H), flags=cv2.INTER_LINEAR)
    mask = np.zeros((H, W), np.uint8)
    cv2.fillConvexPoly(mask, np.round(px).astype(np.int32), 255)
    inner = cv2.erode(mask, np.ones((7, 7), np.uint8)) > 0
    assert inner.sum() > 0.2 * W * H  # the board fills a good part of the view
    diff = np.abs(view.astype(int) - expected.astype(int)).max(axis=2)[inner]
    assert float(diff.mean()) < 2.0, float(diff.mean())
    assert float(np.percentile(diff, 99)) < 12, float(np.percentile(diff, 99))
    # The test discriminates: the image mirrored left-right does not match.
    mirrored = cv2.warpPerspective(decoded[:, ::-1].copy(), Hm, (W, H), flags=cv2.INTER_LINEAR)
    assert float(np.abs(view.astype(int) - mirrored.astype(int)).max(axis=2)[inner].mean()) > 20
    # And the board is what the view shows there: without it, the same view differs.
    bare = PtzRenderer(world_from_dict({}), None).render(pan, tilt, zoom, W, H)
    assert float(np.abs(bare.astype(int) - view.astype(int)).max(axis=2)[inner].mean()) > 20


def test_an_image_with_alpha_is_cut_out_and_grey_and_16_bit_images_load(tmp_path):
    rgba = np.zeros((40, 80, 4), np.uint8)
    rgba[:, :, :3] = (0, 0, 255)
    rgba[:, 40:, 3] = 255  # the left half transparent
    cv2.imwrite(str(tmp_path / "half.png"), rgba)
    world = load_world(_world_yaml(tmp_path, "half.png", size=(1.0, 0.5)))
    tgt = Target(world.targets[0], world.pan_tilt_centre)
    assert tgt.texture.shape == (40, 80, 4)
    assert np.all(tgt.texture[:, :40] == 0)  # premultiplied: transparent texels carry no colour
    assert np.all(tgt.texture[:, 40:] == (0, 0, 255, 255))
    # A ray through the transparent half passes; one through the opaque half stops at the board.
    o = world.pan_tilt_centre
    d_left = tgt.uv_to_point(0.25, 0.5) - o
    d_right = tgt.uv_to_point(0.75, 0.5) - o
    s, _, _ = tgt.intersect(np.array([o, o]), np.array([d_left, d_right]))
    assert math.isinf(s[0])
    assert math.isclose(s[1], 1.0, rel_tol=1e-9)

    grey16 = (np.arange(64 * 32, dtype=np.uint16).reshape(32, 64) * 30).astype(np.uint16)
    cv2.imwrite(str(tmp_path / "g16.png"), grey16)
    tex = textures.decode_image((tmp_path / "g16.png").read_bytes())
    assert tex.shape == (32, 64, 4)
    assert tex.dtype == np.uint8
    np.testing.assert_array_equal(tex[:, :, 0], (grey16 >> 8).astype(np.uint8))
    assert np.all(tex[:, :, 3] == 255)


def _png_header_only(w: int, h: int) -> bytes:
    """A PNG whose header claims w×h pixels, with one tiny (wrong) data chunk: refused before any decoding."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 16)) + chunk(b"IEND", b"")


def _refusal(tmp: Path, file: str, extra: str = "", size: tuple[float, float] = SIZE) -> str:
    with pytest.raises(WorldError) as err:
        load_world(_world_yaml(tmp, file, extra, size))
    assert "'board'" in str(err.value), str(err.value)  # names the target
    return str(err.value)


def test_missing_unreadable_corrupt_and_truncated_files_are_refused_naming_the_target(tmp_path):
    assert "no such image file" in _refusal(tmp_path, "nowhere.png")
    (tmp_path / "folder.png").mkdir()
    assert "not a file" in _refusal(tmp_path, "folder.png")
    (tmp_path / "text.png").write_text("not a picture", encoding="utf-8")
    assert "not a PNG or JPEG" in _refusal(tmp_path, "text.png")
    good_png = cv2.imencode(".png", _picture())[1].tobytes()
    good_jpg = cv2.imencode(".jpg", _picture())[1].tobytes()
    (tmp_path / "cut.png").write_bytes(good_png[: len(good_png) // 2])
    assert "PNG" in _refusal(tmp_path, "cut.png")
    (tmp_path / "cut.jpg").write_bytes(good_jpg[: len(good_jpg) // 2])
    assert "truncated JPEG" in _refusal(tmp_path, "cut.jpg")
    broken = bytearray(good_png)
    broken[60:400] = bytes(340)  # zeroes over the compressed data
    (tmp_path / "broken.png").write_bytes(bytes(broken))
    assert "PNG" in _refusal(tmp_path, "broken.png")
    (tmp_path / "header.jpg").write_bytes(good_jpg[:200])  # markers, no scan
    assert "JPEG" in _refusal(tmp_path, "header.jpg")
    msg = _refusal(tmp_path, "asset:../../world.py")
    assert "asset" in msg
    assert "expected a path" in _refusal(tmp_path, "")


def test_images_beyond_the_pixel_bound_are_refused_before_decoding_naming_the_bound(tmp_path):
    (tmp_path / "wide.png").write_bytes(cv2.imencode(".png", np.zeros((1, 4097), np.uint8))[1].tobytes())
    msg = _refusal(tmp_path, "wide.png")
    assert "4097x1" in msg
    assert "4096x4096" in msg
    (tmp_path / "bomb.png").write_bytes(_png_header_only(100_000, 100_000))  # would be 10 GB decoded
    msg = _refusal(tmp_path, "bomb.png")
    assert "100000x100000" in msg
    assert "4096x4096" in msg
    (tmp_path / "empty.png").write_bytes(_png_header_only(0, 10))
    assert "empty" in _refusal(tmp_path, "empty.png")


def test_bad_sizes_numbers_and_keys_are_refused_naming_the_target(tmp_path):
    cv2.imwrite(str(tmp_path / "ok.png"), _picture())
    for size in ((0.0, 1.0), (-1.0, 1.0), (1.0, 1e6)):
        assert "size" in _refusal(tmp_path, "ok.png", size=size)
    assert "finite" in _refusal(tmp_path, "ok.png", size=(float("nan"), 1.0))
    assert "finite" in _refusal(tmp_path, "ok.png", extra=", normal: [.inf, 0, 0]")
    assert "unknown field" in _refusal(tmp_path, "ok.png", extra=", text: hello")
    assert "along the normal" in _refusal(tmp_path, "ok.png", extra=", normal: [0, 0, 1]")
    assert "facing" in _refusal(tmp_path, "ok.png", extra=", facing: sideways")
    assert "give one of them" in _refusal(tmp_path, "ok.png", extra=", facing: ptz, normal: [-1, 0, 0]")
    # A fixed orientation is accepted: facing normal with normal and up.
    p = _world_yaml(tmp_path, "ok.png", ", facing: normal, normal: [-1, 0, 0], up: [0, 0, 1]")
    tgt = Target(load_world(p).targets[0], np.zeros(3))
    np.testing.assert_allclose(tgt.normal, [-1, 0, 0])
    np.testing.assert_allclose(tgt.right, [0, -1, 0], atol=1e-12)  # seen from -x looking +x: -y is on the right


def test_the_texture_budget_of_all_targets_is_bounded(tmp_path):
    big = np.zeros((4096, 4096), np.uint8)
    cv2.imwrite(str(tmp_path / "big.png"), big)
    n = MAX_TOTAL_TEXELS // (4096 * 4096) + 1
    lines = ["targets:"] + [
        f"  - {{name: b{i}, kind: image, file: big.png, center: [{5 + i}, 0, 1], size: [1, 1]}}" for i in range(n)
    ]
    p = tmp_path / "many.yaml"
    p.write_text("\n".join(lines) + "\n", encoding="utf-8")
    with pytest.raises(WorldError, match=rf"at most {MAX_TOTAL_TEXELS}"):
        load_world(p)
    # One fewer fits.
    p.write_text("\n".join(lines[:-1]) + "\n", encoding="utf-8")
    assert len(load_world(p).targets) == n - 1


def test_the_demo_world_holds_the_acuity_charts_facing_the_head_at_10_20_and_35_m():
    world = load_world()
    centre = world.pan_tilt_centre
    for name, d in (("acuity_10m", 10.0), ("acuity_20m", 20.0), ("acuity_35m", 35.0)):
        spec = next(t for t in world.targets if t.name == name)
        assert spec.kind == "image"
        assert spec.file.endswith("acuity_chart.png")
        assert Path(spec.file).is_file()
        assert math.isclose(float(np.linalg.norm(np.array(spec.center) - centre)), d, abs_tol=0.01)
        tgt = Target(spec, centre)
        to_cam = centre - tgt.center
        assert float(tgt.normal @ to_cam) / np.linalg.norm(to_cam) > 0.99  # faces the head
        # outside the home view (pan 0, ±24° at zoom 1): more than 90° to the side
        az = math.degrees(math.atan2(-to_cam[1], -to_cam[0]))
        assert az < -90.0


def test_the_simulator_refuses_a_bad_world_file_with_the_loaders_message(tmp_path, capsys):
    from axis_ptz_ros2.sim.cli import main

    p = _world_yaml(tmp_path, "missing.png")
    assert main(["--port", "0", "--world", str(p)]) == 2
    err = capsys.readouterr().err
    assert "bad world file" in err
    assert "'board'" in err
    assert "missing.png" in err
