"""A signal's shutdown runs beside the main thread, not inside it (assign5/signals.py)."""
from __future__ import annotations

import os
import signal
import threading

from assign5.signals import shutdown_elsewhere


def test_a_signal_landing_while_the_main_thread_holds_a_lock_does_not_deadlock_the_shutdown():
    """As rospy's XML-RPC proxy: the main thread is inside a call holding a plain lock when
    SIGTERM lands, and the shutdown needs that lock too. Run inside the handler, as
    rospy's own, it would wait for itself forever; here it waits for the main thread."""
    lock, done, reasons = threading.Lock(), threading.Event(), []

    def shutdown(reason: str) -> None:
        if lock.acquire(timeout=3.0):      # run inside the handler it would wait for itself
            reasons.append(reason)
            lock.release()
        else:
            reasons.append("deadlock")
        done.set()

    previous = signal.signal(signal.SIGTERM, shutdown_elsewhere(shutdown))
    try:
        with lock:
            os.kill(os.getpid(), signal.SIGTERM)       # the handler runs at the next bytecode
            held_back = not done.wait(0.2)             # the shutdown waits: the lock is held
        assert done.wait(10.0), "the shutdown never ran"
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert held_back and reasons == [f"signal-{int(signal.SIGTERM)}"]


def test_the_shutdown_thread_is_not_a_daemon():
    """The interpreter must wait for it: the node's map is saved in its shutdown hooks."""
    threads, started, release = [], threading.Event(), threading.Event()

    def shutdown(_reason: str) -> None:
        threads.append(threading.current_thread())
        started.set()
        release.wait(10.0)

    shutdown_elsewhere(shutdown)(int(signal.SIGINT), None)
    try:
        assert started.wait(10.0)
        assert not threads[0].daemon and threads[0] is not threading.main_thread()
    finally:
        release.set()
        if threads:
            threads[0].join(10.0)
