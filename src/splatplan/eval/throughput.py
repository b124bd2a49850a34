"""Study E2 (paper Table I): collision checks per second and peak memory of every method.

Protocol
--------
* **Scene**: the built-in Stonehenge, level 1 (~200k splats), floaters filtered.
* **Queries**: as ``benchmarks/metric_throughput.py``: half uniform in the bounds of the splat
  means, half uniform in a ball of radius 0.05 around a random splat mean (seeded, identical for
  every method). Robot: one sphere, r = 0.015; CollisionSplatting at n_sigma = 1.
* **Batches** (the paper's): Splat-Nav and SAFER-Splat 1 (one query at a time over all Gaussians,
  as the originals), ATLASNav and SPLANNING 4096, CollisionSplatting 4096 and 32768 (full
  :meth:`CollisionChecker.query`, all five outputs). Extra rows: CollisionSplatting's
  collision-only :meth:`CollisionChecker.collides` (early exit; what RRT edge checks use).
* **Timing**: one warm-up evaluation, then ``repeats`` timed evaluations (device synchronised);
  checks/s = queries per timed evaluation / median time. Batch-1 methods: one timed evaluation =
  ``batch1_checks`` calls in a row. Slow batched baselines may be timed on the first
  ``timed_queries`` of their 4096 queries, evaluated as one call, and the rate extrapolated per
  check (``extrapolated``): on CPU both already process a batch in memory-capped chunks (ATLASNav
  111 query rows at a time; SPLANNING [b, n, 3] blocks of <= 2**26 elements), so the work and the
  peak memory are linear resp. constant in the batch.
* **Threads**: our kernel splits every batch over all cores (its thread pool); torch baselines run
  with ``torch.set_num_threads(<cores>)``.
* **Memory**: every (method, batch) runs in a **fresh subprocess**. It imports all libraries,
  builds the scene, draws the queries and warms the method's code paths up on a 64-splat dummy
  scene (loads Warp kernels / initialises torch's CPU runtime), returns freed heap pages to the OS
  (``malloc_trim(0)``: otherwise the method would silently reuse pages freed by the scene build and
  its RSS would not grow), then resets the kernel's RSS high-water mark (``echo 5 > /proc/self/clear_refs``) and reads VmRSS. After building the
  method's scene data (tensors, hash grids), the warm-up and the timed runs it reads VmHWM:
  ``peak_mem_mb = VmHWM - VmRSS_before`` is everything the method added above the loaded
  libraries, scene arrays and queries. On CUDA: ``torch.cuda.max_memory_allocated`` plus the
  growth of Warp's memory-pool high-water mark.

Outputs in ``out_dir``: ``throughput.json`` and ``throughput.md`` (ours beside the paper's Table I).
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import platform
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._config import bounded, check_config
from ..errors import SplatplanError
from .._warp import cpu_threads
from ..robots import point_radius
from ._common import DISPLAY, make_queries

__all__ = ["ThroughputConfig", "PAPER_TABLE_I", "run_throughput"]

#: The paper's Table I: (method, batch) -> (GPU checks/s, CPU checks/s, memory GB).
#: RTX 6000 Pro GPU, 16-core Ryzen 9 9950X CPU.
PAPER_TABLE_I: dict[tuple[str, int], tuple[float, float, float]] = {
    ("splatnav", 1): (162.1, 23.7, 0.22),
    ("safersplat", 1): (217.5, 34.4, 0.38),
    ("atlasnav", 4096): (16_318.7, 262.2, 55.0),
    ("splanning", 4096): (157_538.5, 2_409.4, 14.50),
    ("collisionsplatting", 4096): (215_578.9, 13_653.3, 0.16),
    ("collisionsplatting", 32768): (1_638_400.0, 12_750.2, 0.166),
}


@dataclass
class ThroughputConfig:
    """Knobs of the throughput study (defaults = the full run)."""

    #: Timed evaluations after the warm-up; the median is reported.
    repeats: int = bounded(3, ge=1)
    #: Calls per timed evaluation for the batch-1 baselines (rate extrapolated per check).
    batch1_checks: int = bounded(16, ge=1)
    #: Queries actually evaluated per timed run, per method (None or missing = the whole batch).
    timed_queries: dict[str, int] = field(default_factory=lambda: {"atlasnav": 1024, "splanning": 512})
    #: Rows to run: (method, batch). ``collisionsplatting_collision_only`` uses ``collides``.
    rows: tuple[tuple[str, int], ...] = (
        ("splatnav", 1),
        ("safersplat", 1),
        ("atlasnav", 4096),
        ("splanning", 4096),
        ("collisionsplatting", 4096),
        ("collisionsplatting", 32768),
        ("collisionsplatting_collision_only", 4096),
        ("collisionsplatting_collision_only", 32768),
    )
    #: torch thread counts each baseline row is run with (None = all cores, the paper's setting);
    #: the fastest is reported, all are kept in ``checks_per_s_by_threads``. On a shared machine
    #: torch's OpenMP barriers can make small batch-1 tensors ~10-100x slower with 2 threads than 1.
    baseline_threads: tuple[int | None, ...] = bounded((None, 1), ge=1)
    #: Repeats for CollisionSplatting rows (cheap, so more of them).
    repeats_ours: int = bounded(7, ge=1)
    #: Built-in Stonehenge level (1..5).
    level: int = bounded(1, ge=1, le=5)
    #: Built-in Stonehenge seed.
    seed: int = bounded(0, ge=0)
    #: Built-in Stonehenge splat count before filtering (None: the level's default, ~200k at level 1).
    n_splats: int | None = bounded(None, ge=1)
    #: Robot sphere radius (scene units).
    radius: float = bounded(point_radius(), gt=0)
    #: CollisionSplatting's n_sigma.
    n_sigma: float = bounded(1.0, ge=0)
    #: Seed of the query generator.
    query_seed: int = bounded(0, ge=0)
    #: Wall-clock limit of one worker subprocess (s).
    worker_timeout_s: float = bounded(600.0, gt=0)
    #: Free-form note stored in the JSON.
    note: str = ""

    def validate(self) -> "ThroughputConfig":
        """Check every field's declared range (:mod:`splatplan._config`); returns self."""
        return check_config(self)

    @classmethod
    def quick(cls) -> "ThroughputConfig":
        """A < 1 min smoke version: 20k-splat scene, few checks, one timed run."""
        return cls(
            repeats=1,
            repeats_ours=2,
            batch1_checks=2,
            timed_queries={"atlasnav": 64, "splanning": 64},
            rows=(("splatnav", 1), ("safersplat", 1), ("atlasnav", 4096), ("splanning", 4096), ("collisionsplatting", 4096), ("collisionsplatting", 32768)),
            n_splats=20_000,
            baseline_threads=(None,),
            worker_timeout_s=120.0,
            note="quick run: Stonehenge level 1 with 20,000 splats (not ~200k), 1-2 timed runs; smoke test only",
        )


