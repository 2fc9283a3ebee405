"""The spin of every node process and of the test harness: survives an entity destroyed under it, blocks until
there is work, hands a callback's exception on; ``run_nodes`` processes stop cleanly on SIGINT/SIGTERM."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

pytest.importorskip("rclpy")

import rclpy  # noqa: E402
import rclpy.node  # noqa: E402
from rclpy.context import Context  # noqa: E402
from rclpy.exceptions import InvalidHandle  # noqa: E402
from rclpy.executors import MultiThreadedExecutor  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from axis_ptz_ros2.nodes.runner import Spinner, new_executor, retrieve_task_errors, spin_once  # noqa: E402
from tests.ros.processes import node_process  # noqa: E402
from tests.support.harness import DEADLINE_SCALE  # noqa: E402
from tests.support.waiting import unchanged_for, wait_until

pytestmark = pytest.mark.ros


def test_spin_once_survives_a_destroyed_event_handler_and_keeps_delivering():
    # The race a fresh-clone run hit (a subscription destroyed by another thread while the executor built its wait
    # set), made deterministic: one subscription's event handler is destroyed while the node still lists it.
    ctx = Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node("spin_probe", context=ctx)
    got: list[str] = []
    broken = node.create_subscription(String, "broken", lambda m: None, 1)
    node.create_subscription(String, "chatter", lambda m: got.append(m.data), 10)
    pub = node.create_publisher(String, "chatter", 10)
    executor = MultiThreadedExecutor(num_threads=2, context=ctx)
    executor.add_node(node)
    try:
        broken.event_handlers[0].destroy()
        with pytest.raises(InvalidHandle):  # what rclpy's own spin_once does: the caller's loop dies
            executor.spin_once(timeout_sec=0.01)
        spin_once(executor, 0.01)  # ours returns, so the loop goes on (the handler is still listed here)
        node.destroy_subscription(broken)  # what the destroying thread does next
        pub.publish(String(data="after"))
        for _ in range(200):
            spin_once(executor, 0.01)
            if got:
                break
        assert got == ["after"]
    finally:
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)


# ---------------------------------------------------------------------------------------------------------
# Spinner: the blocking spin of run_nodes and the test harness
# ---------------------------------------------------------------------------------------------------------
def _context_node(name: str) -> tuple[Context, rclpy.node.Node]:
    ctx = Context()
    rclpy.init(context=ctx)
    return ctx, rclpy.create_node(name, context=ctx)


def _wait(pred, timeout: float = 10.0) -> bool:  # noqa: ANN001
    return bool(wait_until(pred, timeout, raises=False))


def test_spinner_survives_a_destroyed_event_handler_and_keeps_delivering():
    ctx, node = _context_node("spinner_probe")
    got: list[str] = []
    broken = node.create_subscription(String, "broken", lambda m: None, 1)
    node.create_subscription(String, "chatter", lambda m: got.append(m.data), 10)
    pub = node.create_publisher(String, "chatter", 10)
    executor = new_executor(ctx)
    executor.add_node(node)
    broken.event_handlers[0].destroy()  # every wait-set build raises InvalidHandle until the subscription goes
    spinner = Spinner(executor, "test-spinner").start()
    try:
        assert _wait(lambda: executor.spins >= 5)  # the wait-set build failed on the broken handle, again and again
        assert spinner.alive()
        assert spinner.error is None
        node.destroy_subscription(broken)  # what the destroying thread does next
        executor.wake()
        pub.publish(String(data="after"))
        assert _wait(lambda: got == ["after"]), got
        assert spinner.alive()
        assert spinner.error is None
    finally:
        assert spinner.stop(2.0)
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)


def test_spinner_blocks_until_there_is_work_and_stops_at_once():
    # The cost this runner exists to remove: a spin_once(timeout) loop builds a new wait set ~10 times a second
    # with nothing to do. Count the wait-set generators rclpy creates while idle, then on one message.
    ctx, node = _context_node("spinner_idle")
    got: list[str] = []
    node.create_subscription(String, "chatter", lambda m: got.append(m.data), 10)
    pub = node.create_publisher(String, "chatter", 10)
    executor = new_executor(ctx)
    executor.add_node(node)
    builds = [0]
    original = executor._wait_for_ready_callbacks  # noqa: SLF001 - counting rclpy's own wait-set generators

    def counting(*a, **k):  # noqa: ANN002, ANN003, ANN202
        builds[0] += 1
        return original(*a, **k)

    executor._wait_for_ready_callbacks = counting  # type: ignore[method-assign] # noqa: SLF001
    spinner = Spinner(executor, "test-spinner").start()
    try:
        assert _wait(unchanged_for(lambda: builds[0], 0.3))  # settled (node added: a rebuild or two, then none)
        before = builds[0]
        time.sleep(1.5)  # a measuring window: the thing under test is how many wait sets are built in it
        assert builds[0] - before <= 1, f"{builds[0] - before} wait-set generators in 1.5 s with nothing to do"
        pub.publish(String(data="one"))
        assert _wait(lambda: got == ["one"])
    finally:
        t0 = time.monotonic()
        assert spinner.stop(2.0)
        assert time.monotonic() - t0 < 1.0
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)


def test_pool_executor_submits_each_callback_once_and_loses_no_message():
    # rclpy Jazzy's MultiThreadedExecutor re-submits a task still waiting in its pool at every wake-up
    # (ros2/rclpy#1452): 2,551 submissions a second for 20 Hz commands to the PTZ node. The PTZ node's shape:
    # commands and a 50 Hz timer in one mutually exclusive group, a second group beside it.
    from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
    from rclpy.qos import QoSProfile

    ctx, node = _context_node("pool_probe")
    commands = MutuallyExclusiveCallbackGroup()
    got: list[str] = []
    ticks = [0]

    def on_command(msg: String) -> None:
        time.sleep(0.003)  # the simulated work of a callback: a camera request
        got.append(msg.data)

    sub = node.create_subscription(String, "cmd", on_command, QoSProfile(depth=200), callback_group=commands)
    node.create_timer(0.02, lambda: ticks.__setitem__(0, ticks[0] + 1), callback_group=commands)
    node.create_timer(0.05, lambda: None, callback_group=MutuallyExclusiveCallbackGroup())
    pub_ctx, pub_node = _context_node("pool_probe_pub")
    pub = pub_node.create_publisher(String, "cmd", QoSProfile(depth=200))
    executor = new_executor(ctx)
    executor.add_node(node)
    spinner = Spinner(executor, "test-pool").start()
    try:
        assert _wait(lambda: pub.get_subscription_count() > 0 and sub.get_publisher_count() > 0)  # matched both ways
        before, ticks_before = executor.submitted, ticks[0]
        sent = [str(i) for i in range(150)]
        for text in sent:
            pub.publish(String(data=text))
            time.sleep(0.01)  # pace the commands (100 Hz) so that they interleave with the timer: the load under test
        assert _wait(lambda: len(got) == len(sent)), f"{len(got)} of {len(sent)} commands ran"
        assert got == sent
        callbacks = len(sent) + (ticks[0] - ticks_before) + 10  # + the 20 Hz timer's ticks at most
        submitted = executor.submitted - before
        assert submitted <= 2 * callbacks, f"{submitted} tasks submitted for about {callbacks} callbacks"
    finally:
        assert spinner.stop(2.0)
        node.destroy_node()
        pub_node.destroy_node()
        rclpy.try_shutdown(context=ctx)
        rclpy.try_shutdown(context=pub_ctx)


def test_pool_executor_waits_for_a_pool_thread_instead_of_spinning_on_a_handed_over_message():
    # Until a pool thread takes a handed-over task, its message stays in the reader, and rmw_fastrtps wakes the
    # wait set at once for it (the reader's status condition, attached for the subscription's QoS events) while
    # rclpy leaves the subscription out: an empty round after an empty round, ~2 a millisecond, holding the GIL
    # from the very pool thread that was to take the task (PTZ commands reached the camera 20-300 ms late, some
    # never). With every pool thread busy the spin must wait for one, and the message is not lost.
    from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
    from rclpy.qos import QoSProfile

    ctx, node = _context_node("pool_busy")
    got: list[str] = []
    release = threading.Event()
    busy = [0]

    def hold(_msg: String) -> None:
        busy[0] += 1
        release.wait(10.0)

    node.create_subscription(String, "hold", hold, QoSProfile(depth=10), callback_group=ReentrantCallbackGroup())
    commands = MutuallyExclusiveCallbackGroup()
    node.create_subscription(String, "cmd", lambda m: got.append(m.data), QoSProfile(depth=10), callback_group=commands)
    pub_ctx, pub_node = _context_node("pool_busy_pub")
    hold_pub = pub_node.create_publisher(String, "hold", QoSProfile(depth=10))
    cmd_pub = pub_node.create_publisher(String, "cmd", QoSProfile(depth=10))
    executor = new_executor(ctx)
    executor.add_node(node)
    spinner = Spinner(executor, "test-pool").start()
    try:
        assert _wait(lambda: hold_pub.get_subscription_count() > 0 and cmd_pub.get_subscription_count() > 0)
        for _ in range(4):  # every pool thread (new_executor: 4) blocked in a callback
            hold_pub.publish(String(data="hold"))
        assert _wait(lambda: busy[0] == 4)
        submitted = executor.submitted
        cmd_pub.publish(String(data="go"))
        assert _wait(
            lambda: executor.submitted > submitted
        )  # it arrived and is handed over; no pool thread can take it
        before = executor.spins
        time.sleep(1.0)  # a measuring window: the thing under test is how many wait-set rounds come in it
        rounds = executor.spins - before
        assert not got
        assert rounds <= 40, f"{rounds} wait-set rounds in 1 s while the task waited for a pool thread"
        release.set()
        assert _wait(lambda: got == ["go"]), got
    finally:
        release.set()
        assert spinner.stop(2.0)
        node.destroy_node()
        pub_node.destroy_node()
        rclpy.try_shutdown(context=ctx)
        rclpy.try_shutdown(context=pub_ctx)


def test_pool_executor_resumes_a_coroutine_callback_after_its_await():
    # A task that is not queued any more (a coroutine waiting on a future) must still be handed out again.
    from rclpy.task import Future

    ctx, node = _context_node("pool_coroutine")
    executor = new_executor(ctx)
    done = Future(executor=executor)
    results: list[str] = []

    async def on_message(msg: String) -> None:
        results.append("started")
        results.append(await done)

    node.create_subscription(String, "go", on_message, 10)
    pub = node.create_publisher(String, "go", 10)
    executor.add_node(node)
    spinner = Spinner(executor, "test-pool").start()
    try:
        assert _wait(lambda: pub.get_subscription_count() > 0)
        pub.publish(String(data="x"))
        assert _wait(lambda: results == ["started"])
        done.set_result("resumed")
        executor.wake()
        assert _wait(lambda: results == ["started", "resumed"]), results
    finally:
        assert spinner.stop(2.0)
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)


def test_spinner_hands_a_callback_exception_to_its_owner():
    ctx, node = _context_node("spinner_error")

    def fail(_msg: String) -> None:
        raise RuntimeError("callback bug")

    node.create_subscription(String, "boom", fail, 10)
    pub = node.create_publisher(String, "boom", 10)
    executor = new_executor(ctx)
    executor.add_node(node)
    spinner = Spinner(executor, "test-spinner").start()
    try:
        assert _wait(lambda: pub.get_subscription_count() > 0)
        pub.publish(String(data="x"))
        assert _wait(lambda: spinner.error is not None or not spinner.alive())
        executor.wake()  # the failed task is fetched on the spin's next pass
        assert _wait(lambda: not spinner.alive())
        assert isinstance(spinner.error, RuntimeError)
    finally:
        spinner.stop(2.0)
        retrieve_task_errors(executor)
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)


# ---------------------------------------------------------------------------------------------------------
# run_nodes in a real process: signals, clean exit, nothing left unreported
# ---------------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def camera():
    from axis_ptz_ros2.sim.camera import SimulatedCamera

    cam = SimulatedCamera(port=0).start()
    yield cam
    cam.stop()


def _read_until(proc: subprocess.Popen[bytes], pattern: bytes, timeout: float) -> bytes:
    """Output of ``proc`` until ``pattern`` appears (or the timeout; the caller checks)."""
    import selectors

    out = b""
    sel = selectors.DefaultSelector()
    assert proc.stdout is not None
    sel.register(proc.stdout, selectors.EVENT_READ)
    deadline = time.monotonic() + timeout * DEADLINE_SCALE
    while pattern not in out and time.monotonic() < deadline and proc.poll() is None:
        if sel.select(0.1):
            chunk = os.read(proc.stdout.fileno(), 65536)
            if not chunk:
                break
            out += chunk
    sel.close()
    return out


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_axis_camera_stops_cleanly_within_2_s_and_ignores_a_second_signal(camera, sig, ros):
    exe = Path(sys.executable).parent / "axis_camera"
    argv = [str(exe), "--ros-args", "-r", f"__ns:=/spin_{sig.name.lower()}", "-p", f"port:={camera.port}"]
    with node_process(argv) as proc:
        out = _read_until(proc, b"PTZ node up", 30.0)
        assert b"PTZ node up" in out, out.decode(errors="replace")[-2000:]
        # a service answer comes from its executor: it spins (the signal must come while it does)
        from axis_ptz_interfaces.srv import ListPresets  # noqa: PLC0415

        client = ros.probe().create_client(ListPresets, f"/spin_{sig.name.lower()}/ptz/list_presets")
        ros.query(client, ListPresets.Request(), timeout=10.0)
        t0 = time.monotonic()
        proc.send_signal(sig)
        proc.send_signal(sig)  # an impatient second signal (spinning: a flag; in clean-up: ignored) changes nothing
        code = proc.wait(10)
        took = time.monotonic() - t0
        assert proc.stdout is not None
        rest = proc.stdout.read().decode(errors="replace")
    text = out.decode(errors="replace") + rest
    assert code == 0, text[-3000:]
    assert took <= 2.0, f"exit took {took:.2f} s"
    for bad in ("Traceback", "never retrieved", "Fatal Python error", "cannot use Destroyable"):
        assert bad not in text, text[-3000:]


HANGING_CLEAN_UP = """
import sys, threading
import rclpy.node
from axis_ptz_ros2.nodes import runner

