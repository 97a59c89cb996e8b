"""rospy's shutdown on SIGINT / SIGTERM, run in a thread of its own.

rospy's own handler shuts the node down inside the main thread, wherever the signal
lands: in the middle of an XML-RPC call to the master (a log line's parameter lookup,
a subscriber's registration) the shutdown's own calls wait on the lock that call holds,
and the node hung until killed (a SIGTERM during start-up, faults.test). From a thread
of its own the shutdown waits until the main thread lets the lock go.
"""
from __future__ import annotations

import signal
import threading
from typing import Any, Callable


def shutdown_elsewhere(signal_shutdown: Callable[[str], None]) -> Callable[[int, Any], None]:
    """A signal handler that starts signal_shutdown("signal-N") in a new thread and
    returns. Not a daemon: the interpreter waits for it (and the on-exit map save)."""
    def handler(signum: int, _frame: Any) -> None:
        threading.Thread(target=signal_shutdown, args=(f"signal-{signum}",), name="shutdown").start()
    return handler


def init_node(name: str) -> None:
    """rospy.init_node(name) with SIGINT and SIGTERM handled by shutdown_elsewhere."""
    import rospy  # here: shutdown_elsewhere is tested where rospy is absent (Python 3.8 run)
    rospy.init_node(name, disable_signals=True)
    handler = shutdown_elsewhere(rospy.signal_shutdown)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, handler)
