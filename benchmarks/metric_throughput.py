"""Throughput and memory of the CollisionSplatting kernel on the built-in Stonehenge scene.

checks/s = robot poses checked per second (one sphere link, r = 0.015, n_sigma = 1), at batch
4096 and 32768; half the queries uniform in the scene bounds, half within 0.05 of a splat mean.
Warm-up first, then the median of timed runs. Memory (CPU): after the scene is loaded, freed heap
pages are returned to the OS and the RSS high-water mark is reset; "extra peak memory" is VmHWM
minus that baseline after building the checker (tiers, hash grids, data copies), the warm-up and
all timed queries of that batch size, i.e. everything CollisionSplatting adds above the scene.

``rows``: numpy inputs (the host adapter: validation, float32 conversion, copy to the device).
``device_rows``: the same queries as a ``wp.array`` already on the checker's device, results into
a preallocated workspace (no host work per call beyond the launch).
``robot_rows``: the Panda (7 DoF, every collision ellipsoid of its default model: the tight model's
53 since issue 19; the committed results are the coarse model's 11, semi-axes 0.018-0.24 m) through
``query_robot`` / ``collides_robot`` (Warp FK -> metric on the device) at random joint
configurations within the limits, robot base at the scene origin on the ground (so its base
ellipsoid always touches ground splats): configurations/s and ellipsoid checks/s, q passed as
numpy or as a ``wp.array``. On Stonehenge as built (scale 1: 1 m across, the arm is larger than
the ring, and each link's neighbourhood holds a large share of the 200k splats) and scaled x4
(4 m across, stones ~0.8 m: an arm among the stones).
The 1-minute load average is recorded: the machine is shared, and wall-clock figures taken under
load are noisy; ``cpu_equiv_checks_per_s`` (queries per CPU-second of this process times the
thread count) estimates what an idle machine gives, assuming the threads scale perfectly.

    python benchmarks/metric_throughput.py [--device cpu|cuda] [--repeats 7] [--out benchmarks/results/metric_throughput.json]

Prints a markdown table with the paper's Table I numbers beside ours and writes JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
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
    ap.add_argument("--robot-configs", default="auto", help="Panda configurations per call (comma list; auto: largest batch / 32, at most 1024; empty: skip)")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "metric_throughput.json"))
    args = ap.parse_args(argv)

    from splatplan._warp import cpu_threads, wp
    from splatplan.eval._common import make_queries
    from splatplan.eval._harness import proc_status_mb, reset_peak_rss, timed_runs, trim_heap
    from splatplan.metric import CollisionChecker
    from splatplan.scenes.builtin.stonehenge import build_stonehenge
    from splatplan.scenes.filters import filter_floaters

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
            times, cpu = timed_runs(lambda fn=fn: getattr(checker, fn)(centers, None, radius), args.repeats, sync=wp().synchronize)
            med = float(np.median(times))
            rows.append({
                "method": "collisionsplatting" + ("" if fn == "query" else "_collision_only"),
                "batch": b,
                "checks_per_s": b / med,
                "checks_per_s_std": float(np.std([b / t for t in times])),
                "seconds_median": med,
                "cpu_equiv_checks_per_s": b * cpu_threads() / float(np.median(cpu)) if args.device == "cpu" else float("nan"),
                "peak_mem_mb": proc_status_mb("VmHWM") - rss0 if hwm_ok and args.device == "cpu" else float("nan"),
            })  # fmt: skip
    device_rows = _device_rows(checker, scene, lo, hi, [int(x) for x in args.batches.split(",")], radius, args.repeats)
    batches = [int(x) for x in args.batches.split(",")]
    rc = [min(1024, max(1, max(batches) // 32))] if args.robot_configs == "auto" else [int(x) for x in args.robot_configs.split(",") if x]
    robot_rows = _robot_rows(scene, args.device, rc, args.repeats)
    result = {
        "device": checker.device,
        "load_avg_1min": round(os.getloadavg()[0], 2),
        "cpu": platform.processor() or platform.machine(),
        "threads": cpu_threads(),
        "n_splats": len(scene),
        "floaters_dropped": rep.n_dropped,
        "radius": radius,
        "n_sigma": 1.0,
        "rows": rows,
        "device_rows": device_rows,
        "robot_rows": robot_rows,
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
    if args.device == "cpu":
        print("checks per CPU-second x threads (what an idle machine would give, read when the wall figures are noisy): "
              + ", ".join(f"{r['method']} {r['batch']:,}: {r['cpu_equiv_checks_per_s']:,.0f}" for r in rows))
    print()
    print("| inputs | variant | batch | checks/s |")
    print("|---|---|---|---|")
    for r in device_rows:
        print(f"| {r['inputs']} | {r['method']} | {r['batch']:,} | {r['checks_per_s']:,.0f} |")
    if robot_rows:
        print()
        print(f"Panda ({robot_rows[0]['n_ellipsoids']} ellipsoids) on the same scene scaled x1 / x4, n_sigma=1")
        print("| scene scale | call | q as | configurations | configurations/s | ellipsoid checks/s | in collision (excl. base link) |")
        print("|---|---|---|---|---|---|---|")
        for r in robot_rows:
            print(
                f"| x{r['scene_scale']:g} | {r['method']} | {r['inputs']} | {r['configs']:,} | {r['configs_per_s']:,.0f} | "
                f"{r['ellipsoid_checks_per_s']:,.0f} | {r['frac_configs_in_collision_excl_base']:.2f} |"
            )
    print(f"(1-min load average: {result['load_avg_1min']} on {result['threads']} threads)")
    print(f"wrote {out}")
    return 0


def _median_time(fn, repeats: int) -> float:
    from splatplan._warp import wp
    from splatplan.eval._harness import timed_runs

    return float(np.median(timed_runs(fn, repeats, sync=wp().synchronize)[0]))


def _device_rows(checker, scene, lo, hi, batches: list[int], radius: float, repeats: int) -> list[dict]:
    """Sphere queries passed as a wp.array on the checker's device, results into a workspace."""
    from splatplan._warp import wp
    from splatplan.eval._common import make_queries

    w = wp()
    rows = []
    rng = np.random.default_rng(0)
    for b in batches:
        c = make_queries(scene.means, lo, hi, b, rng)
        cw = w.array(c.astype(np.float32), dtype=w.vec3, device=checker.device)
        ws = checker.workspace(b)
        checker.query(cw, None, radius, out=ws)
        checker.collides(cw, None, radius, out=ws)
        for fn, name in ((checker.query, "collisionsplatting"), (checker.collides, "collisionsplatting_collision_only")):
            med = _median_time(lambda fn=fn: fn(cw, None, radius, out=ws), repeats)
            rows.append({"method": name, "inputs": "wp.array (device-resident) + workspace", "batch": b, "checks_per_s": b / med, "seconds_median": med})
    return rows


