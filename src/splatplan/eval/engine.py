"""The job engine of the studies and sweeps: many independent tasks, serial or on Dask.

A study (or ``splatplan sweep``) is a list of small :class:`Task` s, a pure function
``fn(spec, context) -> row`` (a JSON-able dict) and a ``context_factory`` that builds what every
task of the run needs (the scene, its checker, the robot). :func:`run_tasks` runs them:

* **serial** (``{"kind": "serial"}``, the default): in this process, the context built once;
* **dask** (``{"kind": "dask", "workers": N}``): on a ``distributed.LocalCluster`` of N worker
  processes, one task at a time each (its collision calls on cores / N threads), listening on
  loopback only (127.0.0.1, no dashboard); or (``{"kind": "dask", "scheduler": "tcp://HOST:PORT"}``)
  on an existing cluster.

Guarantees:

* **The context is built once per worker**, lazily on the worker's first task, and kept on the
  worker object (keyed by the pickled factory), never shipped with the tasks: tasks carry only
  their small spec. A context that fails to build fails the task (recorded), not the run.
* **Results stream to disk** as they finish: one JSON line per task in ``out_path`` (``key``,
  ``ok``, ``row`` or ``error``, ``seconds``, ``worker``), flushed per line. Large numpy arrays in a
  row (> :data:`ARRAY_INLINE_MAX` elements, e.g. a study's score per grid point) go to
  ``<out_path>.arrays/*.npy`` and the line refers to them; ``RunResult.rows`` gives them back as
  arrays. **A rerun skips every key already in the file** (resume); a torn last line (a crash
  mid-write) is dropped first. Failed tasks are skipped too unless ``retry_failed``; the last
  record of a key wins when reading. Studies put a hash of their settings and of splatplan's
  source (:func:`code_version`) into their keys, so stale results are never reused.
* **Ctrl-C** is handled once, by the client (local workers are spawned with SIGINT ignored): the
  cluster is closed, finished tasks stay in the file.
* **A failing task is recorded** with its error (``ok: false``, ``error: "Type: message"``), never
  lost; a task whose worker died is rerun by Dask (its ``allowed-failures``, default 3, then
  recorded as failed with ``KilledWorker``).
* **Same results as serial**: the engine never seeds anything; each task must seed its own RNG from
  its spec (never from worker state), so where a task runs does not change its row.
* **No oversubscription**: local worker processes get ``SPLATPLAN_CPU_THREADS`` = cores / workers
  (at least 1; :attr:`EngineConfig.threads_per_worker` overrides it): the thread pools of the
  checker and the FK split each collision call over that many threads (see
  :func:`splatplan._warp.cpu_threads`), so N workers use the cores a serial run uses; Dask's
  defaults of one BLAS/OMP thread. An external worker without the variable gets 1.

Wiring a study (see ``eval/conservatism.py``: ``make_context``, ``conservatism_task``)::

    tasks = [Task(f"{sig}/ns={ns:g}/seed={s}", {"n_sigma": ns, "seed": s}) for ...]
    res = run_tasks(tasks, solve_one, functools.partial(load_ctx, scene_path), engine, out / "x.results.jsonl")
    rows = res.rows  # {key: row} of every finished task, this run's and earlier ones

``fn`` and ``context_factory`` must be picklable (module-level functions, ``functools.partial``
of them) for the dask engine.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import math
import os
import pickle
import signal
import socket
import sys
import threading
import time
import traceback
import uuid
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable

from ..errors import SplatplanError
from .._progress import progress as _progress

__all__ = ["EngineConfig", "RunResult", "Task", "code_version", "engine_from_flags", "load_results", "run_tasks"]


DISTRIBUTED_HINT = "--workers / --scheduler need the 'distributed' extra: pip install 'splatplan[distributed]'"


@dataclass(frozen=True)
class Task:
    """One job: a stable ``key`` (unique in its run; the resume key) and a small picklable ``spec``
    (JSON-able: numbers, strings, lists, dicts) that fully determines its result."""

    key: str
    spec: dict


@dataclass(frozen=True)
class EngineConfig:
    """Where the tasks run."""

    #: "serial" (this process) or "dask" (a local cluster of ``workers`` processes, or ``scheduler``)
    kind: str = "serial"
    #: worker processes of the local cluster (dask; None with ``scheduler``)
    workers: int | None = None
    #: address of an existing Dask scheduler, e.g. tcp://10.0.0.5:8786 (dask; None = a local cluster)
    scheduler: str | None = None
    #: threads of each local worker's collision calls (SPLATPLAN_CPU_THREADS); None = cores / workers
    threads_per_worker: int | None = None

    def validate(self) -> "EngineConfig":
        if self.kind not in ("serial", "dask"):
            raise SplatplanError(f"engine kind must be 'serial' or 'dask', got {self.kind!r}")
        if self.kind == "serial":
            if self.workers is not None or self.scheduler is not None:
                raise SplatplanError("a serial engine takes neither workers nor a scheduler")
            return self
        if self.scheduler is None and self.workers is None:
            raise SplatplanError("a dask engine needs workers (a local cluster) or a scheduler address")
        try:  # before any work or output
            import distributed  # noqa: F401
        except ImportError:
            raise SplatplanError(DISTRIBUTED_HINT) from None
        if self.workers is not None and (isinstance(self.workers, bool) or not isinstance(self.workers, int) or self.workers < 1):
            raise SplatplanError(f"--workers must be an integer >= 1, got {self.workers!r}")
        if self.scheduler is not None:
            _parse_address(self.scheduler)
        t = self.threads_per_worker
        if t is not None and (isinstance(t, bool) or not isinstance(t, int) or t < 1):
            raise SplatplanError(f"threads_per_worker must be an integer >= 1, got {t!r}")
        return self

    def worker_threads(self) -> int:
        """Threads per local worker: ``threads_per_worker``, else this machine's cores / workers (>= 1)."""
        if self.threads_per_worker is not None:
            return int(self.threads_per_worker)
        try:
            cores = len(os.sched_getaffinity(0))
        except AttributeError:  # pragma: no cover - non-Linux
            cores = os.cpu_count() or 1
        return max(1, cores // max(1, int(self.workers or 1)))

    def as_dict(self) -> dict:
        """The engine as the outputs record it (before the run: the requested values)."""
        if self.kind == "serial":
            return {"kind": "serial"}
        return {"kind": "dask", "workers": self.workers, "scheduler": self.scheduler}


def engine_from_flags(workers: int | None = None, scheduler: str | None = None) -> EngineConfig:
    """``--workers N`` / ``--scheduler ADDR`` -> an :class:`EngineConfig` (serial when neither).

    With both, the run uses the scheduler and ``workers`` is ignored there (it only sizes a local
    cluster) - rejected to avoid a silent surprise."""
    if workers is None and scheduler is None:
        return EngineConfig()
    if workers is not None and scheduler is not None:
        raise SplatplanError("give --workers N (a local cluster) or --scheduler ADDR (an existing one), not both")
    return EngineConfig("dask", workers=workers, scheduler=scheduler).validate()


def _parse_address(addr: str) -> tuple[str, int]:
    """'tcp://HOST:PORT' -> (host, port), or a one-line error."""
    text = str(addr)
    proto, sep, rest = text.partition("://")
    host, _, port = rest.rpartition(":")
    if not sep or proto not in ("tcp", "tls") or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise SplatplanError(f"--scheduler {addr!r}: expected tcp://HOST:PORT (e.g. tcp://10.0.0.5:8786)")
    return host.strip("[]"), int(port)


@dataclass
class RunResult:
    """Outcome of :func:`run_tasks`.

    Attributes:
        rows: key -> row of every task that succeeded (this run's and earlier runs' from the file).
        errors: key -> error text of every task recorded as failed.
        records: key -> the full JSON record (key, ok, row / error, seconds, worker).
        engine: the engine that ran this call, as recorded in the outputs: {"kind": "serial"} or
            {"kind": "dask", "workers": N, "scheduler": ADDRESS}.
        n_run: tasks run by this call; n_skipped: tasks found finished in ``out_path``.
        wall_s: wall-clock seconds of this call (cluster start and shutdown included).
        cluster_start_s: seconds to start (or connect to) the cluster (0 for serial).
        run_s: seconds from the first task's start (serial) or submission (dask) to the last
            result: the run without the cluster's start and shutdown.
    """

    rows: dict[str, dict] = field(default_factory=dict)
    errors: dict[str, str] = field(default_factory=dict)
    records: dict[str, dict] = field(default_factory=dict)
    engine: dict = field(default_factory=lambda: {"kind": "serial"})
    n_run: int = 0
    n_skipped: int = 0
    wall_s: float = 0.0
    cluster_start_s: float = 0.0
    run_s: float = 0.0


@functools.lru_cache(maxsize=1)
def code_version() -> str:
    """A short hash of splatplan's own source files: part of every study's resume keys, so results
    written by other code are never taken for finished tasks."""
    root = Path(__file__).resolve().parents[1]  # the splatplan package
    h = hashlib.sha1()
    for f in sorted(root.rglob("*.py")):
        h.update(str(f.relative_to(root)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:12]


# ---------------------------------------------------------------------------- results file
def load_results(path: str | Path, repair: bool = False) -> dict[str, dict]:
    """key -> last JSON record of a results file (missing file: empty). A torn last line (no
    newline: the writer died mid-line) is ignored, and cut off the file with ``repair``."""
    p = Path(path)
    if not p.is_file():
        return {}
    data = p.read_bytes()
    end = data.rfind(b"\n") + 1
    if end < len(data) and repair:
        with open(p, "r+b") as f:
            f.truncate(end)
    out: dict[str, dict] = {}
    for n, line in enumerate(data[:end].splitlines(), 1):
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
            out[str(rec["key"])] = rec
        except (ValueError, KeyError, TypeError):
            raise SplatplanError(f"results file {p}: line {n} is not a task record; move the file away to start afresh") from None
    return out


#: arrays with more elements than this are stored beside the results file (``<file>.arrays/``)
ARRAY_INLINE_MAX = 64


def _encode(x, arrays_dir: Path | None, stem: str, path: str = "row"):
    """A task's row -> JSON values: numpy scalars and small arrays to numbers and lists,
    tuples to lists, NaN/inf to None; a large array to ``{"__npy__": NAME}`` (saved in
    ``arrays_dir`` first) or, without one, kept as the array (in-memory runs)."""
    import numpy as np

    if isinstance(x, dict):
        return {str(k): _encode(v, arrays_dir, stem, f"{path}.{k}") for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_encode(v, arrays_dir, stem, f"{path}.{i}") for i, v in enumerate(x)]
    if isinstance(x, np.ndarray) and x.size > ARRAY_INLINE_MAX:
        if arrays_dir is None:
            return x
        arrays_dir.mkdir(exist_ok=True)
        name = f"{stem}-{hashlib.sha1(path.encode()).hexdigest()[:8]}.npy"
        tmp = arrays_dir / f".{name}.tmp"
        with open(tmp, "wb") as f:
            np.save(f, x, allow_pickle=False)
        os.replace(tmp, arrays_dir / name)  # the file exists before any line refers to it
        return {"__npy__": name}
    if hasattr(x, "tolist") and not isinstance(x, (str, bytes)):
        return _encode(x.tolist(), arrays_dir, stem, path)
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def _decode(x, arrays_dir: Path | None):
    """Inverse of :func:`_encode` for stored arrays (``{"__npy__": NAME}`` -> the array)."""
    if isinstance(x, dict):
        if set(x) == {"__npy__"} and arrays_dir is not None:
            import numpy as np

            return np.load(arrays_dir / x["__npy__"], allow_pickle=False)
        return {k: _decode(v, arrays_dir) for k, v in x.items()}
    if isinstance(x, list):
        return [_decode(v, arrays_dir) for v in x]
    return x


# ---------------------------------------------------------------------------- task execution
_CTX_LOCK = threading.Lock()


def _context_key(factory) -> bytes:
    try:
        return pickle.dumps(factory)
    except Exception:  # an unpicklable factory can only run serially; key it by identity
        return repr(id(factory)).encode()


def _call(fn: Callable, factory: Callable, spec: dict, contexts: dict) -> dict:
    """Run one task with the context from ``contexts`` (built on first use); never raises."""
    t0 = time.perf_counter()
    try:
        key = _context_key(factory)
        with _CTX_LOCK:
            if key not in contexts:
                contexts.clear()  # one context per worker: a new factory replaces the old one
                contexts[key] = factory()
            ctx = contexts[key]
        row = fn(spec, ctx)  # shipped as is (numpy arrays pickle compactly); encoded by the client
        if not isinstance(row, dict):
            raise TypeError(f"the task function must return a dict, got {type(row).__name__}")
        return {"ok": True, "row": row, "seconds": time.perf_counter() - t0}
    except Exception as exc:  # recorded, not lost (KeyboardInterrupt / SystemExit pass through)
        tb = traceback.format_exc(limit=-3)
        return {"ok": False, "error": f"{type(exc).__name__}: {exc}", "traceback": tb, "seconds": time.perf_counter() - t0}


def _dask_task(fn: Callable, factory: Callable, spec: dict) -> dict:
    """The function the Dask workers run: the worker's context cache lives on the worker object."""
    from distributed import get_worker

    os.environ.setdefault("SPLATPLAN_CPU_THREADS", "1")  # an external worker without our env
    w = get_worker()
    contexts = w.__dict__.setdefault("_splatplan_contexts", {})
    rec = _call(fn, factory, spec, contexts)
    rec["worker"] = f"{socket.gethostname()}:{os.getpid()}"
    return rec


# ---------------------------------------------------------------------------- the engine
#: results logs this process has written to: a run interrupted after some tasks finished keeps
#: them (a rerun of the same command skips them); the CLI names them in its closing line
RESUMABLE: list[Path] = []


def run_tasks(
    tasks: Iterable[Task],
    fn: Callable[[dict, Any], dict],
    context_factory: Callable[[], Any],
    engine: EngineConfig | dict | None = None,
    out_path: str | Path | None = None,
    progress: bool = True,
    retry_failed: bool = False,
    desc: str = "tasks",
) -> RunResult:
    """Run ``fn(task.spec, context)`` for every task not yet finished in ``out_path``.

    Args:
        tasks: the jobs (unique keys).
        fn: task function, ``(spec, context) -> row`` (a JSON-able dict); picklable for dask.
        context_factory: ``() -> context``, called once per worker process (once in total when
            serial); picklable for dask (a module-level function or a ``functools.partial``).
        engine: :class:`EngineConfig` or its dict form (default serial).
        out_path: JSON-lines results file (appended to; None = keep results in memory only).
        progress: show a progress bar (on a terminal only, see ``eval._common.progress``).
        retry_failed: rerun tasks recorded as failed (otherwise a failure counts as finished).
        desc: progress bar label.

    Returns:
        :class:`RunResult` over every task of ``tasks`` (earlier runs' records included).

    Raises:
        SplatplanError: duplicate keys, a bad engine, an unreachable scheduler, a broken results file.
    """
    t_all = time.perf_counter()
    tasks = list(tasks)
    if isinstance(engine, dict):
        engine = EngineConfig(**engine)
    engine = (engine or EngineConfig()).validate()
    keys = [t.key for t in tasks]
    if len(set(keys)) != len(keys):
        dup = next(k for k in keys if keys.count(k) > 1)
        raise SplatplanError(f"task keys must be unique; {dup!r} appears more than once")
    done = load_results(out_path, repair=True) if out_path is not None else {}
    arrays_dir = Path(f"{out_path}.arrays") if out_path is not None else None
    wanted = set(keys)
    finished = {k for k, r in done.items() if k in wanted and (r.get("ok") or not retry_failed)}
    todo = [t for t in tasks if t.key not in finished]
    res = RunResult(n_skipped=len(finished))
    if finished and progress:
        print(f"resuming: {len(finished)} of {len(tasks)} task(s) already finished in {out_path}", file=sys.stderr)
    sinks: list = []  # the results log, opened at the first result: a run that fails or is
    # interrupted before any task finishes leaves no empty log behind

    def record(task: Task, rec: dict) -> None:
        rec = {"key": task.key, **rec}
        if "row" in rec:
            try:
                rec["row"] = _encode(rec["row"], arrays_dir, hashlib.sha1(task.key.encode()).hexdigest()[:16])
                json.dumps(rec["row"], allow_nan=False) if out_path is not None else None
            except (TypeError, ValueError) as exc:  # a row that JSON cannot hold is the task's error
                rec = {"key": task.key, "ok": False, "error": f"TypeError: the task's row is not JSON-able: {exc}", "seconds": rec.get("seconds")}
        done[task.key] = rec
        if out_path is not None:
            if not sinks:
                sinks.append(open(out_path, "a", encoding="utf-8"))  # noqa: SIM115 - closed below
                RESUMABLE.append(Path(out_path))  # an interrupted CLI run says how to resume
            sinks[0].write(json.dumps(rec, allow_nan=False) + "\n")
            sinks[0].flush()

    try:
        bar = _progress(total=len(todo), desc=desc, unit="task") if (todo and progress) else None
        if engine.kind == "serial":
            res.engine = {"kind": "serial"}
            t_run = time.perf_counter()
            contexts: dict = {}
            for t in todo:
                rec = _call(fn, context_factory, t.spec, contexts)
                rec["worker"] = f"{socket.gethostname()}:{os.getpid()}"
                record(t, rec)
                if bar is not None:
                    bar.update(1)
            res.run_s = time.perf_counter() - t_run
        else:
            _run_dask(todo, fn, context_factory, engine, record, bar, res)
        if bar is not None:
            bar.close()
    finally:
        for f in sinks:
            f.close()
    res.n_run = len(todo)
    for k in keys:
        got = done.get(k)
        if got is None:
            continue
        res.records[k] = got
        if got.get("ok"):
            res.rows[k] = _decode(got["row"], arrays_dir)
        else:
            res.errors[k] = got.get("error", "unknown error")
    res.wall_s = time.perf_counter() - t_all
    return res


def _dask_client(engine: EngineConfig):
    """(client, cluster or None, engine dict as recorded)."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise SplatplanError(DISTRIBUTED_HINT) from None
    if engine.scheduler is not None:
        host, port = _parse_address(engine.scheduler)
        try:  # a plain TCP probe first: Client's own timeout message is long and multi-line
            socket.create_connection((host, port), timeout=5).close()
        except OSError as exc:
            raise SplatplanError(f"cannot reach the Dask scheduler at {engine.scheduler}: {exc.strerror or exc}") from None
        try:
            client = Client(engine.scheduler, timeout="10s")
        except (OSError, TimeoutError) as exc:
            raise SplatplanError(f"cannot connect to the Dask scheduler at {engine.scheduler}: {exc}") from None
        n = len(client.scheduler_info().get("workers", {}))
        return client, None, {"kind": "dask", "workers": n, "scheduler": engine.scheduler}
    # the local cluster: loopback only, no dashboard, one task thread per worker process; workers
    # split their collision calls over cores / workers threads (no oversubscription of the cores)
    assert engine.workers is not None  # (validated: a dask engine without a scheduler has workers)
    with _workers_ignore_sigint(), _glibc_malloc_defaults(), warnings.catch_warnings():
        # the scheduler's HTTP routes (health, metrics; no dashboard) bind 127.0.0.1:8787, or another
        # port when that one is taken (another cluster on this machine): not the user's business
        warnings.filterwarnings("ignore", message="Port .* is already in use")
        cluster = LocalCluster(
            host="127.0.0.1",
            processes=True,
            n_workers=int(engine.workers),
            threads_per_worker=1,
            dashboard_address=None,
            silence_logs=50,  # CRITICAL only: keep the workers' chatter off the user's terminal
            env={"SPLATPLAN_CPU_THREADS": str(engine.worker_threads()), "SPLATPLAN_NO_TQDM": "1"},
        )
    client = Client(cluster)
    return client, cluster, {"kind": "dask", "workers": int(engine.workers), "scheduler": cluster.scheduler_address}


@contextlib.contextmanager
def _glibc_malloc_defaults():
    """Spawn the local workers with glibc's own allocator settings, and leave this process's
    environment as it was.

    Dask's nannies export ``MALLOC_TRIM_THRESHOLD_=65536`` (config
    ``distributed.nanny.pre-spawn-environ``) before spawning a worker. Setting that variable at
    all turns off glibc's dynamic mmap threshold, so every large numpy temporary is mmapped and
    unmapped again. That page-faults: the MBM tasks ran 1.25-1.4x slower in a plain process with
    only that variable set (benchmarks/engine.py), as slow as in the workers. A user who sets the
    variable in their own environment or Dask config keeps it. The nannies also write
    their pre-spawn variables (``OMP_NUM_THREADS=1`` etc.) into ``os.environ`` of the process
    that starts them, here the user's: those are restored on exit, so only the workers see them."""
    import dask

    before = dict(os.environ)
    env = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}) or {})
    if "MALLOC_TRIM_THRESHOLD_" not in os.environ and str(env.get("MALLOC_TRIM_THRESHOLD_")) == "65536":  # Dask's default, not a user's choice
        env["MALLOC_TRIM_THRESHOLD_"] = None  # None unsets it (distributed.nanny._get_env_variables)
    try:
        with dask.config.set({"distributed.nanny.pre-spawn-environ": env}):
            yield
    finally:
        for k in set(os.environ) - set(before):
            del os.environ[k]
        os.environ.update(before)


