"""H.264 Annex B byte streams: NAL units, parameter sets, the codec string and our capture-time SEI.

ROS-free and pure Python. References: ITU-T H.264 (08/2021) §7.3 (NAL unit, SPS and SEI syntax), §7.4.1
(emulation prevention), Annex B (byte stream format), §D.1.7 (user data unregistered SEI); RFC 6184 §8.1
(``sprop-parameter-sets``); RFC 6381 §3.3 (``avc1.PPCCLL``).

Every function here either returns a result or raises :class:`~axis_ptz_ros2.media.errors.BitstreamError`;
loops are bounded by the input's length, so no input makes them hang.

An *access unit* is one picture's NAL units, each behind a start code; :func:`split_nal_units` returns the NAL
units without their start codes and :func:`join_nal_units` puts 4-byte start codes back.
"""

from __future__ import annotations

import base64
import binascii
import uuid
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from enum import IntEnum

from axis_ptz_ros2.media.errors import BitstreamError

START_CODE = b"\x00\x00\x00\x01"
_SC3 = b"\x00\x00\x01"

#: Our user-data-unregistered SEI (payload type 5): this UUID, then the capture time as big-endian uint64 ns.
CAPTURE_STAMP_UUID = uuid.UUID("5d3c2a6e-8f1b-4a57-9c0e-61a7d2b4e9f3")
_SEI_USER_DATA_UNREGISTERED = 5


class NalType(IntEnum):
    """``nal_unit_type`` values this project meets (H.264 Table 7-1)."""

    SLICE = 1
    SLICE_DPA = 2
    SLICE_DPB = 3
    SLICE_DPC = 4
    IDR = 5
    SEI = 6
    SPS = 7
    PPS = 8
    AUD = 9
    END_OF_SEQUENCE = 10
    END_OF_STREAM = 11
    FILLER = 12


_VCL_TYPES = frozenset({1, 2, 3, 4, 5})


# ---- Annex B framing ---------------------------------------------------------------------------------------
def split_nal_units(data: bytes) -> list[bytes]:
    """The NAL units of an Annex B byte string (start codes and trailing zero bytes removed).

    Raises :class:`BitstreamError` when there is no start code, when non-zero bytes precede the first one, or
    when a NAL unit is empty or has its forbidden bit set.
    """
    first = data.find(_SC3)
    if first < 0:
        raise BitstreamError(f"no Annex B start code in {len(data)} bytes")
    if data[:first].strip(b"\x00"):
        raise BitstreamError(f"{first} bytes of garbage before the first start code")
    nals: list[bytes] = []
    pos = first + 3
    n = len(data)
    while pos <= n:
        nxt = data.find(_SC3, pos)
        end = n if nxt < 0 else nxt
        nal = data[pos:end].rstrip(b"\x00")  # trailing_zero_8bits and the first byte of a 4-byte start code
        if not nal:
            raise BitstreamError(f"empty NAL unit at byte {pos}")
        if nal[0] & 0x80:
            raise BitstreamError(f"NAL unit at byte {pos} has forbidden_zero_bit set")
        nals.append(nal)
        if nxt < 0:
            break
        pos = nxt + 3
    return nals


def join_nal_units(nals: Iterable[bytes]) -> bytes:
    """An Annex B byte string: each NAL unit behind a 4-byte start code."""
    return b"".join(START_CODE + nal for nal in nals)


def nal_type(nal: bytes) -> int:
    """``nal_unit_type`` of one NAL unit (without start code)."""
    if not nal:
        raise BitstreamError("empty NAL unit")
    if nal[0] & 0x80:
        raise BitstreamError("forbidden_zero_bit set")
    return nal[0] & 0x1F


def nal_types(access_unit: bytes) -> list[int]:
    """The ``nal_unit_type`` of every NAL unit in an Annex B access unit, in order."""
    return [nal[0] & 0x1F for nal in split_nal_units(access_unit)]


def is_idr(access_unit: bytes) -> bool:
    """Whether the access unit holds an IDR picture (a point where a decoder can start)."""
    return NalType.IDR in nal_types(access_unit)


# ---- emulation prevention (§7.4.1) -------------------------------------------------------------------------
def ebsp_to_rbsp(ebsp: bytes) -> bytes:
    """Remove emulation-prevention bytes (``00 00 03`` → ``00 00``)."""
    if b"\x00\x00\x03" not in ebsp:
        return ebsp
    out = bytearray()
    zeros = 0
    for b in ebsp:
        if zeros >= 2 and b == 3:
            zeros = 0
            continue
        out.append(b)
        zeros = zeros + 1 if b == 0 else 0
    return bytes(out)


