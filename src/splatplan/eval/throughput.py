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

Code: :func:`run` is the protocol (``run(ThroughputConfig(...)) -> ThroughputResult``, no files
written); each (method, batch) row is measured by ``_throughput_worker`` in its own interpreter,
with the memory and timing probes of ``_harness`` (shared with ``benchmarks/metric_throughput.py``).
:func:`report` writes ``throughput.json`` and ``throughput.md`` (ours beside the paper's Table I).
"""

from __future__ import annotations

import platform
import time
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from .._config import bounded
from ..errors import SplatplanError
from .._progress import progress
from .._warp import cpu_threads
from ..robots import point_radius
from ._common import DISPLAY
from ._study import StudyConfig, config_dict, note_lines, write_outputs

__all__ = ["PAPER_TABLE_I", "ThroughputConfig", "ThroughputResult", "markdown", "report", "run"]

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
class ThroughputConfig(StudyConfig):
    """Knobs of the throughput study (defaults = the full run); every method runs on ``device``."""

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

    def check(self) -> None:
        """Every row names a known method and a batch >= 1 (the other ranges are declared with the fields)."""
        for m, b in self.rows:
            if m.replace("_collision_only", "") not in DISPLAY or b < 1:
                raise SplatplanError(f"unknown throughput row ({m!r}, {b})")

    @classmethod
    def quick_config(cls) -> "ThroughputConfig":
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
            quick=True,
        )


@dataclass
class ThroughputResult:
    """What E2 measured; every field is a key of ``throughput.json`` (same names, same order)."""

    #: where every method ran (resolved: "cpu" or "cuda:N")
    device: str
    #: one dict per (method, batch): checks_per_s (+ std), peak_mem_mb, timed_queries,
    #: extrapolated, seconds, prep/warm-up figures, threads; or ``error``
    rows: list[dict]
    #: the CPU's name and the cores this process may use
    cpu: str
    cores: int
    #: the scene: splats after the floater filter and the floaters dropped
    n_splats: int
    floaters_dropped: int
    #: robot sphere radius (scene units) and CollisionSplatting's n_sigma
    radius: float
    n_sigma: float
    #: how the memory was measured, in words
    memory_measure: str
    #: the paper's Table I, "method@batch" -> GPU / CPU checks/s and memory (GB)
    paper_table_i: dict[str, dict]
    #: fastest baseline, speed-up of ours over it (ours and the paper's), memory comparison
    targets: dict[str, Any]
    #: the smoke-test settings were used
    quick: bool
    note: str
    #: the ThroughputConfig (tuples as lists)
    config: dict[str, Any]
    seconds_total: float

    def to_json(self) -> dict[str, Any]:
        """The content of ``throughput.json``."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


def _fmt(x: float | None, nd: int = 1) -> str:
    if x is None or not np.isfinite(x):
        return "-"
    return f"{x:,.{nd}f}"


def _markdown(res: dict[str, Any]) -> str:
    dev = res["device"]
    col = "GPU" if dev.startswith("cuda") else "CPU"
    lines = [
        "# E2 throughput and memory (paper Table I)",
        "",
        f"Ours: {dev} ({res['cpu']}, {res['cores']} cores), Stonehenge level {res['config']['level']} "
        f"({res['n_splats']:,} splats after filtering), sphere r = {res['radius']}, n_sigma = {res['n_sigma']} (ours). "
        f"Paper: RTX 6000 Pro GPU / 16-core Ryzen 9 9950X CPU.",
        "",
        *note_lines(res.get("note")),
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


def markdown(result: ThroughputResult) -> str:
    """The markdown table of E2 (ours beside the paper's Table I)."""
    return _markdown(result.to_json())


def _row_spec(cfg: ThroughputConfig, method: str, batch: int, device: str) -> dict[str, Any]:
    """The worker's spec of one (method, batch) row."""
    return {
        "method": method,
        "batch": int(batch),
        "device": device,
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


def _measure_row(cfg: ThroughputConfig, spec: dict[str, Any]) -> dict[str, Any]:
    """One row, each in a fresh worker process: ours once; a baseline once per torch thread count
    of ``baseline_threads`` (the fastest reported, every rate kept in ``checks_per_s_by_threads``)."""
    from ._throughput_worker import run_worker_subprocess

    if spec["method"].startswith("collisionsplatting"):
        return run_worker_subprocess(spec, cfg.worker_timeout_s)
    tries = [run_worker_subprocess({**spec, "torch_threads": th}, cfg.worker_timeout_s) for th in dict.fromkeys(cpu_threads() if t is None else int(t) for t in cfg.baseline_threads)]
    good = [t for t in tries if "error" not in t]
    if not good:
        return tries[0]
    row = max(good, key=lambda t: t["checks_per_s"])
    return {**row, "checks_per_s_by_threads": {str(t["torch_threads"]): t["checks_per_s"] for t in good}}


def _targets(ok: list[dict], device: str) -> dict[str, Any]:
    """Speed-up of ours (batch 4096) over the fastest baseline, ours and the paper's; memory against the batched baselines."""

    def rate(m: str, b: int | None = None) -> float:
        v = [r["checks_per_s"] for r in ok if r["method"] == m and (b is None or r["batch"] == b)]
        return max(v) if v else float("nan")

    ours = rate("collisionsplatting", 4096) if np.isfinite(rate("collisionsplatting", 4096)) else rate("collisionsplatting")
    base = {m: rate(m) for m in ("splatnav", "safersplat", "atlasnav", "splanning") if np.isfinite(rate(m))}
    fastest = max(base, key=lambda m: base[m]) if base else "none"
    col = 0 if device.startswith("cuda") else 1
    paper_fastest = max(PAPER_TABLE_I[(m, b)][col] for m, b in PAPER_TABLE_I if m != "collisionsplatting")
    mem = {r["method"]: r["peak_mem_mb"] for r in ok if r["method"] in ("atlasnav", "splanning")}
    ours_mem = max((r["peak_mem_mb"] for r in ok if r["method"] == "collisionsplatting" and r["batch"] == 4096), default=float("nan"))
    return {
        "fastest_baseline": fastest,
        "speedup_vs_fastest_baseline": ours / base[fastest] if base else float("nan"),
        "paper_speedup_vs_fastest_baseline": PAPER_TABLE_I[("collisionsplatting", 4096)][col] / paper_fastest,
        "ours_at_least_10x_fastest_baseline": bool(base and ours >= 10 * base[fastest]),
        "ours_mem_mb": ours_mem,
        "batched_baseline_mem_mb": mem,
        "ours_memory_lowest_among_batched": bool(mem and all(ours_mem < v for v in mem.values())),
    }


def run(config: ThroughputConfig) -> ThroughputResult:
    """Run E2 (the protocol of the module docstring): every row in its own worker process; writes no file.

    Args:
        config: the knobs (:meth:`ThroughputConfig.quick_config` for the smoke version); validated here.

    Raises:
        SplatplanError: a bad config, CUDA asked for but absent, or no CollisionSplatting row measured.
    """
    from .._warp import resolve_device

    cfg = config.validate()
    dev = resolve_device(cfg.device)  # clear error for a missing GPU
    if dev.startswith("cuda"):
        import torch

        if not torch.cuda.is_available():
            raise SplatplanError("device 'cuda' requested but torch sees no CUDA device; use --device cpu")
    t_all = time.perf_counter()
    rows = [_measure_row(cfg, _row_spec(cfg, m, b, dev)) for m, b in progress(cfg.rows, desc="throughput", unit="row")]
    ok = [r for r in rows if "error" not in r]
    if not any(r["method"] == "collisionsplatting" for r in ok):
        errs = "; ".join(f"{r['method']}: {r['error']}" for r in rows if "error" in r)
        raise SplatplanError(f"throughput study failed: {errs or 'no CollisionSplatting row'}")
    first = ok[0]
    return ThroughputResult(
        device=dev,
        rows=rows,
        cpu=platform.processor() or platform.machine(),
        cores=cpu_threads(),
        n_splats=first["n_splats"],
        floaters_dropped=first["floaters_dropped"],
        radius=cfg.radius,
        n_sigma=cfg.n_sigma,
        memory_measure=first["memory_measure"] + ", each (method, batch) in a fresh subprocess, above libraries, scene arrays and queries",
        paper_table_i={f"{m}@{b}": {"gpu_checks_per_s": v[0], "cpu_checks_per_s": v[1], "memory_gb": v[2]} for (m, b), v in PAPER_TABLE_I.items()},
        targets=_targets(ok, dev),
        quick=bool(cfg.quick),
        note=cfg.note,
        config=config_dict(cfg),
        seconds_total=time.perf_counter() - t_all,
    )


def report(result: ThroughputResult, out_dir: str | Path) -> list[Path]:
    """Write ``throughput.json`` and ``throughput.md`` into ``out_dir`` (an existing folder); returns their paths."""
    return write_outputs(out_dir, "throughput", result.to_json(), markdown(result))
