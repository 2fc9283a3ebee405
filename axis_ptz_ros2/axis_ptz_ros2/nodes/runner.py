"""The runner: executors that spin each node in a thread of its own, and the process's start/stop order.

Two rclpy Jazzy defects are worked around here, each with the measurement that showed it:

* ``MultiThreadedExecutor`` re-submits a task that is still waiting in its thread pool's queue every time its
  wait set wakes, and each wake then comes at once (ros2/rclpy#1452, fixed upstream after the Jazzy wheels):
  under 20 Hz ``ptz/cmd/absolute`` commands the PTZ node's executor made ~2,500 submissions a second with 320
  queued, and a stream node with a second callback group queued thousands of no-op tasks that failed with
  ``InvalidHandle`` at shutdown and held its exit. :class:`PoolExecutor` submits a task once while it waits.
* ``Executor.shutdown`` does not wait for work in flight, and rclpy's signal handler shuts the context down
  inside the signal (see :func:`run_nodes`).
* While a handed-over task waits for a pool thread, its message stays in the reader and every wait returns at
  once with nothing ready (rmw_fastrtps wakes on the reader's status condition, rclpy leaves the subscription
  out): ~8,500 empty rounds a second that hold the GIL from the pool thread meant to take the task. 20 Hz PTZ
  commands reached the camera with a median of 31-54 ms (up to 300 ms) and 2-19 of 100 were dropped by the
  reader's KEEP_LAST 5; :class:`PoolExecutor` waits (GIL released) until a pool thread has taken the task:
  3.3 ms, none dropped.
"""

from __future__ import annotations

import faulthandler
import inspect
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

import rclpy
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.context import Context
from rclpy.exceptions import InvalidHandle
from rclpy.executors import (
    ConditionReachedException,
    Executor,
    ExternalShutdownException,
    MultiThreadedExecutor,
    ShutdownException,
    SingleThreadedExecutor,
    TimeoutException,
)
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import get_default_context


def wait_for_running_callbacks(executor: Executor, timeout: float) -> bool:
    """After ``executor.shutdown()``: wait (at most ``timeout`` s) until no callback is still running.

    rclpy Jazzy's ``Executor.shutdown`` sets its shutdown flag and then skips its own wait for outstanding work
    (the wait is guarded by that same flag), and ``MultiThreadedExecutor`` never stops its thread pool. A callback
    dispatched just before the shutdown can therefore still run while the caller destroys its node and the
    context: at best "cannot use Destroyable" errors, at worst a crash inside rcl. The executor's list of
    dispatched tasks is private, so this reads it defensively; True if nothing is left running.
    """
    tasks = getattr(executor, "_futures", None)
    if not isinstance(tasks, list):
        return True
    deadline = time.monotonic() + timeout
    while any(not t.done() for t in list(tasks)):
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.01)
    return True


def retrieve_task_errors(executor: Executor, logger_name: str = "axis_ptz_ros2") -> int:
    """After the spin has ended: fetch (and log) the exception of every finished callback that nobody fetched.

    ``MultiThreadedExecutor`` fetches a callback's exception only on its next ``spin_once``; a callback that
    failed while the spin ended (typically on a handle destroyed at shutdown) would otherwise print "The following
    exception was never retrieved" from rclpy's ``Future.__del__`` at interpreter exit. Returns how many."""
    tasks = getattr(executor, "_futures", None)
    if not isinstance(tasks, list):
        return 0
    seen: dict[str, int] = {}
    for t in list(tasks):
        if t.done():
            err = t.exception()  # marks it fetched
            if err is not None:
                text = f"{type(err).__name__}: {err}"
                seen[text] = seen.get(text, 0) + 1
    tasks.clear()
    for text, count in seen.items():  # one line per distinct failure: a stop must not flood the log
        times = f" ({count} callbacks)" if count > 1 else ""
        rclpy.logging.get_logger(logger_name).warning(f"a callback failed while the executor stopped{times}: {text}")
    return sum(seen.values())


def spin_once(executor: Executor, timeout_sec: float | None) -> None:
    """``executor.spin_once``, surviving an entity destroyed by another thread while the executor built its wait set.

    rclpy Jazzy adds every subscription's event handler to the wait set without a guard, so a subscription that a
    callback destroys meanwhile (the web console's and the republisher's lazy subscriptions, a calibration capture
    closing) raises ``InvalidHandle`` out of ``spin_once``: a fresh-clone test run lost its whole spin thread that
    way. The failed wait-set generator is finished, so the next call builds a new one without the destroyed entity.
    """
    try:
        executor.spin_once(timeout_sec=timeout_sec)
    except InvalidHandle:
        if not executor.context.ok():
            raise