def _robot_rows(scene, device: str, configs: list[int], repeats: int) -> list[dict]:
    """Panda query_robot / collides_robot on the scene at scale 1 and 4 (skipped without the robots stage)."""
    try:
        from splatplan.robots import load_robot
    except ImportError:
        return []
    from splatplan._warp import wp
    from splatplan.metric import CollisionChecker
    from splatplan.scenes.splats import Splats

    w = wp()
    robot = load_robot("panda")
    e = robot.n_ellipsoids
    rows = []
    for scale in (1.0, 4.0):
        scaled = Splats(scene.means * scale, scene.quats, scene.scales * scale, scene.opacities, scene.colors)
        checker = CollisionChecker(scaled, n_sigma=1.0, device=device)
        rng = np.random.default_rng(1)
        for n in configs:
            q = rng.uniform(robot.joint_limits[:, 0], robot.joint_limits[:, 1], (n, robot.dof))
            qw = w.array(q.astype(np.float32), device=checker.device)
            ws = checker.workspace(n * e)
            hit = np.asarray(checker.collides_robot(robot, q))  # warm-up
            checker.query_robot(robot, qw, out=ws)
            for name in ("query_robot", "collides_robot"):
                fn = getattr(checker, name)
                for label, arg, kw in (("numpy", q, {}), ("wp.array + workspace", qw, {"out": ws})):
                    med = _median_time(lambda fn=fn, arg=arg, kw=kw: fn(robot, arg, **kw), repeats if scale > 1 else min(repeats, 3))
                    rows.append({
                        "method": name, "inputs": label, "scene_scale": scale, "configs": n, "n_ellipsoids": e,
                        "configs_per_s": n / med, "ellipsoid_checks_per_s": n * e / med, "seconds_median": med,
                        "frac_configs_in_collision": float(hit.any(axis=-1).mean()),
                        "frac_configs_in_collision_excl_base": float(hit[:, 1:].any(axis=-1).mean()),
                    })  # fmt: skip
        checker.close()
    return rows


if __name__ == "__main__":
    sys.exit(main())
