"""Job engine benchmark: the same plan jobs serial and on a local Dask cluster of 2 workers.

Job sets: plan jobs of ``splatplan sweep`` on built-in scenes, run to a fixed RRT iteration budget
(``max_iters``) so that every job does the same work wherever it runs:

* ``stonehenge``: sphere r = 0.015, built-in Stonehenge (``--splats`` splats), n_sigma 0 and 1,
  random free start/goal pairs;
* ``tabletop``: the Panda on the built-in tabletop, n_sigma 1, random free joint-space pairs;
* ``mbm`` (``--mbm N``): the ``eval mbm`` tasks (:func:`splatplan.eval.mbm.mbm_task`, our planner)
  on the first N problems of each shared MotionBenchMaker family (``--mbm-splats`` splats per
  scene); each worker builds its robot once and its scenes once per problem. The searches run to
  an iteration budget (``--mbm-max-iters``, default 100, about the 10 s limit on a quiet machine;
  0 = the wall-clock ``--mbm-time-limit``, where a search the limit cuts short may differ between
  the runs), so every row is the same serial and distributed (``same_rows``). Serial runs twice:
  with every core in each collision call (as a user runs it: the speedup) and with the workers'
  per-task threads, cores / workers (the engine's own efficiency). ``--mbm-only`` skips the
  built-in sets.

Measured:

* wall time serial (this process; Warp's CPU launches on every core, as today) and on 2 workers
  (cluster start excluded, and reported on its own), the speedup, and that the per-task rows are
  identical (timing fields aside);
* **per-task overhead** (scheduling + data transfer): ``--overhead-tasks`` no-op tasks on the
  running 2-worker cluster (wall / count: the scheduler's round trip per task, pipelined over both
  workers), and the extra time per MB of a task returning a 1 MB array;
* the per-worker context build (scene load + checker) from the first task of each worker;
* for MBM, **the machine's ceiling**: the same tasks split round-robin over 2 plain processes (no
  engine, contexts built before the clock starts); its speedup over serial bounds what any
  2-process engine can reach on this machine (the cores share caches and memory bandwidth).

Model (stated, not measured on a cluster): with W workers in total (N machines x c workers), n
tasks of mean duration t, per-task overhead o (the scheduler handles tasks one after another) and
a context build b per worker,
``T(W) ~= T_start + b + max(n t / W, n o)`` (+ the last task's tail), so the speedup over serial
``n t`` saturates at ``t / o`` workers. The script prints T(W) for W = 2, 8, 32, 128 from the
measured t, o and b.

    python benchmarks/engine.py [--quick] [--workers 2] [--pairs N] [--max-iters N] [--mbm N [--mbm-only]] [--out benchmarks/results/engine.json]

Timings on this shared 2-core machine are under heavy contention (the JSON records the load
average); the lead reruns on a quiet machine.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import statistics
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))


def noop(spec: dict, ctx) -> dict:
    """A task that does nothing (measures the engine's own overhead)."""
    return {"i": spec["i"]}


def payload(spec: dict, ctx) -> dict:
    """A task returning ``spec["mb"]`` MB of float64 (measures data transfer)."""
    return {"a": np.zeros(int(spec["mb"] * 131072))}


def no_context() -> None:
    return None


def _strip(rows: dict) -> dict:
    return {k: {f: v for f, v in r.items() if f not in ("time_s",)} for k, r in rows.items()}


def run_set(name: str, spec, base: Path, out: Path, workers: int) -> dict:
    from splatplan.eval.engine import run_tasks
    from splatplan.eval.sweep import build_tasks, expand_scenes, make_context, sweep_task

    tasks = build_tasks(spec, expand_scenes(spec, base))
    factory = functools.partial(make_context, spec.robot, spec.device, spec.filter_floaters, spec.n_splats)
    ser = run_tasks(tasks, sweep_task, factory, None, out / f"{name}_serial.jsonl", progress=False)
    t_ser = ser.run_s
    dk = run_tasks(tasks, sweep_task, factory, {"kind": "dask", "workers": workers}, out / f"{name}_dask.jsonl", progress=False)
    t_dk = dk.run_s  # submission of the first task to the last result (cluster start / shutdown apart)
    task_s = [r["seconds"] for r in ser.records.values()]
    first = {}
    for r in dk.records.values():  # the first task of each worker includes the context build
        first.setdefault(r["worker"], []).append(r["seconds"])
    same = _strip(ser.rows) == _strip(dk.rows) and not ser.errors and not dk.errors
    return {
        "job_set": name,
        "n_tasks": len(tasks),
        "serial_s": t_ser,
        "dask_s": t_dk,
        "cluster_start_s": dk.cluster_start_s,
        "dask_wall_incl_start_and_shutdown_s": dk.wall_s,
        "speedup": t_ser / t_dk,
        "speedup_incl_start": t_ser / dk.wall_s,
        "task_s_median": statistics.median(task_s),
        "task_s_sum": float(sum(task_s)),
        "first_task_s_per_worker": {k: max(v) for k, v in first.items()},
        "same_rows": bool(same),
        "n_solved": int(sum(bool(r.get("success")) for r in ser.rows.values())),
        "engine": dk.engine,
    }


def _serial_threads(n: int | None):
    """Set this process's collision-call threads (SPLATPLAN_CPU_THREADS) for a serial run; returns the old value."""
    old = os.environ.get("SPLATPLAN_CPU_THREADS")
    if n is None:
        os.environ.pop("SPLATPLAN_CPU_THREADS", None)
    else:
        os.environ["SPLATPLAN_CPU_THREADS"] = str(int(n))
    return old


def run_mbm_set(n_per_family: int, n_splats: int | None, time_limit: float, out: Path, workers: int, margin_m: float | None = None,
                max_iters: int | None = None, n_sigma: float | None = None) -> dict:  # fmt: skip
    """The MBM job set: serial with every core in each collision call (as a user runs it), serial with
    cores / workers threads (the same per-task threads as a worker: the engine's own efficiency),
    then on ``workers`` local workers (cores / workers threads each); same tasks, same seeds."""
    from dataclasses import asdict

    from splatplan.eval.engine import EngineConfig, Task, run_tasks
    from splatplan.eval.mbm import MBMConfig, check_inputs, comparable, list_tasks, make_context, mbm_task, settings_hash, task_key

    kw = {} if n_sigma is None else {"n_sigma": n_sigma}
    cfg = MBMConfig(n_per_family=n_per_family, n_splats=n_splats, time_limit=time_limit, margin_m=margin_m, max_iters=max_iters, **kw).validate()
    sig = settings_hash(cfg)
    factory = functools.partial(make_context, cfg)
    tasks = [Task(task_key(t, cfg, sig), asdict(t)) for t in check_inputs(list_tasks(cfg), factory().robot)]
    engine = EngineConfig("dask", workers=workers)
    per_worker = engine.worker_threads()
    cores = len(os.sched_getaffinity(0))
    old = _serial_threads(None)
    try:
        ser = run_tasks(tasks, mbm_task, factory, None, out / "mbm_serial.jsonl", progress=False)
        _serial_threads(per_worker)
        ser1 = run_tasks(tasks, mbm_task, factory, None, out / "mbm_serial_per_worker_threads.jsonl", progress=False)
    finally:
        _serial_threads(None if old is None else int(old))
    dk = run_tasks(tasks, mbm_task, factory, engine, out / "mbm_dask.jsonl", progress=False)
    ceiling = machine_ceiling(tasks, factory, workers, per_worker)
    task_s = [r["seconds"] for r in ser.records.values()]
    first = {}
    for r in dk.records.values():  # the first task of each worker includes the robot load
        first.setdefault(r["worker"], []).append(r["seconds"])
    differing = [k for k in ser.rows if comparable(ser.rows[k]) != comparable(dk.rows.get(k, {}))]
    differing1 = [k for k in ser.rows if comparable(ser.rows[k]) != comparable(ser1.rows.get(k, {}))]
    rows = list(ser.rows.values())
    return {
        "job_set": f"mbm ({n_per_family}/family, {f'{n_splats:,} splats' if n_splats else f'{1e3 * cfg.splat_spacing_m:g} mm splat spacing'}, n_sigma {cfg.n_sigma:g}, margin {'derived' if margin_m is None else format(margin_m, 'g') + ' m'}, "
                   + (f"{max_iters} iterations per search)" if max_iters else f"{time_limit:g} s per search)"),
        "n_tasks": len(tasks),
        "serial_s": ser.run_s,
        "serial_threads": cores,
        "serial_per_worker_threads_s": ser1.run_s,
        "worker_threads": per_worker,
        "dask_s": dk.run_s,
        "cluster_start_s": dk.cluster_start_s,
        "dask_wall_incl_start_and_shutdown_s": dk.wall_s,
        "speedup": ser.run_s / dk.run_s,
        "speedup_same_threads": ser1.run_s / dk.run_s,
        "engine_efficiency_same_threads": ser1.run_s / (workers * dk.run_s),
        "speedup_incl_start": ser.run_s / dk.wall_s,
        **ceiling,
        # the best speedup any engine of this many processes gets on this machine for these tasks
        "ceiling_speedup": ser.run_s / ceiling["ceiling_s"],
        "task_s_median": statistics.median(task_s),
        "task_s_sum": float(sum(task_s)),
        "task_s_sum_per_worker_threads": float(sum(r["seconds"] or 0.0 for r in ser1.records.values())),
        "first_task_s_per_worker": {k: max(v) for k, v in first.items()},
        "dask_task_s_sum": float(sum(r["seconds"] or 0.0 for r in dk.records.values())),
        # worker-seconds not spent inside a task, per task: scheduling, transfer, idle tail
        "overhead_per_task_derived_s": (workers * dk.run_s - sum(r["seconds"] or 0.0 for r in dk.records.values())) / max(1, len(tasks)),
        "same_rows": not differing and not differing1 and not ser.errors and not dk.errors and not ser1.errors,
        "differing": differing + [k + " (serial, per-worker threads)" for k in differing1],
        "errors": {**ser.errors, **ser1.errors, **dk.errors},
        "n_both_free": int(sum(bool(r.get("start_free") and r.get("goal_free")) for r in rows)),
        "n_solved": int(sum(bool(r.get("solved")) for r in rows)),
        "hit_time_limit": int(sum(r.get("time_s") is not None and r["time_s"] >= 0.95 * time_limit for r in rows)),
        "non_planning_s_per_problem": _non_planning(ser.records),
        "engine": dk.engine,
    }


def _ceiling_part(factory, specs: list, threads: int, barrier, results) -> None:
    """One plain process of the machine-ceiling run: build the context, wait for the others, then
    run ``specs`` one after another (no engine at all)."""
    os.environ["SPLATPLAN_CPU_THREADS"] = str(int(threads))
    from splatplan.eval.mbm import mbm_task

    ctx = factory()
    barrier.wait()
    t0 = time.perf_counter()
    for spec in specs:
        mbm_task(spec, ctx)
    results.put(time.perf_counter() - t0)


def machine_ceiling(tasks: list, factory, workers: int, threads: int) -> dict:
    """What any engine of ``workers`` processes could do here at best: the tasks split round-robin
    over that many plain processes started together (contexts built before the clock starts, no
    scheduler, no transfer); the wall time is the slowest part. On a machine whose cores share caches
    and memory bandwidth, each process runs slower next to the others than alone, and this shows it."""
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    barrier, results = ctx.Barrier(workers + 1), ctx.Queue()
    procs = [ctx.Process(target=_ceiling_part, args=(factory, [t.spec for t in tasks[i::workers]], threads, barrier, results)) for i in range(workers)]
    for p in procs:
        p.start()
    barrier.wait()
    parts = sorted(results.get() for _ in procs)
    for p in procs:
        p.join()
    return {"ceiling_s": parts[-1], "ceiling_parts_s": parts}


def _non_planning(records: dict) -> dict:
    """Per-task seconds outside the planner call (scene sampling, margin, checker, endpoint and path
    exact clearance): task seconds minus the row's planning time_s; median and mean."""
    v = [r["seconds"] - (r["row"].get("time_s") or 0.0) for r in records.values() if r.get("ok")]
    return {"median": statistics.median(v), "mean": statistics.fmean(v)} if v else {}


def overhead(workers: int, n: int) -> dict:
    from distributed import Client, LocalCluster

    from splatplan.eval.engine import Task, _dask_task

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Port .* is already in use")
        cluster = LocalCluster(host="127.0.0.1", processes=True, n_workers=workers, threads_per_worker=1, dashboard_address=None, silence_logs=50)
    client = Client(cluster)
    try:
        warm = client.gather([client.submit(_dask_task, noop, no_context, {"i": i}, pure=False) for i in range(2 * workers)])
        assert all(r["ok"] for r in warm)
        t0 = time.perf_counter()
        futs = [client.submit(_dask_task, noop, no_context, Task(f"n{i}", {"i": i}).spec, pure=False) for i in range(n)]
        client.gather(futs)
        per_task = (time.perf_counter() - t0) / n
        res = {}
        for mb in (0.0, 1.0):
            m = max(8, n // 10)
            t0 = time.perf_counter()
            client.gather([client.submit(_dask_task, payload, no_context, {"mb": mb, "i": i}, pure=False) for i in range(m)])
            res[mb] = (time.perf_counter() - t0) / m
        return {"noop_tasks": n, "per_task_s": per_task, "per_task_1mb_s": res[1.0], "per_mb_s": max(0.0, res[1.0] - res[0.0])}
    finally:
        client.close()
        cluster.close()


def model(t: float, o: float, b: float, start: float, n: int) -> dict:
    return {str(w): start + b + max(n * t / w, n * o) + t for w in (1, 2, 8, 32, 128)}


def main(argv: list[str] | None = None) -> int:
    from splatplan.eval.sweep import SweepSpec

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a tiny job set (smoke test)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--splats", type=int, default=100_000, help="Stonehenge splats")
    ap.add_argument("--overhead-tasks", type=int, default=400)
    ap.add_argument("--pairs", type=int, default=None, help="start/goal pairs per job set (default 24 Stonehenge, 12 tabletop)")
    ap.add_argument("--max-iters", type=int, default=None, help="RRT iterations per plan (default 300 Stonehenge, 150 tabletop)")
    ap.add_argument("--mbm", type=int, default=None, metavar="N", help="add the MBM job set: the first N problems of each shared MBM family")
    ap.add_argument("--mbm-splats", type=int, default=None, help="a fixed splat count per MBM scene (default: MBMConfig's splat spacing)")
    ap.add_argument("--mbm-time-limit", type=float, default=10.0, help="planning time limit per MBM problem (s)")
    ap.add_argument("--mbm-margin", type=float, default=None, help="MBM planning margin (m); default derived from the splats and n_sigma")
    ap.add_argument("--mbm-max-iters", type=int, default=100, help="iteration budget per MBM search (reproducible rows; 0 = the wall-clock --mbm-time-limit)")
    ap.add_argument("--mbm-n-sigma", type=float, default=None, help="MBM n_sigma (default: MBMConfig's)")
    ap.add_argument("--mbm-only", action="store_true", help="run only the MBM job set (with --mbm)")
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent / "results" / "engine.json"))
    args = ap.parse_args(argv)
    if args.mbm_only and args.mbm is None:
        ap.error("--mbm-only needs --mbm N")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    work = out.parent / f".{out.stem}_runs_{os.getpid()}"
    work.mkdir()
    load0 = os.getloadavg()[0]
    sets = {
        "stonehenge": SweepSpec(scenes=["builtin:stonehenge"], robot="sphere:0.015", n_sigma=[0.0, 1.0], pairs=24, max_iters=300, time_limit=120.0, n_splats=args.splats),
        "tabletop": SweepSpec(scenes=["builtin:tabletop"], robot="panda", n_sigma=[1.0], pairs=12, max_iters=150, time_limit=120.0, n_splats=args.splats),
    }
    for k, spec in sets.items():
        if args.pairs is not None:
            sets[k] = spec = replace(spec, pairs=args.pairs)
        if args.max_iters is not None:
            sets[k] = replace(spec, max_iters=args.max_iters)
    if args.quick:
        sets = {"stonehenge": replace(sets["stonehenge"], n_sigma=[1.0], pairs=2, max_iters=50, n_splats=20_000)}
    if args.mbm_only:
        sets = {}
    rows = []
    try:
        if args.mbm is not None:
            rows.append(run_mbm_set(args.mbm, args.mbm_splats, args.mbm_time_limit, work, args.workers, args.mbm_margin, args.mbm_max_iters or None, args.mbm_n_sigma))
            print(f"mbm: {rows[-1]['serial_s']:.1f} s serial, {rows[-1]['dask_s']:.1f} s on {args.workers} workers", file=sys.stderr)
        for name, spec in sets.items():
            rows.append(run_set(name, spec.validate(), Path("."), work, args.workers))
            print(f"{name}: {rows[-1]['serial_s']:.1f} s serial, {rows[-1]['dask_s']:.1f} s on {args.workers} workers", file=sys.stderr)
        ov = overhead(args.workers, 50 if args.quick else args.overhead_tasks)
    finally:
        for f in sorted(work.rglob("*"), reverse=True):
            f.unlink() if f.is_file() else f.rmdir()
        work.rmdir()
    for r in rows:
        b = max(r["first_task_s_per_worker"].values()) - r["task_s_median"]
        r["model_s_by_workers"] = model(r["task_s_sum"] / r["n_tasks"], ov["per_task_s"], max(0.0, b), r["cluster_start_s"], r["n_tasks"])
    res = {
        "rows": rows,
        "overhead": ov,
        "cores": len(os.sched_getaffinity(0)),
        "load_avg_1min_start": load0,
        "load_avg_1min_end": os.getloadavg()[0],
        "model": "T(W) = T_start + b + max(n t / W, n o) + t; t = mean task s (serial), o = per-task overhead, b = context build per worker",
        "note": "shared 2-core machine under contention: indicative only; rerun on a quiet machine",
        "quick": bool(args.quick),
    }
    out.write_text(json.dumps(res, indent=2) + "\n")
    lines = [
        f"| job set | tasks | serial (s) | {args.workers} workers (s) | speedup | cluster start (s) | median task (s) | same rows | T(8) model | T(32) model |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        m = r["model_s_by_workers"]
        lines.append(
            f"| {r['job_set']} | {r['n_tasks']} | {r['serial_s']:.1f} | {r['dask_s']:.1f} | {r['speedup']:.2f}x | {r['cluster_start_s']:.1f} | "
            f"{r['task_s_median']:.2f} | {'yes' if r['same_rows'] else 'NO'} | {m['8']:.1f} | {m['32']:.1f} |"
        )
    for r in rows:
        if "serial_per_worker_threads_s" in r:
            lines.append(f"\n{r['job_set']}: serial with {r['serial_threads']} threads per collision call (as a user runs it) {r['serial_s']:.1f} s -> "
                         f"{args.workers} workers x {r['worker_threads']} thread(s) {r['dask_s']:.1f} s: **{r['speedup']:.2f}x**; serial with {r['worker_threads']} thread(s) "
                         f"(the same per-task threads as a worker) {r['serial_per_worker_threads_s']:.1f} s: {r['speedup_same_threads']:.2f}x, engine efficiency "
                         f"{100 * r['engine_efficiency_same_threads']:.0f}%; the same tasks split over {args.workers} plain processes (no engine; the machine's ceiling) "
                         f"{r['ceiling_s']:.1f} s: {r['ceiling_speedup']:.2f}x at best; non-planning seconds per problem (serial): median {r['non_planning_s_per_problem'].get('median', float('nan')):.2f}")  # fmt: skip
        if "differing" in r:
            lines.append(f"\n{r['job_set']}: {r['n_solved']}/{r['n_both_free']} solved serially (of the problems with both endpoints free; {r['n_tasks']} tasks), {r['hit_time_limit']} at the time limit; "
                         f"worker time outside tasks per task {r['overhead_per_task_derived_s']:.2f} s (scheduling, transfer, idle tail); "
                         f"rows differing: {', '.join(r['differing']) or 'none'}; errors: {len(r['errors'])}")  # fmt: skip
    lines.append("")
    lines.append(f"per-task overhead (no-op tasks, {args.workers} workers): {1e3 * ov['per_task_s']:.2f} ms; 1 MB result: {1e3 * ov['per_task_1mb_s']:.2f} ms "
                 f"({1e3 * ov['per_mb_s']:.2f} ms/MB); load average {load0:.1f} -> {res['load_avg_1min_end']:.1f} on {res['cores']} cores")  # fmt: skip
    text = "\n".join(lines) + "\n"
    print(text)
    out.with_suffix(".md").write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
