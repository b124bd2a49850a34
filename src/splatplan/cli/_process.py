"""The CLI process: signal handling (so every ``finally`` runs on Ctrl-C or kill) and the plot backend."""

from __future__ import annotations

import os
import signal
import sys
import threading
from contextlib import contextmanager

__all__ = ["Terminated", "cli_signal_handlers", "headless_matplotlib", "received_signal", "signals_deferred"]

#: the signals :func:`cli_signal_handlers` turned into exceptions since it was entered (main thread)
_RECEIVED: list[int] = []


class Terminated(SystemExit):
    """Raised by the CLI's SIGTERM handler (exit code 143), so ``finally`` blocks clean up."""


#: seconds before a signal that arrived inside a finaliser is delivered again
REDELIVER_S = 0.02


def _in_finalizer(frame) -> bool:
    """Whether ``frame`` (the one a signal interrupted) runs inside an object's ``__del__`` or a
    ``weakref`` callback: Python swallows an exception raised there ("Exception ignored in ...", a
    traceback on stderr) and goes on as if the signal had never come."""
    while frame is not None:
        code = frame.f_code
        if code.co_name == "__del__" or code.co_filename.endswith("weakref.py"):
            return True
        frame = frame.f_back
    return False


def _deliver_later(signum: int) -> None:
    """Send ``signum`` to this process again in :data:`REDELIVER_S` (from a timer thread; the handler
    runs again in the main thread, outside the finaliser by then, or defers once more)."""
    t = threading.Timer(REDELIVER_S, os.kill, (os.getpid(), signum))
    t.daemon = True
    t.start()


def _raise_interrupt(signum, frame):
    if _in_finalizer(frame):
        _deliver_later(signum)
        return
    _RECEIVED.append(signum)
    raise KeyboardInterrupt


def _raise_terminated(signum, frame):
    if _in_finalizer(frame):
        _deliver_later(signum)
        return
    _RECEIVED.append(signum)
    raise Terminated(128 + signum)


def received_signal() -> int | None:
    """The last SIGINT / SIGTERM that :func:`cli_signal_handlers` raised as an exception, or None.
    Native code can swallow that exception into another one (a C extension whose import it
    interrupts fails with ``ImportError: initialization failed``): the CLI reads this to report such a
    failure as the interruption it is."""
    return _RECEIVED[-1] if _RECEIVED else None


@contextmanager
def cli_signal_handlers():
    """SIGINT -> KeyboardInterrupt and SIGTERM -> :class:`Terminated` while the block runs (main
    thread only), so every ``finally`` (temp files of :func:`atomic_path`) runs on Ctrl-C or kill.
    A signal the caller ignores (SIG_IGN, e.g. ``nohup``-style launchers) stays ignored. A signal
    that lands inside a finaliser (``__del__``, where the exception would be swallowed) is sent
    again a moment later."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    _RECEIVED.clear()
    if old[signal.SIGINT] is not signal.SIG_IGN:
        signal.signal(signal.SIGINT, _raise_interrupt)
    if old[signal.SIGTERM] is not signal.SIG_IGN:
        signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)


@contextmanager
def signals_deferred():
    """Hold SIGINT/SIGTERM while native work (a Warp launch on worker threads) is in flight and
    deliver them when the block ends, as KeyboardInterrupt / :class:`Terminated`.

    Interrupting the main thread while worker threads still run a kernel lets the interpreter shut
    down under them (a segfault); use this around one bounded chunk of work at a time.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    old = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}

    def record(signum, frame):
        pending.append(signum)

    for s, h in old.items():
        if h is not signal.SIG_IGN:  # an ignored signal stays ignored
            signal.signal(s, record)
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)
    if pending:
        if signal.SIGTERM in pending:
            raise Terminated(128 + signal.SIGTERM)
        raise KeyboardInterrupt


def headless_matplotlib() -> None:
    """The CLI only writes image files: matplotlib's Agg backend for this process and the worker
    processes it starts, chosen once at start-up. The library never picks a backend (its plotting
    returns Figures or saves through whatever backend its caller chose)."""
    os.environ["MPLBACKEND"] = "Agg"  # read when matplotlib is imported: costs nothing when no command plots
    mpl = sys.modules.get("matplotlib")
    if mpl is not None:  # imported already (e.g. main() called in-process): switch it now
        mpl.use("Agg")
