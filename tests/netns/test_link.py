"""The robot streaming to the operator over a weak link (issue 13), fast versions: conditions, not timings.
Figures (frame age percentiles, rates, recovery times) are in ``bench/bench_link.py``."""

from __future__ import annotations

import time
from pathlib import Path

from tests.netns.conftest import TwoHosts, host_env, wait_for

# The camera asked for the most it can do; no budget set by hand: the link feedback has to find the rate.
FULL = ["-p", "fps:=30", "-p", "resolution:=704x576", "-p", "compression:=30"]
# what the README tells a user to run on both hosts of a weak link
PROFILE = str(Path(__file__).resolve().parents[2] / "config" / "fastdds_weak_link.xml")


LINK_KBPS = 1000


def _degraded(params: dict) -> bool:
    return params["source"] == "bandwidth_budget" and (
        params["fps"] < 30 or params["resolution"] != "704x576" or params["compression"] > 30
    )


def test_feedback_lowers_the_stream_on_a_narrow_lossy_link_and_frames_keep_arriving(two_hosts: TwoHosts) -> None:
    # everything starts on the narrow lossy link: discovery, then a 704x576 @ 30 stream (~9 Mbit/s) into 1 Mbit/s
    two_hosts.link.set_rate(LINK_KBPS)
    two_hosts.link.set_loss(2)
    env = host_env(FASTRTPS_DEFAULT_PROFILES_FILE=PROFILE)
    two_hosts.start_robot(FULL, env=env)
    probe = two_hosts.probe(env=env)  # the operator's viewer: reports what it receives on video/feedback
    wait_for(lambda: probe.of("image"), 120, "the first image over the narrow lossy link", two_hosts)
    # the budget in effect comes from the link feedback (none was set by hand) and lowers the stream. Not asserted:
    # that the budget itself ends under the link's rate. On the demo world's detailed home view (issue 22) the
    # adapter can sit at 1469 kbit/s on this 1000 kbit/s link, the stream at 176x144 @ 15 (~570 kbit/s) under
    # it, probing up to 352x288 (2938, ~2.2 Mbit/s) and back every ~10 s (one full test run in two at 25404ae;
    # README, "The new home view")
    try:
        wait_for(
            lambda: [p for p in probe.of("video/params") if _degraded(p) and p["budget"] > 0],
            120,
            "the stream to step down by the link's feedback",
            two_hosts,
        )
    except AssertionError as err:  # say what the operator did see, for whoever reads the failure
        seen = probe.of("video/params")[-5:]
        raise AssertionError(
            f"{err}; last video/params at the operator: {seen}; images received: {len(probe.of('image'))}"
        ) from None
    # frames keep arriving at the operator after the adaptation, each one the camera's (stamped, in order)
    t0 = time.time_ns()
    wait_for(lambda: len(probe.of("image", t0)) >= 20, 90, "frames over the narrow link", two_hosts)
    frames = probe.of("image", t0)
    sent = [r["sim"] for r in frames]  # the simulator's send stamps (its seq restarts with every connection)
    assert sent == sorted(set(sent)), "no frame twice, none out of order"


def test_no_stale_frame_is_delivered_after_a_cut(two_hosts: TwoHosts) -> None:
    two_hosts.link.set_rate(2000)
    two_hosts.link.set_loss(2)
    env = host_env(FASTRTPS_DEFAULT_PROFILES_FILE=PROFILE)
    two_hosts.start_robot(FULL, env=env)
    probe = two_hosts.probe(env=env)
    wait_for(lambda: len(probe.of("image")) >= 20, 120, "frames over the shaped lossy link", two_hosts)

    two_hosts.link.set_up(False)
    cut = time.time_ns()
    time.sleep(5.0)  # the camera keeps sending on the robot; nothing can cross
    heal = time.time_ns()
    two_hosts.link.set_up(True)
    wait_for(lambda: len(probe.of("image", heal)) >= 10, 90, "video after the heal", two_hosts)

    after = probe.of("image", heal)
    # a frame captured during the cut (more than half a second before the heal) delivered after it would be
    # a backlog of stale video; the newest frame replaces older ones, so none may arrive
    stale = [r for r in after if r["sim"] < heal - 500_000_000]
    oldest = (heal - min((r["sim"] for r in stale), default=heal)) / 1e9
    assert not stale, f"{len(stale)} frames from the cut delivered after the heal, oldest sent {oldest:.1f} s before"
    # frames received during the cut were sent before it (in flight or buffered when the link went down): one
    # the camera sent after the cut could only have crossed a down link (judged by the camera's own send stamp,
    # not by when the operator's callback ran)
    during = [r for r in probe.of("image", cut) if r["rx"] < heal]
    crossed = [(r["sim"] - cut) / 1e9 for r in during if not 0 < r["sim"] < cut]
    assert not crossed, f"frames sent this many s after the cut arrived over a link that was down: {crossed}"
