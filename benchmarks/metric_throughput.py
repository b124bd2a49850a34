"""Throughput and memory of the CollisionSplatting kernel on the built-in Stonehenge scene.

checks/s = robot poses checked per second (one sphere link, r = 0.015, n_sigma = 1), at batch
4096 and 32768; half the queries uniform in the scene bounds, half within 0.05 of a splat mean.
Warm-up first, then the median of timed runs. Memory (CPU): after the scene is loaded, freed heap
pages are returned to the OS and the RSS high-water mark is reset; "extra peak memory" is VmHWM
minus that baseline after building the checker (tiers, hash grids, data copies), the warm-up and
all timed queries of that batch size, i.e. everything CollisionSplatting adds above the scene.

    python benchmarks/metric_throughput.py [--device cpu|cuda] [--repeats 7] [--out benchmarks/results/metric_throughput.json]

Prints a markdown table with the paper's Table I numbers beside ours and writes JSON.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

PAPER = {  # Table I: (GPU checks/s, CPU checks/s, memory GB) on an RTX 6000 Pro / 16-core Ryzen 9 9950X
    4096: (215_578.9, 13_653.3, 0.16),
    32768: (1_638_400.0, 12_750.2, 0.166),
}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--batches", default="4096,32768")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "metric_throughput.json"))
    args = ap.parse_args(argv)

    from splatplan._warp import cpu_threads, wp
    from splatplan.metric import CollisionChecker
    from splatplan.scenes.filters import filter_floaters
    from splatplan.eval._common import make_queries
    from splatplan.eval.throughput import proc_status_mb, reset_peak_rss, trim_heap
    from splatplan.scenes.stonehenge import build_stonehenge

    scene, _ = build_stonehenge(level=1, seed=0)
    scene, rep = filter_floaters(scene)
    lo, hi = scene.bounds()
    rng = np.random.default_rng(0)
    radius = 0.015
    rows = []
    wp()  # load Warp before the baseline
    for b in [int(x) for x in args.batches.split(",")]:
        centers = make_queries(scene.means, lo, hi, b, rng)
        trim_heap()
        rss0 = proc_status_mb("VmRSS")
        hwm_ok = reset_peak_rss()
        checker = CollisionChecker(scene, n_sigma=1.0, device=args.device)
        checker.query(centers, None, radius)  # warm-up: compile, build grids
        checker.collides(centers, None, radius)
        wp().synchronize()
        for fn in ("query", "collides"):
            times = []
            for _ in range(args.repeats):
                t = time.perf_counter()
                getattr(checker, fn)(centers, None, radius)
                wp().synchronize()
                times.append(time.perf_counter() - t)
            med = float(np.median(times))
            rows.append({
                "method": "collisionsplatting" + ("" if fn == "query" else "_collision_only"),
                "batch": b,
                "checks_per_s": b / med,
                "checks_per_s_std": float(np.std([b / t for t in times])),
                "seconds_median": med,
                "peak_mem_mb": proc_status_mb("VmHWM") - rss0 if hwm_ok and args.device == "cpu" else float("nan"),
            })  # fmt: skip
    result = {
        "device": checker.device,
        "cpu": platform.processor() or platform.machine(),
        "threads": cpu_threads(),
        "n_splats": len(scene),
        "floaters_dropped": rep.n_dropped,
        "radius": radius,
        "n_sigma": 1.0,
        "rows": rows,
    }
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")

    print(f"CollisionSplatting on {result['device']} ({result['threads']} threads), {len(scene):,} splats, sphere r={radius}, n_sigma=1")
    print("| variant | batch | checks/s (ours) | extra peak memory (MB) | paper CPU checks/s | paper GPU checks/s | paper GB |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        g, c, m = PAPER.get(r["batch"], (float("nan"),) * 3)
        print(f"| {r['method']} | {r['batch']:,} | {r['checks_per_s']:,.0f} | {r['peak_mem_mb']:.1f} | {c:,.1f} | {g:,.1f} | {m} |")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