#: how long :class:`PoolExecutor`'s spin waits for a pool thread to take a task it handed over (s)
TAKE_WAIT_S = 0.05


class PoolExecutor(MultiThreadedExecutor):
    """rclpy's ``MultiThreadedExecutor`` with one change: a task still waiting in the thread pool's queue is not
    submitted again.

    Jazzy's ``_wait_for_ready_callbacks`` yields every task that is "not executing and not done", which includes
    one that was handed to the pool and has not started yet; ``_spin_once_impl`` then submits it again, and the
    next wake-up (every callback that runs triggers two) yields it again. The copies do nothing (``Task.__call__``
    returns at once for a task already running or done) but the queue and the wake-ups grow with each other:
    2,551 submissions a second and 320 queued for 20 Hz commands to the PTZ node (upstream: ros2/rclpy#1452).
    Here a task is submitted once; it is yielded again only after a pool thread has taken it, which is what a
    coroutine task resuming after an ``await`` needs. Everything else is rclpy's own code path.
    """

    def __init__(self, num_threads: int, *, context: Context | None = None) -> None:
        super().__init__(num_threads=num_threads, context=context)
        self._queued: set[Any] = set()  # tasks handed to the pool that no pool thread has taken yet
        self._taken = threading.Condition()  # notified when a pool thread takes a task (guards ``_queued``)
        self.submitted = 0  # tasks handed to the pool (a counter for tests and benches)
        self.spins = 0  # wait-set rounds (a counter for tests: no round may come back at once, empty-handed)

    def _spin_once_impl(
        self,
        timeout_sec: float | Any | None = None,
        wait_condition: Callable[[], bool] = lambda: False,
    ) -> None:
        self.spins += 1
        try:
            handler = self.wait_for_ready_callbacks(timeout_sec, None, wait_condition)[0]
        except (ExternalShutdownException, ShutdownException, TimeoutException, ConditionReachedException):
            return
        with self._taken:
            queued = handler in self._queued
            self._queued.add(handler)
        if not queued:
            self.submitted += 1
            self._executor.submit(self._run_task, handler)
            self._futures.append(handler)
        # Until a pool thread has taken it, the task's message is still in its reader, and rmw_fastrtps wakes the
        # wait set at once for it (the reader's status condition, attached for the subscription's QoS events)
        # while rclpy leaves the subscription itself out: every wait returns with nothing ready. That loop holds
        # the GIL so often that the pool thread waiting for it started the callback 20-300 ms late (PTZ commands
        # at 20 Hz: median 42 ms to the camera and 14 of 100 dropped by the reader's KEEP_LAST 5). So wait here,
        # with the GIL released, until a pool thread has taken it (at most ``TAKE_WAIT_S``: with every pool
        # thread busy the task waits for one, and the spin goes on).
        with self._taken:
            self._taken.wait_for(lambda: handler not in self._queued, timeout=TAKE_WAIT_S)
        for future in self._futures[:]:  # as rclpy: forget finished tasks, raise a callback's exception
            if future.done():
                self._futures.remove(future)
                future.result()

    def _run_task(self, task: Any) -> None:
        with self._taken:
            self._queued.discard(task)
            self._taken.notify_all()
        task()


def new_executor(context: Context | None = None) -> PoolExecutor:
    """A multi-threaded executor (:class:`PoolExecutor`): callbacks run in a pool of threads, for nodes whose
    callback groups let callbacks run at the same time (the PTZ node's motion services and ``ptz/move`` goals
    block until the head arrives, and a cancel or a topic command must get through meanwhile)."""
    return PoolExecutor(num_threads=4, context=context)


def callbacks_serialised(node: Node) -> bool:
    """True if every callback of ``node`` is in its default, mutually exclusive callback group (checked over the
    entities it has now): a multi-threaded executor then runs them one at a time anyway. A coroutine callback
    (``async def``) in a group of its own does not count against it: it never holds a thread while it awaits
    (the stream node's ``still/capture`` answers once a worker thread has fetched the still), and a
    single-threaded executor resumes it as well as a pool would."""
    group = node.default_callback_group
    if not isinstance(group, MutuallyExclusiveCallbackGroup):
        return False
    entities: list[Any] = [
        *node.subscriptions,
        *node.timers,
        *node.clients,
        *node.services,
        *node.guards,
        *node.waitables,
    ]
    return all(
        getattr(e, "callback_group", group) is group or inspect.iscoroutinefunction(getattr(e, "callback", None))
        for e in entities
    )


