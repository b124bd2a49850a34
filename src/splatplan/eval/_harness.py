"""Timing and memory harness of the throughput measurements: study E2 (its per-row worker,
``_throughput_worker``) and ``benchmarks/metric_throughput.py`` use these, and nothing else does.

Memory (Linux ``/proc``): :func:`trim_heap` returns freed heap pages to the OS, :func:`reset_peak_rss`
resets the RSS high-water mark, :func:`proc_status_mb` reads ``VmRSS`` / ``VmHWM``; a method's extra
peak memory is ``VmHWM`` after it ran minus ``VmRSS`` before. Timing: :func:`timed_runs` (wall and
CPU seconds of each call, the device synchronised after each).
"""

from __future__ import annotations

import time
from typing import Callable


def proc_status_mb(key: str) -> float:
    """A ``/proc/self/status`` field (e.g. VmRSS, VmHWM) in MiB; NaN when unavailable."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith(key + ":"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float("nan")


def trim_heap() -> None:
    """Return freed heap pages to the OS (glibc ``malloc_trim(0)``; no-op elsewhere).

    Without it, memory freed while the scene was built stays resident in the heap, later
    allocations reuse those pages without raising RSS, and the peak is under-estimated.
    """
    try:
        import ctypes

        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass


def reset_peak_rss() -> bool:
    """Reset the RSS high-water mark VmHWM to the current RSS (Linux >= 4.0). True on success."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


def timed_runs(fn: Callable[[], object], repeats: int, sync: Callable[[], object] | None = None) -> tuple[list[float], list[float]]:
    """Call ``fn()`` ``repeats`` times (after any warm-up the caller did); ``sync()`` after each
    call, inside the timing (device work finished). Returns (wall seconds, CPU seconds of this
    process) per call."""
    wall, cpu = [], []
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        fn()
        if sync is not None:
            sync()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return wall, cpu