@contextlib.contextmanager
def _workers_ignore_sigint():
    """Spawn the local workers with SIGINT ignored (inherited through exec): Ctrl-C in the terminal
    reaches the whole process group, and only this process should handle it (it then closes the
    cluster) - not every worker with a traceback of its own. Main thread only; restored after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


def _run_dask(todo: list[Task], fn, factory, engine: EngineConfig, record, bar, res: RunResult) -> None:
    t0 = time.perf_counter()
    client, cluster, info = _dask_client(engine)  # names the extra when distributed is missing
    from distributed import as_completed
    from distributed.scheduler import KilledWorker

    res.engine = info
    res.cluster_start_s = time.perf_counter() - t0
    try:
        if not todo:
            return
        t_run = time.perf_counter()
        run_id = uuid.uuid4().hex[:8]
        fut_task = {}
        for t in todo:
            f = client.submit(_dask_task, fn, factory, t.spec, key=f"splatplan-{run_id}-{t.key}", pure=False, retries=0)
            fut_task[f] = t
        for fut in as_completed(list(fut_task)):
            t = fut_task[fut]
            try:
                rec = fut.result()
            except KilledWorker as exc:
                rec = {"ok": False, "error": f"KilledWorker: the task's workers died {exc}"[:500], "seconds": None}
            except Exception as exc:  # e.g. the task function could not be unpickled on the worker
                rec = {"ok": False, "error": f"{type(exc).__name__}: {exc}", "seconds": None}
            record(t, rec)
            if bar is not None:
                bar.update(1)
        res.run_s = time.perf_counter() - t_run
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