class Stuck(rclpy.node.Node):
    def __init__(self):
        super().__init__("stuck_clean_up")
        print("up", flush=True)
        self._ticked = False
        self.create_timer(0.05, self._tick)

    def _tick(self):  # a timer callback runs: the executor spins
        if not self._ticked:
            self._ticked = True
            print("spinning", flush=True)

    def destroy_node(self):
        threading.Event().wait()  # a clean-up that never returns (a join on a thread that never ends)

runner.EXIT_WITHIN_S = 1.5
sys.exit(runner.run_nodes([Stuck], sys.argv))
"""


def test_a_clean_up_that_hangs_ends_the_process_with_every_threads_stack_in_the_log():
    """A hung clean-up must not hold the process until whoever stopped it kills it (with nothing in the log, as a
    CI run's web console did): past EXIT_WITHIN_S the process prints every thread's stack and exits 1."""
    with node_process([sys.executable, "-c", HANGING_CLEAN_UP, "--ros-args", "-r", "__ns:=/spin_hang"]) as proc:
        out = _read_until(proc, b"spinning", 30.0)  # the signal must come while it spins
        assert b"spinning" in out, out.decode(errors="replace")[-2000:]
        t0 = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        code = proc.wait(10)
        took = time.monotonic() - t0
        assert proc.stdout is not None
        text = (out + proc.stdout.read()).decode(errors="replace")
    assert code == 1, text[-3000:]
    assert 1.5 <= took < 5.0, f"ended {took:.2f} s after the signal"
    assert "Timeout (0:00:01.500000)!" in text, text[-3000:]  # faulthandler's dump, every thread
    assert "in destroy_node" in text, text[-3000:]  # the stack names where it hung


def test_a_stop_signal_raises_once_while_nodes_are_built_and_a_second_one_only_sets_the_flag():
    """A CI run's ``axis_panorama_sim`` exited 1 with a ``_Stop`` traceback: the process group's SIGINT raised the
    stop while the node was being built, and a second signal, landing as the clean-up started (before the handlers
    were set to ignore), raised again inside it. Only the first signal may raise."""
    from axis_ptz_ros2.nodes.runner import _Signals, _Stop  # noqa: PLC0415

    signals = _Signals()
    with pytest.raises(_Stop):
        signals._on_signal(signal.SIGINT, None)
    assert signals.stop.is_set()
    assert signals.wake.is_set()
    signals._on_signal(signal.SIGINT, None)  # the second: no raise, the flag stays set
    signals._on_signal(signal.SIGTERM, None)
    assert signals.stop.is_set()
    spinning = _Signals()
    spinning.spinning = True
    spinning._on_signal(signal.SIGTERM, None)  # once spinning, never a raise (only the flag and the wake-up)
    assert spinning.stop.is_set()
    assert spinning.wake.is_set()