def executor_for(node: Node, context: Context | None = None) -> Executor:
    """The executor for one node: single-threaded when its callbacks run one at a time anyway
    (:func:`callbacks_serialised`), else :func:`new_executor`.

    Same semantics, a third of the cost per callback: ``MultiThreadedExecutor`` hands every callback to a pool
    thread and wakes up twice more to rebuild its wait set (once when the pool thread has taken the message, once
    when it is done), where ``SingleThreadedExecutor`` runs it in place. The stream node's 20 Hz ``ptz/state``
    subscription cost 5.8 % of a core on the multi-threaded executor and 2.4 % on the single-threaded one
    (bench/bench_cpu.py's numbers, loaded machine). A node that later adds a callback group of its own would
    run that group's callbacks one at a time too: such a node must create its groups in its constructor.
    """
    if callbacks_serialised(node):
        return SingleThreadedExecutor(context=context)
    return new_executor(context)


class Spinner:
    """Spins an executor in a thread of its own, blocking until there is work (no periodic wake-ups).

    Why not ``spin_once(timeout)`` in a loop: rclpy builds a new wait set of every entity of every node on each
    call, and a timeout also creates (and destroys) an rcl timer each time; ten idle wake-ups a second cost a
    composed process a few percent of a core. Blocking ``spin()`` wakes only for work; :meth:`stop` (the
    executor's shutdown) wakes it to end. An ``InvalidHandle`` from an entity destroyed under the wait-set
    build (see :func:`spin_once`) does not end the spin, and an exception from a callback is kept in
    :attr:`error` for the owner to raise."""

    def __init__(self, executor: Executor, name: str = "executor", on_end: Callable[[], None] | None = None) -> None:
        """``on_end`` is called in the spin thread when it ends, however it ends (the owner's wake-up)."""
        self.executor = executor
        self.error: BaseException | None = None
        self._stopping = False
        self._on_end = on_end
        self.thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> Spinner:
        self.thread.start()
        return self

    def _run(self) -> None:
        ctx = self.executor.context
        try:
            while ctx.ok() and not self._stopping:
                try:
                    self.executor.spin()  # returns once the executor is shut down or the context is
                    return
                except InvalidHandle:
                    if not ctx.ok():
                        return
                except ExternalShutdownException:
                    return
        except BaseException as err:  # noqa: BLE001 - handed to the owner (a callback's exception ends the spin)
            if not self._stopping and ctx.ok():
                self.error = err
        finally:
            if self._on_end is not None:
                self._on_end()

    def alive(self) -> bool:
        return self.thread.is_alive()

    def stop(self, timeout: float = 2.0) -> bool:
        """Shut the executor down (wakes the spin) and join the thread; True if it ended in time."""
        self._stopping = True
        self.executor.shutdown(timeout_sec=0.0)
        if self.thread.ident is not None:
            self.thread.join(timeout)
        return not self.thread.is_alive()

    def wait_idle(self, timeout: float) -> bool:
        """After :meth:`stop`: wait until no callback runs any more (in the spin thread itself for a
        single-threaded executor, in the pool for a multi-threaded one); True if none does."""
        deadline = time.monotonic() + timeout
        if self.thread.ident is not None:
            self.thread.join(timeout)
        return wait_for_running_callbacks(self.executor, max(0.0, deadline - time.monotonic())) and (
            not self.thread.is_alive()
        )


class _Stop(BaseException):
    """SIGINT/SIGTERM while a :func:`run_nodes` process builds its nodes (a BaseException, like KeyboardInterrupt)."""


class _Signals:
    """SIGINT/SIGTERM for :func:`run_nodes`: raise while nodes are being built (a constructor may wait on the
    camera), only set a flag once spinning (and :attr:`wake` the main thread). An exception raised inside the
    executor's own code could leave its state or a lock half-done; the flag cannot."""

    def __init__(self) -> None:
        self.stop = threading.Event()
        #: what the main thread waits on: a stop signal, a spin thread ending or the context shutting down
        self.wake = threading.Event()
        self.spinning = False
        #: a stop was raised once already: a second signal (a group's SIGINT and the launcher's, or one that
        #: lands while the first one's clean-up starts) only sets the flag, so it never cuts the clean-up short
        self.raised = False
        self.previous: dict[int, Any] = {}

    def install(self) -> None:
        if threading.current_thread() is threading.main_thread():  # signal handlers live in the main thread
            for sig in (signal.SIGINT, signal.SIGTERM):
                self.previous[sig] = signal.signal(sig, self._on_signal)

    def _on_signal(self, signum: int, frame: Any) -> None:
        self.stop.set()
        self.wake.set()
        if not self.spinning and not self.raised:
            self.raised = True
            raise _Stop(signum)

    def ignore(self) -> None:
        """During clean-up: a second signal must not cut it short."""
        for sig in self.previous:
            signal.signal(sig, signal.SIG_IGN)

    def restore(self) -> None:
        """After clean-up. Once a stop signal came the process is ending: the signals stay ignored, because the
        interpreter resets Python-level handlers to SIG_DFL while it finalises, and the second SIGINT of a
        Ctrl-C under ``ros2 launch`` (terminal and launch both signal) then killed it (exit -2)."""
        if self.stop.is_set():
            return
        for sig, handler in self.previous.items():
            signal.signal(sig, handler)