def rbsp_to_ebsp(rbsp: bytes) -> bytes:
    """Insert emulation-prevention bytes so no ``00 00 0x`` (x ≤ 3) occurs in the NAL unit's payload."""
    out = bytearray()
    zeros = 0
    for b in rbsp:
        if zeros >= 2 and b <= 3:
            out.append(3)
            zeros = 0
        out.append(b)
        zeros = zeros + 1 if b == 0 else 0
    if zeros >= 2:  # ends in a cabac_zero_word: a final 0x03 keeps it from merging with the next start code
        out.append(3)
    return bytes(out)


class _BitReader:
    """MSB-first bit reader with Exp-Golomb codes (§9.1); every overrun is a :class:`BitstreamError`."""

    __slots__ = ("_data", "_pos", "_nbits")

    def __init__(self, data: bytes) -> None:
        self._data = data
        self._pos = 0
        self._nbits = 8 * len(data)

    def u(self, n: int) -> int:
        if self._pos + n > self._nbits:
            raise BitstreamError("SPS ends early")
        v = 0
        for _ in range(n):
            byte = self._data[self._pos >> 3]
            v = (v << 1) | ((byte >> (7 - (self._pos & 7))) & 1)
            self._pos += 1
        return v

    def ue(self) -> int:
        zeros = 0
        while self.u(1) == 0:
            zeros += 1
            if zeros > 31:
                raise BitstreamError("Exp-Golomb code longer than 32 bits")
        return (1 << zeros) - 1 + self.u(zeros)

    def se(self) -> int:
        k = self.ue()
        return (k + 1) // 2 if k & 1 else -(k // 2)


# ---- SPS (§7.3.2.1.1) ----------------------------------------------------------------------------------------
_HIGH_PROFILES = frozenset({100, 110, 122, 244, 44, 83, 86, 118, 128, 138, 139, 134, 135})


@dataclass(frozen=True, slots=True)
class SpsInfo:
    """What a viewer needs from a sequence parameter set."""

    profile_idc: int
    constraint_flags: int  # constraint_set0_flag … set5_flag and the two reserved bits, as one byte
    level_idc: int
    sps_id: int
    chroma_format_idc: int
    width: int  # after frame cropping
    height: int
    max_num_ref_frames: int

    @property
    def codec_string(self) -> str:
        """The WebCodecs / RFC 6381 codec string, ``avc1.PPCCLL``."""
        return codec_string(self)


def parse_sps(nal: bytes) -> SpsInfo:
    """Parse an SPS NAL unit (with its one-byte header, without start code) up to the frame cropping."""
    if nal_type(nal) != NalType.SPS:
        raise BitstreamError(f"not an SPS: nal_unit_type {nal[0] & 0x1F}")
    r = _BitReader(ebsp_to_rbsp(nal[1:]))
    profile_idc = r.u(8)
    constraint_flags = r.u(8)
    level_idc = r.u(8)
    sps_id = r.ue()
    if sps_id > 31:
        raise BitstreamError(f"seq_parameter_set_id {sps_id} > 31")
    chroma_format_idc = 1
    separate_colour_plane = 0
    if profile_idc in _HIGH_PROFILES:
        chroma_format_idc = r.ue()
        if chroma_format_idc > 3:
            raise BitstreamError(f"chroma_format_idc {chroma_format_idc} > 3")
        if chroma_format_idc == 3:
            separate_colour_plane = r.u(1)
        r.ue()  # bit_depth_luma_minus8
        r.ue()  # bit_depth_chroma_minus8
        r.u(1)  # qpprime_y_zero_transform_bypass_flag
        if r.u(1):  # seq_scaling_matrix_present_flag
            for i in range(8 if chroma_format_idc != 3 else 12):
                if r.u(1):
                    _skip_scaling_list(r, 16 if i < 6 else 64)
    log2_max_frame_num_minus4 = r.ue()
    if log2_max_frame_num_minus4 > 12:
        raise BitstreamError(f"log2_max_frame_num_minus4 {log2_max_frame_num_minus4} > 12")
    poc_type = r.ue()
    if poc_type == 0:
        r.ue()  # log2_max_pic_order_cnt_lsb_minus4
    elif poc_type == 1:
        r.u(1)  # delta_pic_order_always_zero_flag
        r.se()  # offset_for_non_ref_pic
        r.se()  # offset_for_top_to_bottom_field
        cycle = r.ue()
        if cycle > 255:
            raise BitstreamError(f"num_ref_frames_in_pic_order_cnt_cycle {cycle} > 255")
        for _ in range(cycle):
            r.se()
    elif poc_type != 2:
        raise BitstreamError(f"pic_order_cnt_type {poc_type} > 2")
    max_num_ref_frames = r.ue()
    r.u(1)  # gaps_in_frame_num_value_allowed_flag
    width_mbs = r.ue() + 1
    height_map_units = r.ue() + 1
    frame_mbs_only = r.u(1)
    if not frame_mbs_only:
        r.u(1)  # mb_adaptive_frame_field_flag
    r.u(1)  # direct_8x8_inference_flag
    crop = (0, 0, 0, 0)
    if r.u(1):  # frame_cropping_flag
        crop = (r.ue(), r.ue(), r.ue(), r.ue())
    chroma_array_type = 0 if separate_colour_plane else chroma_format_idc
    sub_w, sub_h = {0: (1, 1), 1: (2, 2), 2: (2, 1), 3: (1, 1)}[chroma_array_type]
    crop_x = sub_w
    crop_y = sub_h * (2 - frame_mbs_only)
    width = width_mbs * 16 - crop_x * (crop[0] + crop[1])
    height = (2 - frame_mbs_only) * height_map_units * 16 - crop_y * (crop[2] + crop[3])
    if width <= 0 or height <= 0:
        raise BitstreamError(f"frame cropping leaves {width}x{height}")
    return SpsInfo(
        profile_idc=profile_idc,
        constraint_flags=constraint_flags,
        level_idc=level_idc,
        sps_id=sps_id,
        chroma_format_idc=chroma_format_idc,
        width=width,
        height=height,
        max_num_ref_frames=max_num_ref_frames,
    )


