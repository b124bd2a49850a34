"""The job engine: serial and a real 2-worker LocalCluster on loopback give the same rows; resume,
recorded failures, a worker killed mid-run loses nothing, per-worker contexts, bad engines."""

from __future__ import annotations

import functools
import json
import os
import signal
import threading
import time

import numpy as np
import pytest

pytest.importorskip("distributed")

from splatplan.errors import SplatplanError
from splatplan.eval.engine import EngineConfig, Task, engine_from_flags, load_results, run_tasks

N_CTX_BUILDS = []


def make_ctx(scale: float) -> dict:
    """A toy per-worker context; records its pid (serial: in this process)."""
    N_CTX_BUILDS.append(os.getpid())
    from splatplan._warp import cpu_threads

    return {"scale": scale, "pid": os.getpid(), "built": time.time(), "threads": cpu_threads()}


def toy(spec: dict, ctx: dict) -> dict:
    """Seeded from the spec only: the same row wherever it runs."""
    if spec.get("fail"):
        raise ValueError(f"task {spec['i']} fails on purpose")
    time.sleep(spec.get("sleep", 0.0))
    rng = np.random.default_rng([spec["seed"], spec["i"]])
    return {"i": spec["i"], "value": float(ctx["scale"] * rng.random()), "ctx_pid": ctx["pid"], "ctx_built": ctx["built"], "threads": ctx["threads"]}


def tasks(n: int, **extra) -> list[Task]:
    return [Task(f"t{i}", {"i": i, "seed": 7, **extra}) for i in range(n)]


def values(res) -> dict:
    return {k: r["value"] for k, r in res.rows.items()}


