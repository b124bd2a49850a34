"""Warp start-up in one place: quiet, with the kernel cache inside the project build tree.

Import :func:`wp` from here instead of calling ``warp.init()`` anywhere else, so the banner
never reaches the CLI's output. The kernel cache is the user's choice when they made one
(:func:`_cache_dir`); only then does splatplan leave Warp's process-wide setting alone.
"""

from __future__ import annotations

import os
import sys
import threading
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import torch

_lock = threading.Lock()


def _cache_dir(current: str | None, environ=os.environ) -> Path | None:
    """The kernel cache folder splatplan sets, or None to leave Warp's setting as it is.

    In order: a ``warp.config.kernel_cache_dir`` already set (``current``: by the user, or by a
    ``warp.init()`` that ran before splatplan's) stays; ``SPLATPLAN_WARP_CACHE``; Warp's own
    ``WARP_CACHE_PATH`` (Warp reads it); in a source checkout ``<repo>/build/warp-cache`` (our own
    runs and tests share one cache); otherwise Warp's default (its per-user cache folder).
    """
    if current is not None:
        return None
    env = environ.get("SPLATPLAN_WARP_CACHE")
    if env:
        return Path(env)
    if environ.get("WARP_CACHE_PATH"):
        return None
    # Editable/source checkout: <repo>/src/splatplan/_warp.py -> <repo>/build/warp-cache
    repo = Path(__file__).resolve().parents[2]
    if (repo / "pyproject.toml").exists() and (repo / "src" / "splatplan").is_dir():
        return repo / "build" / "warp-cache"
    return None


@lru_cache(maxsize=1)
def wp():
    """Return the initialised ``warp`` module (quiet; kernel cache: :func:`_cache_dir`)."""
    with _lock:
        import warp

        # Warp prints its banner and every module load to stdout at its default log level; a level
        # the user chose (anything but the default) stays.
        if hasattr(warp.config, "log_level"):  # warp >= 1.10
            if warp.config.log_level == warp.LOG_INFO:
                warp.config.log_level = warp.LOG_ERROR
        else:  # older releases
            warp.config.quiet = True
        cache = _cache_dir(warp.config.kernel_cache_dir)
        if cache is not None:
            cache.mkdir(parents=True, exist_ok=True)
            warp.config.kernel_cache_dir = str(cache)
        # The native library prints a CUDA-driver warning straight to fd 2 on machines without a
        # GPU; keep it off the CLI's output (resolve_device gives our own message instead).
        with _silence_fd(2):
            warp.init()
        return warp


@contextmanager
def _silence_fd(fd: int):
    try:
        saved = os.dup(fd)
    except OSError:  # no such descriptor (embedded interpreters)
        yield
        return
    try:
        sys.stderr.flush()
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, fd)
        os.close(devnull)
        yield
    finally:
        os.dup2(saved, fd)
        os.close(saved)


def resolve_device(device: str | None) -> str:
    """Map ``None``/"auto"/"cpu"/"cuda"/"cuda:N" to a Warp device name, with a clear error."""
    from .errors import SplatplanError

    w = wp()
    if device in (None, "auto"):
        return "cuda:0" if w.is_cuda_available() else "cpu"
    if device == "cpu":
        return "cpu"
    if device.startswith("cuda"):
        if not w.is_cuda_available():
            raise SplatplanError(f"device {device!r} requested but no CUDA device is available; use --device cpu")
        if device == "cuda":
            return "cuda:0"
        idx = device[5:]
        n = w.get_cuda_device_count()
        if device[4:5] != ":" or not idx.isdigit() or int(idx) >= n:
            raise SplatplanError(f"device {device!r} not available: this machine has {n} CUDA device(s) (cuda:0..cuda:{n - 1}); use --device cuda:0 or cpu")
        return f"cuda:{int(idx)}"
    raise SplatplanError(f"unknown device {device!r}: use 'cpu', 'cuda' or 'cuda:N'")


def resolve_torch_device(device) -> "torch.device":
    """The torch device of ``None``/"auto"/"cpu"/"cuda"/"cuda:N" or a ``torch.device``.

    "auto" means what it means for :func:`resolve_device`: CUDA when Warp sees a CUDA device (and
    this torch build can use it), else the CPU.
    """
    import torch

    from .errors import SplatplanError

    if isinstance(device, torch.device):
        dev = device
    elif device in (None, "auto"):
        cuda = torch.cuda.is_available() and wp().is_cuda_available()
        return torch.device("cuda:0" if cuda else "cpu")
    else:
        try:
            dev = torch.device(str(device))
        except (RuntimeError, ValueError):
            raise SplatplanError(f"unknown device {device!r}: use 'cpu', 'cuda' or 'cuda:N'") from None
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise SplatplanError(f"device {device!r} requested but no CUDA device is available; use --device cpu")
    if dev.type not in ("cpu", "cuda"):
        raise SplatplanError(f"unknown device {device!r}: use 'cpu', 'cuda' or 'cuda:N'")
    return dev