def _skip_scaling_list(r: _BitReader, size: int) -> None:
    last, nxt = 8, 8
    for _ in range(size):
        if nxt != 0:
            delta = r.se()
            if not -128 <= delta <= 127:
                raise BitstreamError(f"delta_scale {delta} out of range")
            nxt = (last + delta + 256) % 256
        last = nxt if nxt != 0 else last


def codec_string(sps: SpsInfo) -> str:
    """``avc1.PPCCLL``: profile_idc, the constraint-flags byte and level_idc in hex (RFC 6381 §3.3)."""
    return f"avc1.{sps.profile_idc:02X}{sps.constraint_flags:02X}{sps.level_idc:02X}"


def find_sps(access_unit: bytes) -> SpsInfo | None:
    """The first SPS of an access unit, parsed; None if it has none."""
    for nal in split_nal_units(access_unit):
        if nal[0] & 0x1F == NalType.SPS:
            return parse_sps(nal)
    return None


# ---- parameter sets out of band (RFC 6184 §8.1) ------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class ParameterSets:
    """One SPS and one PPS NAL unit (without start codes), e.g. from an SDP's ``sprop-parameter-sets``."""

    sps: bytes
    pps: bytes

    def __post_init__(self) -> None:
        if nal_type(self.sps) != NalType.SPS:
            raise BitstreamError(f"expected an SPS, got nal_unit_type {self.sps[0] & 0x1F}")
        if nal_type(self.pps) != NalType.PPS:
            raise BitstreamError(f"expected a PPS, got nal_unit_type {self.pps[0] & 0x1F}")

    @property
    def info(self) -> SpsInfo:
        return parse_sps(self.sps)


def parse_sprop_parameter_sets(value: str) -> ParameterSets:
    """Parse the SDP fmtp ``sprop-parameter-sets`` value: comma-separated base64 NAL units (SPS first).

    The first SPS and the first PPS are kept; other NAL types are refused.
    """
    sps: bytes | None = None
    pps: bytes | None = None
    items = [item.strip() for item in value.strip().split(",") if item.strip()]
    if not items:
        raise BitstreamError("sprop-parameter-sets is empty")
    for item in items:
        try:
            nal = base64.b64decode(item, validate=True)
        except (binascii.Error, ValueError) as err:
            raise BitstreamError(f"sprop-parameter-sets item {item[:16]!r} is not base64") from err
        t = nal_type(nal)
        if t == NalType.SPS:
            parse_sps(nal)
            sps = sps or nal
        elif t == NalType.PPS:
            pps = pps or nal
        else:
            raise BitstreamError(f"sprop-parameter-sets holds nal_unit_type {t}, not an SPS or PPS")
    if sps is None or pps is None:
        raise BitstreamError("sprop-parameter-sets lacks " + ("an SPS" if sps is None else "a PPS"))
    return ParameterSets(sps, pps)


def _first_vcl_index(nals: Sequence[bytes]) -> int:
    for i, nal in enumerate(nals):
        if nal[0] & 0x1F in _VCL_TYPES:
            return i
    raise BitstreamError("access unit holds no picture (no VCL NAL unit)")


def prepend_parameter_sets(access_unit: bytes, params: ParameterSets) -> bytes:
    """An IDR access unit that lacks an SPS or a PPS, with them inserted after any AUD; others unchanged."""
    nals = split_nal_units(access_unit)
    types = {nal[0] & 0x1F for nal in nals}
    if NalType.IDR not in types or (NalType.SPS in types and NalType.PPS in types):
        return access_unit
    at = 1 if nals[0][0] & 0x1F == NalType.AUD else 0
    add = [p for p, t in ((params.sps, NalType.SPS), (params.pps, NalType.PPS)) if t not in types]
    return join_nal_units([*nals[:at], *add, *nals[at:]])


