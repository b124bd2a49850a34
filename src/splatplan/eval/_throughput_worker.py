"""The worker of study E2 (:mod:`splatplan.eval.throughput`): times and measures ONE (method,
batch) in a fresh interpreter, so every row's peak memory starts from the same clean process.

Run as ``python -m splatplan.eval._throughput_worker --worker SPEC_JSON``; prints one JSON line.
See the throughput module docstring for the protocol (warm-up on a dummy scene, heap trim, RSS
high-water reset, timed runs); the probes are in :mod:`splatplan.eval._harness`.
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import subprocess
import sys
import time
from typing import Any

import numpy as np

from ._common import make_queries
from ._harness import proc_status_mb, reset_peak_rss, timed_runs, trim_heap
from ..metric.config import MetricConfig  # the paper-reproduction studies run the paper's exact settings


def _dummy_splats(n: int = 64):
    """A tiny random scene for warming code paths up before the memory baseline."""
    from ..scenes.splats import Splats

    rng = np.random.default_rng(1)
    q = rng.normal(size=(n, 4))
    return Splats(
        means=rng.uniform(-0.1, 0.1, (n, 3)),
        quats=q / np.linalg.norm(q, axis=1, keepdims=True),
        scales=rng.uniform(0.001, 0.003, (n, 3)),
        opacities=np.full(n, 0.9),
        colors=np.full((n, 3), 0.5),
    )


def _make_runner(method: str, splats: Any, device: str, radius: float, n_sigma: float):
    """(build, run): build() constructs the method's scene data; run(centers) evaluates a batch."""
    if method.startswith("collisionsplatting"):
        from .._warp import wp
        from ..metric import CollisionChecker

        collision_only = method.endswith("collision_only")
        state: dict[str, Any] = {}

        def build() -> None:
            state["c"] = CollisionChecker(splats, n_sigma=n_sigma, device=device, config=MetricConfig.paper())

        def run(centers: np.ndarray) -> None:
            c = state["c"]
            if collision_only:
                c.collides(centers, None, radius)
            else:
                c.query(centers, None, radius)
            wp().synchronize()

        return build, run

    import torch

    from ..baselines import BASELINES
    from ..baselines._common import sync

    info = BASELINES[method]
    dev = torch.device(device)
    scored: dict[str, Any] = {}

    def build_baseline() -> None:
        scored["o"] = info.cls(splats, dev)
        sync(dev)

    def run_baseline(centers: np.ndarray) -> None:
        scored["o"].score(centers, radius, batch=max(1, min(len(centers), info.native_batch)) if info.native_batch > 1 else 1)
        sync(dev)

    return build_baseline, run_baseline


def _worker(spec: dict) -> dict:
    """Time and measure one (method, batch) in this (fresh) process. See the module docstring."""
    import torch

    from .._warp import cpu_threads, wp
    from ._common import load_stonehenge_filtered

    method, batch, device = spec["method"], int(spec["batch"]), spec["device"]
    radius, n_sigma = float(spec["radius"]), float(spec["n_sigma"])
    threads = cpu_threads() if spec.get("torch_threads") is None else int(spec["torch_threads"])
    torch.set_num_threads(threads)
    wp()  # initialise Warp (import cost is not the method's memory)
    splats, _, rep = load_stonehenge_filtered(spec["level"], spec["seed"], spec["n_splats"])
    lo, hi = splats.bounds()
    centers = make_queries(splats.means.astype(np.float64), lo, hi, batch, np.random.default_rng(spec["query_seed"]))
    batch1 = method in ("splatnav", "safersplat")
    n_timed = int(spec["batch1_checks"]) if batch1 else min(batch, int(spec.get("timed_queries") or batch))
    timed = centers[np.arange(n_timed) % len(centers)]  # (n_timed, 3)

    # warm the code paths up on a dummy scene (kernel loading, runtime initialisation)
    dummy = _dummy_splats()
    b0, r0 = _make_runner(method, dummy, device, radius, n_sigma)
    b0()
    r0(timed[:2] if not batch1 else timed[:1])
    del b0, r0, dummy
    gc.collect()
    trim_heap()

    cuda = device.startswith("cuda")
    if cuda:
        torch.cuda.synchronize()
        torch.cuda.reset_peak_memory_stats()
        wp_dev = wp().get_device(device)
        wp_before = wp().get_mempool_used_mem_current(wp_dev) if wp().is_mempool_enabled(wp_dev) else 0
    hwm_ok = reset_peak_rss()
    rss0 = proc_status_mb("VmRSS")

    t0 = time.perf_counter()
    build, run = _make_runner(method, splats, device, radius, n_sigma)
    build()
    prep_s = time.perf_counter() - t0
    prep_mem = proc_status_mb("VmHWM") - rss0 if hwm_ok and not cuda else float("nan")  # scene data only

    def evaluate() -> None:
        if batch1:
            for c in timed:
                run(c[None])
        else:
            run(timed)

    t0 = time.perf_counter()
    if batch1:
        run(timed[:1])  # warm-up: one check
    else:
        evaluate()  # warm-up: the timed batch (builds grids, compiles)
    warmup_s = time.perf_counter() - t0
    seconds, _ = timed_runs(evaluate, int(spec["repeats"]))
    med = float(np.median(seconds))
    rates = [n_timed / s for s in seconds]
    if cuda:
        peak = torch.cuda.max_memory_allocated() / 2**20
        if wp().is_mempool_enabled(wp_dev):
            peak += max(0, wp().get_mempool_used_mem_high(wp_dev) - wp_before) / 2**20
        mem_how = "torch.cuda.max_memory_allocated + Warp mempool high-water growth"
    else:
        peak = proc_status_mb("VmHWM") - rss0 if hwm_ok else float("nan")
        mem_how = "VmHWM - VmRSS after loading (HWM reset via /proc/self/clear_refs)"
    return {
        "method": method,
        "batch": batch,
        "checks_per_s": n_timed / med,
        "checks_per_s_std": float(np.std(rates)),
        "peak_mem_mb": float(peak),
        "timed_queries": n_timed,
        "extrapolated": bool(not batch1 and n_timed != batch),
        "seconds": seconds,
        "prep_s": prep_s,
        "prep_peak_mem_mb": float(prep_mem),
        "warmup_s": warmup_s,
        "rss_before_mb": rss0,
        "memory_measure": mem_how,
        "torch_threads": threads,
        "kernel_threads": cpu_threads() if device == "cpu" else None,
        "n_splats": len(splats),
        "floaters_dropped": int(rep.n_dropped),
    }


def run_worker_subprocess(spec: dict, timeout_s: float) -> dict:
    """Run :func:`_worker` in a fresh interpreter; returns its result dict (or an error row)."""
    cmd = [sys.executable, "-m", "splatplan.eval._throughput_worker", "--worker", json.dumps(spec)]
    env = dict(os.environ)
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s, env=env)
    except subprocess.TimeoutExpired:
        return {"method": spec["method"], "batch": spec["batch"], "error": f"worker timed out after {timeout_s:.0f} s"}
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
    if proc.returncode != 0 or not lines:
        tail = (proc.stderr or "").strip().splitlines()[-5:]
        return {"method": spec["method"], "batch": spec["batch"], "error": f"worker failed (rc {proc.returncode}): " + " | ".join(tail)}
    return json.loads(lines[-1])


def _main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="E2 throughput worker (internal): one (method, batch) per process")
    ap.add_argument("--worker", required=True, help="JSON spec")
    args = ap.parse_args(argv)
    res = _worker(json.loads(args.worker))
    sys.stdout.write(json.dumps(res) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(_main())