def test_serial_and_dask_same_rows_context_once_per_worker(tmp_path):
    factory = functools.partial(make_ctx, 2.0)
    ser = run_tasks(tasks(12), toy, factory, None, tmp_path / "serial.jsonl", progress=False)
    assert ser.engine == {"kind": "serial"} and ser.n_run == 12 and not ser.errors
    assert len({r["ctx_built"] for r in ser.rows.values()}) == 1  # built once
    dk = run_tasks(tasks(12), toy, factory, {"kind": "dask", "workers": 2}, tmp_path / "dask.jsonl", progress=False)
    assert dk.engine["kind"] == "dask" and dk.engine["workers"] == 2
    assert dk.engine["scheduler"].startswith("tcp://127.0.0.1:")  # loopback only
    assert values(dk) == values(ser)  # bit-identical per task
    # one context per worker process, never one per task
    per_pid = {}
    for r in dk.rows.values():
        per_pid.setdefault(r["ctx_pid"], set()).add(r["ctx_built"])
    assert all(len(v) == 1 for v in per_pid.values()) and len(per_pid) <= 2
    cores = len(os.sched_getaffinity(0))
    assert {r["threads"] for r in dk.rows.values()} == {max(1, cores // 2)}  # collision calls: cores / workers threads each
    recs = load_results(tmp_path / "dask.jsonl")
    assert sorted(recs) == sorted(f"t{i}" for i in range(12))


def test_resume_skips_finished_and_failures_are_recorded(tmp_path):
    out = tmp_path / "r.jsonl"
    factory = functools.partial(make_ctx, 1.0)
    first = run_tasks(tasks(5), toy, factory, None, out, progress=False)
    assert first.n_run == 5
    with open(out, "ab") as f:  # a torn last line, as a crash mid-write leaves it
        f.write(b'{"key": "t9", "ok": tr')
    ts = tasks(8)
    ts[6] = Task("t6", {"i": 6, "seed": 7, "fail": True})
    second = run_tasks(ts, toy, factory, None, out, progress=False)
    assert second.n_skipped == 5 and second.n_run == 3
    assert set(second.rows) == {f"t{i}" for i in range(8)} - {"t6"}
    assert second.errors["t6"].startswith("ValueError: task 6 fails on purpose")
    lines = out.read_text().splitlines()
    assert [json.loads(x)["key"] for x in lines] == [f"t{i}" for i in range(8)]  # torn line gone, each key once
    third = run_tasks(ts, toy, factory, None, out, progress=False)  # a failure counts as finished ...
    assert third.n_run == 0
    ts[6] = Task("t6", {"i": 6, "seed": 7})
    fourth = run_tasks(ts, toy, factory, None, out, progress=False, retry_failed=True)  # ... unless retried
    assert fourth.n_run == 1 and "t6" in fourth.rows and not fourth.errors


def test_killed_worker_loses_nothing(tmp_path):
    """SIGKILL a worker process while it runs tasks: Dask reruns them; every key is recorded once."""
    out = tmp_path / "k.jsonl"
    factory = functools.partial(make_ctx, 3.0)
    ts = tasks(10, sleep=0.4)
    killed = []

    def killer():
        # wait for the first finished task, then kill the worker that computed it (it holds more)
        for _ in range(300):
            time.sleep(0.1)
            recs = load_results(out) if out.exists() else {}
            if recs:
                pid = next(iter(recs.values()))["row"]["ctx_pid"]
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)
                return

    th = threading.Thread(target=killer, daemon=True)
    th.start()
    res = run_tasks(ts, toy, factory, {"kind": "dask", "workers": 2}, out, progress=False)
    th.join(timeout=5)
    assert killed, "no worker was killed"
    assert not res.errors and set(res.rows) == {f"t{i}" for i in range(10)}
    keys = [json.loads(x)["key"] for x in out.read_text().splitlines()]
    assert sorted(keys) == sorted(f"t{i}" for i in range(10))  # every key exactly once
    ser = run_tasks(ts, toy, factory, None, None, progress=False)
    assert values(res) == values(ser)
    pids = {r["ctx_pid"] for r in res.rows.values()}
    assert len(pids) >= 2  # the restarted worker (a new process) took over


def test_worker_threads():
    """Local workers split the cores between them (no oversubscription); an explicit count wins."""
    cores = len(os.sched_getaffinity(0))
    assert EngineConfig("dask", workers=2).validate().worker_threads() == max(1, cores // 2)
    assert EngineConfig("dask", workers=4 * cores).validate().worker_threads() == 1
    assert EngineConfig("dask", workers=2, threads_per_worker=3).validate().worker_threads() == 3
    for bad in (0, 1.5, True):
        with pytest.raises(SplatplanError, match="threads_per_worker"):
            EngineConfig("dask", workers=2, threads_per_worker=bad).validate()


def test_bad_engines():
    assert engine_from_flags() == EngineConfig()
    assert engine_from_flags(workers=2).as_dict() == {"kind": "dask", "workers": 2, "scheduler": None}
    for kw, msg in (({"workers": 0}, ">= 1"), ({"scheduler": "localhost:8786"}, "tcp://HOST:PORT"), ({"workers": 2, "scheduler": "tcp://a:1"}, "not both")):
        with pytest.raises(SplatplanError, match=msg):
            engine_from_flags(**kw)
    with pytest.raises(SplatplanError, match="cannot reach the Dask scheduler"):
        run_tasks(tasks(1), toy, functools.partial(make_ctx, 1.0), engine_from_flags(scheduler="tcp://127.0.0.1:9"), None, progress=False)
    with pytest.raises(SplatplanError, match="unique"):
        run_tasks([Task("a", {}), Task("a", {})], toy, functools.partial(make_ctx, 1.0))


def big(spec: dict, ctx: dict) -> dict:
    return {"scores": np.arange(1000, dtype=np.float64) * spec["i"], "small": np.arange(3), "nan": float("nan")}


def test_large_arrays_go_beside_the_file(tmp_path):
    out = tmp_path / "a.jsonl"
    factory = functools.partial(make_ctx, 1.0)
    res = run_tasks(tasks(2), big, factory, {"kind": "dask", "workers": 1}, out, progress=False)
    assert len(out.read_text()) < 2000 and len(list((tmp_path / "a.jsonl.arrays").glob("*.npy"))) == 2
    again = run_tasks(tasks(2), big, factory, None, out, progress=False)  # resumed: read back from the files
    assert again.n_run == 0
    for r in (res, again):
        np.testing.assert_array_equal(r.rows["t1"]["scores"], np.arange(1000.0))
        assert r.rows["t1"]["small"] == [0, 1, 2] and r.rows["t1"]["nan"] is None


def test_existing_scheduler_by_address(tmp_path):
    from distributed import LocalCluster

    factory = functools.partial(make_ctx, 2.0)
    with LocalCluster(host="127.0.0.1", protocol="tcp", n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cl:
        res = run_tasks(tasks(3), toy, factory, engine_from_flags(scheduler=cl.scheduler_address), tmp_path / "e.jsonl", progress=False)
    assert res.engine == {"kind": "dask", "workers": 1, "scheduler": cl.scheduler_address}
    assert values(res) == values(run_tasks(tasks(3), toy, factory, progress=False))


def test_missing_distributed_extra_says_how_to_install(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "distributed", None)  # import -> ImportError, as without the extra
    with pytest.raises(SplatplanError, match=r"pip install 'splatplan\[distributed\]'"):
        engine_from_flags(workers=2)  # the CLI's check, before any work
    with pytest.raises(SplatplanError, match=r"pip install 'splatplan\[distributed\]'"):
        run_tasks(tasks(1), toy, functools.partial(make_ctx, 1.0), {"kind": "dask", "workers": 2}, None, progress=False)


def worker_env(spec: dict, ctx) -> dict:
    return {"i": spec["i"], "malloc_trim": os.environ.get("MALLOC_TRIM_THRESHOLD_"), "omp": os.environ.get("OMP_NUM_THREADS")}


def test_local_workers_keep_glibc_malloc_defaults(tmp_path, monkeypatch):
    """Dask's MALLOC_TRIM_THRESHOLD_ (it turns off glibc's dynamic mmap threshold: numpy-heavy
    tasks ran ~1.3x slower) does not reach our local workers unless the user set it; the client's
    own environment is left as it was."""
    monkeypatch.delenv("MALLOC_TRIM_THRESHOLD_", raising=False)
    before = dict(os.environ)
    res = run_tasks(tasks(2), worker_env, no_context, {"kind": "dask", "workers": 1}, tmp_path / "env.jsonl", progress=False)
    assert not res.errors and {r["malloc_trim"] for r in res.rows.values()} == {None}
    assert {r["omp"] for r in res.rows.values()} == {"1"}  # Dask's other pre-spawn settings stay
    assert dict(os.environ) == before


def no_context() -> None:
    return None
