"""The one table of H.264 bounds and defaults (``media/limits.py``): every layer reads it, none has its own."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest

from axis_ptz_ros2.media import limits
from axis_ptz_ros2.nodes.stream_params import SPECS
from axis_ptz_ros2.streaming.h264 import H264Settings
from axis_ptz_ros2.streaming.h264_policy import check_h264, h264_target_kbps
from axis_ptz_ros2.streaming.rtsp_source import media_request
from axis_ptz_ros2.streaming.video_types import VideoSettings
from axis_ptz_ros2.vapix.models import Resolution, VideoParams

pytestmark = pytest.mark.unit

PACKAGE = Path(__file__).resolve().parents[2] / "axis_ptz_ros2" / "axis_ptz_ros2"


def _defaults(cls: type) -> dict[str, object]:
    return {f.name: f.default for f in dataclasses.fields(cls) if f.default is not dataclasses.MISSING}


def test_parameter_descriptors_read_the_table() -> None:
    assert SPECS["h264_bitrate_kbps"].int_range == limits.BITRATE_RANGE_KBPS
    assert SPECS["h264_max_bitrate_kbps"].int_range == limits.BITRATE_RANGE_KBPS
    assert SPECS["h264_keyframe_interval"].int_range == limits.KEYFRAME_RANGE
    assert SPECS["h264_preset"].choices == limits.PRESETS
    assert SPECS["codec"].choices == limits.CODECS
    assert SPECS["h264_bitrate_kbps"].default == limits.DEFAULT_BITRATE_KBPS
    assert SPECS["h264_max_bitrate_kbps"].default == limits.DEFAULT_MAX_BITRATE_KBPS
    assert SPECS["h264_keyframe_interval"].default == limits.DEFAULT_KEYFRAME_INTERVAL
    assert SPECS["h264_preset"].default == limits.DEFAULT_PRESET


def test_every_settings_type_takes_its_defaults_from_the_table() -> None:
    pytest.importorskip("av")
    from axis_ptz_ros2.media.encoder import EncoderConfig  # noqa: PLC0415 - PyAV
    from axis_ptz_ros2.media.transcoder import TranscoderConfig  # noqa: PLC0415 - PyAV

    stage = _defaults(H264Settings)
    assert (stage["bitrate_kbps"], stage["keyframe_interval"], stage["preset"]) == (
        limits.DEFAULT_BITRATE_KBPS,
        limits.DEFAULT_KEYFRAME_INTERVAL,
        limits.DEFAULT_PRESET,
    )
    assert (stage["profile"], stage["refresh"]) == (limits.DEFAULT_PROFILE, limits.DEFAULT_REFRESH)
    for cls in (TranscoderConfig, EncoderConfig):
        d = _defaults(cls)
        assert d["bitrate_bps"] == limits.DEFAULT_BITRATE_KBPS * 1000, cls
        assert d["keyframe_interval"] == limits.DEFAULT_KEYFRAME_INTERVAL, cls
        assert (d["preset"], d["profile"], d["refresh"]) == (
            limits.DEFAULT_PRESET,
            limits.DEFAULT_PROFILE,
            limits.DEFAULT_REFRESH,
        ), cls
    # the stage's default settings open an encoder (the encoder accepts what the stream node asks for)
    TranscoderConfig(**{k: v for k, v in dataclasses.asdict(H264Settings().transcoder_config()).items()})


def test_the_parameter_range_lies_inside_the_encoders_and_the_policy_keeps_to_it() -> None:
    low, high = limits.BITRATE_RANGE_KBPS
    elow, ehigh = limits.ENCODER_BITRATE_RANGE_KBPS
    assert elow <= low < high <= ehigh
    assert (elow * 1000, ehigh * 1000) == (limits.MIN_BITRATE_BPS, limits.MAX_BITRATE_BPS)
    # the budgets never take the target under the parameter's floor, nor the ceiling above its top
    assert h264_target_kbps(low, low, 1.0, 1.0)[0] == low
    assert h264_target_kbps(high, high, 1e9)[1] == high
    # the check refuses just outside, with the table's bounds in the reason
    reason = check_h264(dataclasses.replace(VideoSettings(), h264_bitrate_kbps=low - 1))
    assert reason is not None
    assert f"{low}…{high}" in reason
    assert check_h264(dataclasses.replace(VideoSettings(), h264_bitrate_kbps=high)) is None
    # a camera is asked for no bitrate its videomaxbitrate refuses
    params = VideoParams(Resolution(704, 576), 25, 0)
    assert media_request(params, H264Settings(bitrate_kbps=1)).max_bitrate_kbps == elow
    assert media_request(params, H264Settings(bitrate_kbps=10**9)).max_bitrate_kbps == ehigh


@pytest.mark.parametrize(
    "pattern",
    [
        r"\b(?:50|100)_?000\b.*(?:bitrate|kbps|bps)",  # a bitrate bound written out again
        r"(?:preset|h264_preset)\s*:\s*str\s*=\s*\"",  # a preset default written out again
        r"(?:profile|refresh)\s*:\s*str\s*=\s*\"",  # a profile/refresh default written out again
    ],
)
def test_no_settings_module_writes_a_bound_or_default_again(pattern: str) -> None:
    modules = [
        "media/encoder.py",
        "media/transcoder.py",
        "streaming/h264.py",
        "streaming/h264_policy.py",
        "streaming/video_types.py",
        "streaming/rtsp_source.py",
        "nodes/stream_params.py",
    ]
    found = [
        f"{m}:{n}: {line.strip()}"
        for m in modules
        for n, line in enumerate((PACKAGE / m).read_text(encoding="utf-8").splitlines(), 1)
        if re.search(pattern, line) and not line.lstrip().startswith("#")
    ]
    assert not found, found
