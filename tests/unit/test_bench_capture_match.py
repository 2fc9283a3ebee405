"""bench/capture_match.py: a transcoded picture (stamped by the stream node with its JPEG's arrival) is matched to
the simulator's send of that JPEG, so the benches measure capture-to-display without the product reading the
simulator's comment (issue 38 item 3)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))

from capture_match import log_sends, match, rekey  # noqa: E402

pytestmark = pytest.mark.unit

MS = 1_000_000
T0 = 1_700_000_000_000_000_000
SENDS = [T0 + k * 40 * MS for k in range(20)]  # 25 pictures a second


def test_each_picture_is_matched_to_the_last_send_before_its_stamp() -> None:
    pics = [(k, SENDS[k] + 2 * MS) for k in range(20)]  # stamped 2 ms after its send
    assert match(pics, SENDS) == SENDS
    assert match(pics, list(reversed(SENDS))) == SENDS  # the log's order does not matter


def test_a_reader_behind_the_camera_is_put_back_on_its_own_jpeg() -> None:
    # the JPEG sent 5th was stamped only after the 6th had been sent (a loaded machine): by time alone both
    # pictures would be the 6th's; the pts order says picture 4 came from a JPEG before picture 5's
    pics = [(3, SENDS[3] + MS), (4, SENDS[5] + MS), (5, SENDS[5] + 3 * MS), (6, SENDS[6] + MS)]
    assert match(pics, SENDS) == [SENDS[3], SENDS[4], SENDS[5], SENDS[6]]


def test_pictures_lost_or_jpegs_not_transcoded_keep_their_own_sends() -> None:
    # pts 10 and 11 consecutive though JPEGs were skipped between them (stage inactive); 12 lost on the way
    pics = [(10, SENDS[2] + MS), (11, SENDS[7] + MS), (13, SENDS[9] + MS)]
    assert match(pics, SENDS) == [SENDS[2], SENDS[7], SENDS[9]]


def test_a_pts_counted_without_a_jpeg_does_not_shift_every_earlier_picture() -> None:
    # pictures 0-14 each 2 ms after their own JPEG, then a pts counted twice for one JPEG (two access units of it):
    # by the pts order alone every earlier picture would move one JPEG back (their lag 42 ms: a frame off); the
    # bulk moved back is refused and the time decides
    pics = [(k, SENDS[k] + 2 * MS) for k in range(15)] + [(16, SENDS[15] + 2 * MS), (17, SENDS[15] + 30 * MS)]
    got = match(pics, SENDS)
    assert got[:16] == SENDS[:16]
    # one picture behind the camera is still put back (the test above): a minority moved is kept
    pics = [(3, SENDS[3] + MS), (4, SENDS[5] + MS), (5, SENDS[5] + 3 * MS), (6, SENDS[6] + MS)]
    assert match(pics, SENDS) == [SENDS[3], SENDS[4], SENDS[5], SENDS[6]]


def test_no_send_before_the_stamp_and_pictures_without_pts() -> None:
    assert match([(0, T0 - MS)], SENDS) == [None]
    # without pts (-1) only time is used: nothing is moved by an order it does not have
    pics = [(-1, SENDS[4] + MS), (-1, SENDS[5] + MS)]
    assert match(pics, SENDS) == [SENDS[4], SENDS[5]]


def test_rekey_moves_the_stamp_aside_and_renames_saved_pictures(tmp_path: Path) -> None:
    stamp = SENDS[3] + 2 * MS
    np.save(tmp_path / f"{stamp}.npy", np.zeros((2, 2), np.uint8))
    recs = [{"pts": 3, "cap": stamp, "saved": True}, {"pts": 4, "cap": 0}]
    text = rekey(recs, SENDS, tmp_path)
    assert recs[0]["cap"] == SENDS[3]
    assert recs[0]["stamp"] == stamp
    assert recs[1]["cap"] == 0  # no capture stamp: left alone
    assert (tmp_path / f"{SENDS[3]}.npy").exists()
    assert not (tmp_path / f"{stamp}.npy").exists()
    assert "1 pictures matched" in text
    assert "median 2.0 ms" in text


def test_log_sends_reports_what_the_simulator_writes_into_each_jpeg(monkeypatch: pytest.MonkeyPatch) -> None:
    import axis_ptz_ros2.sim.http.mjpeg as mjpeg_side
    from axis_ptz_ros2.sim.renderer import encode_jpeg
    from tests.support.stamps import sim_stamp

    monkeypatch.setattr(mjpeg_side, "stamp", mjpeg_side.stamp)  # restored after the test
    got: list[tuple[int, int, str]] = []
    log_sends(lambda seq, t, conn: got.append((seq, t, conn)))
    jpeg = encode_jpeg(np.zeros((16, 16, 3), np.uint8), 50)
    outs = [mjpeg_side.stamp(jpeg, seq) for seq in (1, 2, 1)]  # a second connection on the same thread
    assert [g[:2] for g in got] == [sim_stamp(o) for o in outs]
    assert got[0][2] == got[1][2] != got[2][2]


def test_only_the_connection_the_pictures_follow_is_searched() -> None:
    # a second stream (the MJPEG ladder beside the compression-0 one, 5/s, out of step) sends 3 ms before some
    # pictures' stamps: searched with the rest, it would be taken for their JPEG
    ladder = [T0 + k * 200 * MS + 41 * MS for k in range(4)]
    pics = [(k, SENDS[k] + 4 * MS) for k in range(20)]
    assert SENDS[1] + 4 * MS - ladder[0] == 3 * MS  # (the trap)
    assert match(pics, {"a.0": SENDS, "b.0": ladder}) == SENDS
    assert match(pics, SENDS + ladder) != SENDS  # all sends together: wrong