# ---------------------------------------------------------------------------------------------
# Memory probes (Linux /proc)
# ---------------------------------------------------------------------------------------------


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


# ---------------------------------------------------------------------------------------------
# Worker (runs in a fresh subprocess)
# ---------------------------------------------------------------------------------------------


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
            state["c"] = CollisionChecker(splats, n_sigma=n_sigma, device=device)

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
    state = {}

    def build() -> None:
        state["o"] = info.cls(splats, dev)
        sync(dev)

    def run(centers: np.ndarray) -> None:
        state["o"].score(centers, radius, batch=max(1, min(len(centers), info.native_batch)) if info.native_batch > 1 else 1)
        sync(dev)

    return build, run


def _worker(spec: dict) -> dict:
    """Time and measure one (method, batch) in this (fresh) process. See the module docstring."""
    import torch

    from .._warp import wp
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
    seconds = []
    for _ in range(int(spec["repeats"])):
        t0 = time.perf_counter()
        evaluate()
        seconds.append(time.perf_counter() - t0)
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


def _run_worker_subprocess(spec: dict, timeout_s: float) -> dict:
    """Run :func:`_worker` in a fresh interpreter; returns its result dict (or an error row)."""
    cmd = [sys.executable, "-m", "splatplan.eval.throughput", "--worker", json.dumps(spec)]
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


# ---------------------------------------------------------------------------------------------
# The study
# ---------------------------------------------------------------------------------------------


def _fmt(x: float | None, nd: int = 1) -> str:
    if x is None or not np.isfinite(x):
        return "-"
    return f"{x:,.{nd}f}"


