"""The simulated camera as its handlers see it (issue 38): the counters they advance are counted under the camera's
lock, and a persona names its parameter tree by a tag that sim/params.py resolves."""

from __future__ import annotations

import dataclasses
import threading

import pytest

from axis_ptz_ros2.sim.camera import SimulatedCamera
from axis_ptz_ros2.sim.params import TREE_BUILDERS, axis214_tree, modern_tree, parameter_tree
from axis_ptz_ros2.sim.persona import AXIS_214, AXIS_Q6075, Q6075_LIMITS, Q6075_ZOOM
from axis_ptz_ros2.sim.view import CameraView

pytestmark = pytest.mark.unit


@pytest.fixture(scope="module")
def camera() -> SimulatedCamera:
    return SimulatedCamera(port=0, rtsp_port=None)  # never started: no sockets


def test_counters_advanced_from_many_threads_lose_no_count(camera: SimulatedCamera) -> None:
    view: CameraView = camera
    frames0, snaps0 = camera.frames_sent, camera.snapshots_sent
    threads, per_thread = 8, 5000
    barrier = threading.Barrier(threads)
    stamps: list[list[int]] = [[] for _ in range(threads)]

    def work(i: int) -> None:
        barrier.wait()
        for _ in range(per_thread):
            view.count_frame_sent()
            stamps[i].append(view.count_snapshot())

    workers = [threading.Thread(target=work, args=(i,)) for i in range(threads)]
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    assert camera.frames_sent - frames0 == threads * per_thread
    assert camera.snapshots_sent - snaps0 == threads * per_thread
    # every snapshot got its own stamp (the image.cgi reply is stamped with it)
    all_stamps = [s for ss in stamps for s in ss]
    assert sorted(all_stamps) == list(range(snaps0 + 1, snaps0 + threads * per_thread + 1))
    state = camera.state_dict()
    assert (state["frames_sent"], state["snapshots_sent"]) == (camera.frames_sent, camera.snapshots_sent)


def test_a_persona_names_its_tree_by_tag() -> None:
    assert (AXIS_214.tree, AXIS_Q6075.tree) == ("axis214", "modern")
    assert {"axis214": axis214_tree, "modern": modern_tree} == TREE_BUILDERS
    lim, zoom = Q6075_LIMITS, Q6075_ZOOM
    tree = AXIS_Q6075.parameter_tree(lim, zoom, "00408C1A2B3C", "digest")
    assert tree == modern_tree(AXIS_Q6075, lim, zoom, "00408C1A2B3C", "digest")
    assert tree["Brand.ProdNbr"] == "Q6075-E"
    assert parameter_tree("axis214", AXIS_Q6075, lim, zoom, "00408C1A2B3C", "none")["Brand.ProdNbr"] == "214"


def test_an_unknown_tree_tag_is_refused() -> None:
    with pytest.raises(ValueError, match=r"persona axis214: unknown parameter tree 'q6000'; known: axis214, modern"):
        dataclasses.replace(AXIS_214, tree="q6000")  # type: ignore[arg-type]
    lim, zoom = Q6075_LIMITS, Q6075_ZOOM
    with pytest.raises(ValueError, match=r"unknown parameter tree 'q6000'"):
        parameter_tree("q6000", AXIS_Q6075, lim, zoom, "00408C1A2B3C", "none")