def cpu_threads() -> int:
    """Worker threads for CPU launches (Warp runs one CPU launch on one thread)."""
    env = os.environ.get("SPLATPLAN_CPU_THREADS")
    if env:
        return max(1, int(env))
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - non-Linux
        return max(1, os.cpu_count() or 1)


class LazyThreadPool:
    """CPU worker threads owned by one object: started on first use, stopped by :meth:`close` (the
    next use starts them again). Copies and pickles carry no threads (they start their own)."""

    def __init__(self, threads: int | None = None, name: str = "splatplan") -> None:
        self.threads = threads  #: workers (None: :func:`cpu_threads` when the pool starts)
        self.name = name
        self._lock = threading.Lock()
        self._pool = None

    def get(self):
        """The running ``ThreadPoolExecutor`` (started here when needed)."""
        from concurrent.futures import ThreadPoolExecutor

        with self._lock:
            if self._pool is None:
                self._pool = ThreadPoolExecutor(max_workers=self.threads or cpu_threads(), thread_name_prefix=self.name)
            return self._pool

    def close(self, wait: bool = True) -> None:
        """Stop the workers (after the queued work when ``wait``)."""
        with self._lock:
            pool, self._pool = self._pool, None
        if pool is not None:
            pool.shutdown(wait=wait)

    def __getstate__(self) -> dict:
        return {"threads": self.threads, "name": self.name}

    def __setstate__(self, state: dict) -> None:
        type(self).__init__(self, **state)

    def __copy__(self) -> "LazyThreadPool":
        return LazyThreadPool(self.threads, self.name)

    def __deepcopy__(self, memo) -> "LazyThreadPool":
        return self.__copy__()


class OwnsThreadPool:
    """Mixin of an object that keeps a :class:`LazyThreadPool` in ``self._pool``: ``close()`` stops
    its threads and ``with obj:`` closes it on exit (the object stays usable)."""

    _pool: LazyThreadPool

    def close(self) -> None:
        """Stop the CPU worker threads (the next CPU call starts them again)."""
        self._pool.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self) -> None:  # pragma: no cover - best effort at interpreter exit
        try:
            self._pool.close(wait=False)
        except Exception:
            pass


def wait_all(futures) -> None:
    """Wait for every future of a batch of CPU launches, re-raising the first error.

    On Ctrl-C (or an error) while launches still run, the ones not started are cancelled and the
    running ones are waited for before the exception propagates: the caller must never free
    the buffers that a running kernel still writes (that segfaulted on interrupts).
    """
    import concurrent.futures

    futures = list(futures)
    try:
        for f in futures:
            f.result()
    except BaseException:
        for f in futures:
            f.cancel()
        concurrent.futures.wait(futures)
        raise


def launch_split(kernel, dim: int, inputs: list, device, pool=None, *, offset_at: int = 0, min_split: int = 256, min_step: int = 128, chunks_per_thread: int = 8) -> None:
    """Launch ``kernel`` over ``dim`` threads, ``inputs[offset_at]`` being the first thread index of the launch.

    Warp runs a CPU launch on one thread, so the callers give a CPU launch a ``pool`` of worker
    threads: with more than one worker and ``dim >= min_split`` the range is cut into chunks of at
    least ``min_step`` threads, about ``chunks_per_thread`` per worker, submitted to ``pool`` and taken
    as workers free up (per-thread costs vary a lot: free space against dense surfaces, so equal
    halves would leave a core idle). ``pool`` None (other devices): one launch. Waits for every chunk
    (:func:`wait_all`)."""
    w = wp()
    n_thr = getattr(pool, "_max_workers", 1) if pool is not None else 1
    if n_thr == 1 or dim < min_split:
        args = list(inputs)
        args[offset_at] = 0
        w.launch(kernel, dim=dim, inputs=args, device=device)
        return

    def chunk(lo: int) -> list:
        args = list(inputs)
        args[offset_at] = lo
        return args

    wait_all(pool.submit(w.launch, kernel, dim=n, inputs=chunk(lo), device=device) for lo, n in split_chunks(dim, n_thr, min_step, chunks_per_thread))


def split_chunks(dim: int, n_thr: int, min_step: int, chunks_per_thread: int) -> list[tuple[int, int]]:
    """The (first thread index, size) chunks :func:`launch_split` cuts ``dim`` threads into for
    ``n_thr`` workers: at least ``min_step`` each, about ``chunks_per_thread`` per worker."""
    step = max(min_step, -(-dim // (chunks_per_thread * n_thr)))
    return [(lo, min(step, dim - lo)) for lo in range(0, dim, step)]