class ParameterSetTracker:
    """Keeps the latest SPS/PPS (from the SDP, then in-band) and puts them in front of every IDR lacking them.

    For cameras that send them only in the SDP (Axis's default) or only now and then.
    """

    def __init__(self, initial: ParameterSets | None = None) -> None:
        self._sps = initial.sps if initial else None
        self._pps = initial.pps if initial else None

    @property
    def parameter_sets(self) -> ParameterSets | None:
        if self._sps is None or self._pps is None:
            return None
        return ParameterSets(self._sps, self._pps)

    def process(self, access_unit: bytes) -> bytes:
        """Learn in-band parameter sets; return the access unit, with SPS/PPS in front if it is a bare IDR.

        Raises :class:`BitstreamError` for an IDR when no SPS/PPS is known yet (it cannot be decoded).
        """
        nals = split_nal_units(access_unit)
        has_idr = False
        for nal in nals:
            t = nal[0] & 0x1F
            if t == NalType.SPS:
                parse_sps(nal)
                self._sps = nal
            elif t == NalType.PPS:
                self._pps = nal
            elif t == NalType.IDR:
                has_idr = True
        if not has_idr:
            return access_unit
        params = self.parameter_sets
        if params is None:
            raise BitstreamError("IDR without SPS/PPS, and none known from the SDP or the stream")
        return prepend_parameter_sets(access_unit, params)


# ---- capture-time SEI (§7.3.2.3.1, §D.1.7) ----------------------------------------------------------------------
def _sei_varint(value: int) -> bytes:
    return b"\xff" * (value // 255) + bytes([value % 255])


def _read_sei_varint(rbsp: bytes, pos: int, what: str) -> tuple[int, int]:
    """Read a payload type or size (0xFF bytes of 255 each, then a last byte) at ``pos``: (value, next pos)."""
    value, n = 0, len(rbsp)
    while pos < n and rbsp[pos] == 0xFF:
        value += 255
        pos += 1
    if pos >= n:
        raise BitstreamError(f"SEI payload {what} runs past the NAL unit")
    return value + rbsp[pos], pos + 1


def capture_stamp_sei(stamp_ns: int) -> bytes:
    """Our SEI NAL unit (header included, emulation prevention applied) carrying ``stamp_ns``."""
    if not 0 <= stamp_ns < 1 << 64:
        raise BitstreamError(f"capture stamp {stamp_ns} ns does not fit an unsigned 64-bit field")
    payload = CAPTURE_STAMP_UUID.bytes + stamp_ns.to_bytes(8, "big")
    rbsp = _sei_varint(_SEI_USER_DATA_UNREGISTERED) + _sei_varint(len(payload)) + payload + b"\x80"
    return bytes([NalType.SEI]) + rbsp_to_ebsp(rbsp)


def insert_capture_stamp(access_unit: bytes, stamp_ns: int) -> bytes:
    """The access unit with our capture-time SEI in front of its first slice (after AUD/SPS/PPS/other SEI)."""
    nals = split_nal_units(access_unit)
    at = _first_vcl_index(nals)
    return join_nal_units([*nals[:at], capture_stamp_sei(stamp_ns), *nals[at:]])


def sei_messages(nal: bytes) -> list[tuple[int, bytes]]:
    """The ``(payloadType, payload)`` messages of one SEI NAL unit."""
    if nal_type(nal) != NalType.SEI:
        raise BitstreamError(f"not an SEI: nal_unit_type {nal[0] & 0x1F}")
    rbsp = ebsp_to_rbsp(nal[1:])
    out: list[tuple[int, bytes]] = []
    pos, n = 0, len(rbsp)
    while pos < n and rbsp[pos:] != b"\x80":  # more_rbsp_data(): anything before rbsp_trailing_bits
        ptype, pos = _read_sei_varint(rbsp, pos, "type")
        size, pos = _read_sei_varint(rbsp, pos, "size")
        if pos + size > n:
            raise BitstreamError(f"SEI payload of {size} bytes runs past the NAL unit")
        out.append((ptype, rbsp[pos : pos + size]))
        pos += size
    return out


def extract_capture_stamp(access_unit: bytes) -> int | None:
    """The capture time (ns) from our SEI in the access unit; None if it carries none.

    Other SEI messages (x264's version string, other vendors' user data) are skipped.
    """
    want = CAPTURE_STAMP_UUID.bytes
    for nal in split_nal_units(access_unit):
        if nal[0] & 0x1F != NalType.SEI:
            continue
        for ptype, payload in sei_messages(nal):
            if ptype == _SEI_USER_DATA_UNREGISTERED and len(payload) == 24 and payload[:16] == want:
                return int.from_bytes(payload[16:], "big")
    return None