#: the longest a :func:`run_nodes` process takes to end once its clean-up starts (s): past it, every thread's stack
#: goes to stderr and the process exits 1. Clean-up takes well under 1 s; the web console may wait up to 3 s for
#: its HTTP clients. ``ros2 launch`` sends SIGTERM 5 s after its SIGINT and SIGKILL 5 s later: this comes first.
EXIT_WITHIN_S = 8.0


def run_nodes(factories: Sequence[Callable[[], Node]], args: Sequence[str] | None = None) -> int:
    """Create nodes in one process and spin them until SIGINT/SIGTERM or shutdown.

    Each node has an executor of its own (:func:`executor_for`: a wake-up rebuilds the wait set of one node's
    entities, not of every node in the process, and one node's blocking callbacks never hold up another's),
    spinning in a thread of its own and blocking until there is work (:class:`Spinner`); the main thread only
    sleeps until a signal, a spin ending or the context going wakes it (no periodic wake-up).
    Shutdown order: the executor stops, callbacks still running finish, every node is destroyed (joining its
    threads) while the context is still valid, and only then the context is shut down. rclpy's own signal
    handler is not installed: it shuts the context down inside the signal, so nodes would be destroyed after it,
    and destroying a publisher of a shut-down context crashed ``axis_visualizer`` with SIGSEGV in a CI run
    (faulthandler's trace: ``Publisher.destroy`` in ``destroy_node``). Our handlers (:class:`_Signals`) only set
    a flag once spinning; a second signal is ignored during clean-up. A clean-up that hangs ends the process
    after :data:`EXIT_WITHIN_S` with every thread's stack on stderr (exit 1).
    """
    if not faulthandler.is_enabled():  # a crash in native code leaves every thread's Python stack in the log
        faulthandler.enable()
    signals = _Signals()
    nodes: list[Node] = []
    spinners: list[Spinner] = []
    code = 0
    try:
        signals.install()
        rclpy.init(args=list(args) if args is not None else sys.argv, signal_handler_options=SignalHandlerOptions.NO)
        for f in factories:
            n = f()
            nodes.append(n)
            # one executor per node: a wake-up (a message, a timer) rebuilds the wait set of that node's entities
            # only, and one node's blocking callbacks never hold up another's
            executor = executor_for(n)
            executor.add_node(n)
            spinners.append(Spinner(executor, f"executor:{n.get_name()}", on_end=signals.wake.set))
        context = get_default_context()
        context.on_shutdown(signals.wake.set)
        signals.spinning = True
        for s in spinners:
            s.start()
        # The main thread sleeps until woken (a signal's handler runs here and sets the event; a blocked lock
        # wait is interrupted for it): no periodic wake-up, which took the GIL from the reader 10 times a second.
        # The 1 s timeout is only a safety net.
        while context.ok() and not signals.stop.is_set() and all(s.alive() for s in spinners):
            signals.wake.wait(1.0)
        for s in spinners:
            if s.error is not None:
                raise s.error
    except (_Stop, KeyboardInterrupt, ExternalShutdownException):
        pass
    except ValueError as err:  # start-up configuration errors: say why, exit non-zero
        print(f"error: {err}", file=sys.stderr)  # noqa: T201
        code = 2
    finally:
        signals.ignore()
        # The process is ending. A clean-up (or the interpreter's exit after it: it joins the executors' pool
        # threads) that hangs would hold it until whoever stopped it kills it, with nothing in the log: after
        # EXIT_WITHIN_S every thread's stack goes to stderr and the process exits 1. Never cancelled: the timer
        # ends with the process.
        faulthandler.dump_traceback_later(EXIT_WITHIN_S, exit=True)
        try:
            for s in spinners:
                s.stop(timeout=1.0)
            deadline = time.monotonic() + 2.0
            for s in spinners:
                s.wait_idle(max(0.0, deadline - time.monotonic()))
            for n in nodes:
                n.destroy_node()
            for s in spinners:
                retrieve_task_errors(s.executor)
            rclpy.try_shutdown()
        finally:
            signals.restore()
    return code


def close_own_loop(executor: Executor, node: Node | None) -> None:
    """The end of a node that spins its own loop (the teleops): off its executor and destroyed (if it was made),
    then the executor and the context shut down."""
    if node is not None:
        executor.remove_node(node)
        node.destroy_node()
    executor.shutdown(timeout_sec=1.0)
    rclpy.try_shutdown()