def _markdown(res: dict) -> str:
    dev = res["device"]
    col = "GPU" if dev.startswith("cuda") else "CPU"
    lines = [
        "# E2 throughput and memory (paper Table I)",
        "",
        f"Ours: {dev} ({res['cpu']}, {res['cores']} cores), Stonehenge level {res['config']['level']} "
        f"({res['n_splats']:,} splats after filtering), sphere r = {res['radius']}, n_sigma = {res['n_sigma']} (ours). "
        f"Paper: RTX 6000 Pro GPU / 16-core Ryzen 9 9950X CPU.",
        "",
    ]
    if res.get("note"):
        lines += [f"**{res['note']}**", ""]
    lines += [
        f"| method | batch | checks/s ours ({col}) | peak memory ours (MB) | paper {col} checks/s | paper GPU checks/s | paper memory (GB) | timed |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in res["rows"]:
        key = r["method"]
        base = key.replace("_collision_only", "")
        name = DISPLAY.get(base, base) + (" (collision-only)" if key.endswith("collision_only") else "")
        g, c, m = PAPER_TABLE_I.get((key, r["batch"]), (None, None, None))
        if "error" in r:
            lines.append(f"| {name} | {r['batch']:,} | error: {r['error']} | | {_fmt(c if col == 'CPU' else g)} | {_fmt(g)} | {_fmt(m, 3)} | |")
            continue
        if r["batch"] == 1:
            timed = f"{r['timed_queries']} one-at-a-time checks per run"
        else:
            timed = f"{r['timed_queries']:,} queries" + (", extrapolated per check" if r["extrapolated"] else "")
        timed += f", median of {len(r['seconds'])}"
        if "checks_per_s_by_threads" in r:
            timed += ", torch threads " + " / ".join(f"{k}: {v:,.1f}/s" for k, v in r["checks_per_s_by_threads"].items())
        lines.append(
            f"| {name} | {r['batch']:,} | {_fmt(r['checks_per_s'])} ± {_fmt(r['checks_per_s_std'])} | {_fmt(r['peak_mem_mb'])} | "
            f"{_fmt(c if col == 'CPU' else g)} | {_fmt(g)} | {_fmt(m, 3)} | {timed} |"
        )
    t = res["targets"]
    lines += [
        "",
        f"- Speed-up of CollisionSplatting (batch 4096, full query) over the fastest baseline in this run "
        f"({DISPLAY.get(t['fastest_baseline'], t['fastest_baseline'])}): {t['speedup_vs_fastest_baseline']:.1f}x "
        f"(paper {col}: {t['paper_speedup_vs_fastest_baseline']:.1f}x).",
        f"- Memory of CollisionSplatting vs the batched baselines: {t['ours_mem_mb']:.1f} MB vs "
        + ", ".join(f"{DISPLAY[k]} {v:.1f} MB" for k, v in t["batched_baseline_mem_mb"].items())
        + f" -> lowest: {t['ours_memory_lowest_among_batched']}.",
        "- Memory: " + res["memory_measure"] + ".",
        f"- Batch-1 baselines: {res['config']['batch1_checks']} one-at-a-time checks per timed run (per-check rate). "
        "ATLASNav/SPLANNING rows marked 'extrapolated' were timed on the first N of their 4096 queries in one call; "
        "on CPU the classes chunk the batch under a fixed element budget, so time is linear in the batch and memory the same.",
        f"- Total wall time {res['seconds_total']:.0f} s.",
        "",
    ]
    return "\n".join(lines)


def report(res: dict) -> str:
    """The markdown table of E2 (ours beside the paper's Table I)."""
    return _markdown(res)


def run_throughput(out_dir: Path, quick: bool = False, device: str = "auto", config: ThroughputConfig | None = None) -> dict:
    """Run E2 and write ``throughput.json`` and ``throughput.md`` into ``out_dir``.

    Args:
        out_dir: output folder (created).
        quick: the < 1 min smoke version (:meth:`ThroughputConfig.quick`).
        device: "auto" (CUDA when present), "cpu" or "cuda"/"cuda:N" (every method runs there).
        config: explicit knobs (override ``quick``).

    Returns:
        The dict written to ``throughput.json``.
    """
    from .._warp import resolve_device

    cfg = (config or (ThroughputConfig.quick() if quick else ThroughputConfig())).validate()
    dev = resolve_device(device)  # clear error for a missing GPU
    if dev.startswith("cuda"):
        import torch

        if not torch.cuda.is_available():
            raise SplatplanError("device 'cuda' requested but torch sees no CUDA device; use --device cpu")
    if cfg.repeats < 1 or cfg.batch1_checks < 1:
        raise SplatplanError("ThroughputConfig: repeats and batch1_checks must be >= 1")
    for m, b in cfg.rows:
        if m.replace("_collision_only", "") not in DISPLAY or b < 1:
            raise SplatplanError(f"unknown throughput row ({m!r}, {b})")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    t_all = time.perf_counter()
    from .._progress import progress

    rows = []
    for method, batch in progress(cfg.rows, desc="throughput", unit="row"):
        spec = {
            "method": method,
            "batch": int(batch),
            "device": dev,
            "radius": cfg.radius,
            "n_sigma": cfg.n_sigma,
            "level": cfg.level,
            "seed": cfg.seed,
            "n_splats": cfg.n_splats,
            "query_seed": cfg.query_seed,
            "repeats": cfg.repeats_ours if method.startswith("collisionsplatting") else cfg.repeats,
            "batch1_checks": cfg.batch1_checks,
            "timed_queries": cfg.timed_queries.get(method),
        }
        if method.startswith("collisionsplatting"):
            rows.append(_run_worker_subprocess(spec, cfg.worker_timeout_s))
            continue
        tries = []
        for th in dict.fromkeys(cpu_threads() if t is None else int(t) for t in cfg.baseline_threads):
            tries.append(_run_worker_subprocess({**spec, "torch_threads": th}, cfg.worker_timeout_s))
        good = [t for t in tries if "error" not in t]
        row = max(good, key=lambda t: t["checks_per_s"]) if good else tries[0]
        if good:
            row = {**row, "checks_per_s_by_threads": {str(t["torch_threads"]): t["checks_per_s"] for t in good}}
        rows.append(row)
    ok = [r for r in rows if "error" not in r]
    if not any(r["method"] == "collisionsplatting" for r in ok):
        errs = "; ".join(f"{r['method']}: {r['error']}" for r in rows if "error" in r)
        raise SplatplanError(f"throughput study failed: {errs or 'no CollisionSplatting row'}")

    def rate(m: str, b: int | None = None) -> float:
        v = [r["checks_per_s"] for r in ok if r["method"] == m and (b is None or r["batch"] == b)]
        return max(v) if v else float("nan")

    ours = rate("collisionsplatting", 4096) if np.isfinite(rate("collisionsplatting", 4096)) else rate("collisionsplatting")
    base = {m: rate(m) for m in ("splatnav", "safersplat", "atlasnav", "splanning") if np.isfinite(rate(m))}
    fastest = max(base, key=base.get) if base else "none"
    col = 0 if dev.startswith("cuda") else 1
    paper_fastest = max(PAPER_TABLE_I[(m, b)][col] for m, b in PAPER_TABLE_I if m != "collisionsplatting")
    mem = {r["method"]: r["peak_mem_mb"] for r in ok if r["method"] in ("atlasnav", "splanning")}
    ours_mem = max((r["peak_mem_mb"] for r in ok if r["method"] == "collisionsplatting" and r["batch"] == 4096), default=float("nan"))
    first = ok[0]
    res = {
        "device": dev,
        "rows": rows,
        "cpu": platform.processor() or platform.machine(),
        "cores": cpu_threads(),
        "n_splats": first["n_splats"],
        "floaters_dropped": first["floaters_dropped"],
        "radius": cfg.radius,
        "n_sigma": cfg.n_sigma,
        "memory_measure": first["memory_measure"] + ", each (method, batch) in a fresh subprocess, above libraries, scene arrays and queries",
        "paper_table_i": {f"{m}@{b}": {"gpu_checks_per_s": v[0], "cpu_checks_per_s": v[1], "memory_gb": v[2]} for (m, b), v in PAPER_TABLE_I.items()},
        "targets": {
            "fastest_baseline": fastest,
            "speedup_vs_fastest_baseline": ours / base[fastest] if base else float("nan"),
            "paper_speedup_vs_fastest_baseline": PAPER_TABLE_I[("collisionsplatting", 4096)][col] / paper_fastest,
            "ours_at_least_10x_fastest_baseline": bool(base and ours >= 10 * base[fastest]),
            "ours_mem_mb": ours_mem,
            "batched_baseline_mem_mb": mem,
            "ours_memory_lowest_among_batched": bool(mem and all(ours_mem < v for v in mem.values())),
        },
        "quick": bool(quick),
        "note": cfg.note,
        "config": {k: ([list(x) for x in v] if k == "rows" else v) for k, v in asdict(cfg).items()},
        "seconds_total": time.perf_counter() - t_all,
    }
    (out_dir / "throughput.json").write_text(json.dumps(res, indent=2) + "\n")
    (out_dir / "throughput.md").write_text(_markdown(res))
    return res


def _main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="E2 throughput worker (internal): one (method, batch) per process")
    ap.add_argument("--worker", required=True, help="JSON spec")
    args = ap.parse_args(argv)
    res = _worker(json.loads(args.worker))
    sys.stdout.write(json.dumps(res) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(_main())
