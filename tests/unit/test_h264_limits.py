"""The one table of H.264 bounds and defaults (``media/limits.py``): every layer reads it, none has its own."""

from __future__ import annotations

import dataclasses
import re
from dataclasses import replace
from pathlib import Path

import pytest

from axis_ptz_ros2.media import limits
from axis_ptz_ros2.media.errors import EncoderError
from axis_ptz_ros2.media.h264_settings import H264Settings
from axis_ptz_ros2.nodes.stream_params import SPECS
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


def test_the_one_settings_type_takes_its_defaults_from_the_table() -> None:
    d = _defaults(H264Settings)
    assert (d["bitrate_kbps"], d["max_bitrate_kbps"], d["keyframe_interval"], d["preset"]) == (
        limits.DEFAULT_BITRATE_KBPS,
        limits.DEFAULT_MAX_BITRATE_KBPS,
        limits.DEFAULT_KEYFRAME_INTERVAL,
        limits.DEFAULT_PRESET,
    )
    assert (d["profile"], d["refresh"], d["fps"]) == (
        limits.DEFAULT_PROFILE,
        limits.DEFAULT_REFRESH,
        limits.DEFAULT_FPS,
    )
    # the request carries the same type, filled by the h264_* parameters (their defaults are its defaults)
    assert VideoSettings().h264 == H264Settings()
    h264_params = {name for name in SPECS if name.startswith("h264_")}
    assert {SPECS[n].field for n in h264_params} == {f"h264.{n[len('h264_') :]}" for n in h264_params}
    assert {SPECS[n].field.split(".")[1] for n in h264_params} <= set(d)


def test_bitrates_are_kbit_and_become_bits_in_one_place() -> None:
    s = H264Settings(bitrate_kbps=1234, vbv_kbit=56)
    assert (s.bitrate_bps, s.vbv_bits) == (1_234_000, 56_000)
    assert H264Settings().vbv_bits == 0  # 0: the encoder's default buffer


def test_the_encoder_opens_with_what_the_settings_say() -> None:
    """What the stage opens an encoder with (:meth:`H264Settings.opening`): at the ceiling, the VBV buffer asked
    for, the keyframe interval at most one second of frames; and libx264 gets exactly that, in its units."""
    pytest.importorskip("av")
    from axis_ptz_ros2.media.encoder import H264Encoder  # noqa: PLC0415 - PyAV

    target = H264Settings(bitrate_kbps=700, max_bitrate_kbps=1500, keyframe_interval=600, fps=25, vbv_kbit=90)
    opening = target.opening()
    assert (opening.bitrate_kbps, opening.keyframe_interval, opening.vbv_kbit) == (1500, 25, 90)
    reported = replace(
        target, long_wave=True, reported_wave=100
    ).opening()  # every viewer reports its losses: the wave asked for
    assert reported.keyframe_interval == 100
    assert replace(target, long_wave=True).opening().keyframe_interval == 25  # h264_reported_wave 0: off
    assert H264Settings(bitrate_kbps=700, max_bitrate_kbps=300).opening().bitrate_kbps == 700  # a ceiling under it
    enc = H264Encoder(opening, 64, 64)
    assert (enc.opened_max_bitrate_bps, enc.opened_vbv_bits) == (1_500_000, 90_000)
    assert enc.settings == opening
    default = H264Encoder(H264Settings(bitrate_kbps=1000), 64, 64)  # the default buffer: VBV_BUFFER_S of it
    assert default.opened_vbv_bits == int(1_000_000 * limits.VBV_BUFFER_S)


def test_the_parameter_range_lies_inside_the_encoders_and_the_policy_keeps_to_it() -> None:
    low, high = limits.BITRATE_RANGE_KBPS
    elow, ehigh = limits.ENCODER_BITRATE_RANGE_KBPS
    assert elow <= low < high <= ehigh
    # the budgets never take the target under the parameter's floor, nor the ceiling above its top
    assert h264_target_kbps(low, low, 1.0, 1.0)[0] == low
    assert h264_target_kbps(high, high, 1e9)[1] == high
    # the check refuses just outside, with the table's bounds in the reason
    below = VideoSettings(h264=H264Settings(bitrate_kbps=low - 1))
    reason = check_h264(below)
    assert reason is not None
    assert f"{low}…{high}" in reason
    assert check_h264(VideoSettings(h264=H264Settings(bitrate_kbps=high))) is None
    # the settings refuse what the encoder (and a camera's videomaxbitrate) refuses, with the table's bounds ...
    for bad in (elow - 1, ehigh + 1):
        with pytest.raises(EncoderError, match=f"bitrate must be {elow}…{ehigh} kbit/s"):
            H264Settings(bitrate_kbps=bad)
    # ... so a camera is asked for the bitrate in force as it is
    params = VideoParams(Resolution(704, 576), 25, 0)
    assert media_request(params, H264Settings(bitrate_kbps=elow)).max_bitrate_kbps == elow
    assert media_request(params, H264Settings(bitrate_kbps=ehigh)).max_bitrate_kbps == ehigh
    request = media_request(params, H264Settings(keyframe_interval=600, fps=25))
    assert request.keyframe_interval == 25  # at most one second of frames
    # ... whoever reports: a camera's own IDRs are what heals its stream's viewers
    assert (
        media_request(
            params, H264Settings(keyframe_interval=600, fps=25, long_wave=True, reported_wave=100)
        ).keyframe_interval
        == 25
    )


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
        "media/h264_settings.py",
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
