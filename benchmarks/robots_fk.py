"""Forward-kinematics throughput: robot configurations -> world poses of every collision ellipsoid.

configs/s for the numpy reference (float64, ``Robot.ellipsoid_frames``) and for the Warp kernel
(float32, ``Robot.fk_wp``: inputs already a wp.array on the device, outputs preallocated and
reused, i.e. the device-resident path; on the CPU the batch is split across the robot's thread
pool). configs/s is wall-clock; "configs per CPU-second" divides by the process's CPU time (all
threads), the per-core rate, which stays meaningful when other jobs share the cores. Warm-up first (kernel compile), then the median of timed runs, the device synchronised.
The numpy reference is skipped above ``--numpy-max`` configurations (it materialises every link
transform in float64: ~1.7 GB at 1M Panda configurations).

    python benchmarks/robots_fk.py [--robot panda] [--device cpu|cuda] [--batches 10000,100000,1000000]
                                   [--repeats 5] [--out benchmarks/results/robots_fk.json]

Target (issue 12): >= 1,000,000 Panda configurations/s for the Warp kernel on this 2-core CPU.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np


def _median_time(fn, repeats: int, sync) -> tuple[float, list[float], float]:
    """(median wall seconds, all wall times, median process CPU seconds over all threads)."""
    times, cpu = [], []
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        fn()
        sync()
        times.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return float(np.median(times)), times, float(np.median(cpu))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="panda")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--batches", default="10000,100000,1000000")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--numpy-max", type=int, default=200_000, help="largest batch for the numpy reference")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "robots_fk.json"))
    args = ap.parse_args(argv)

    from splatplan._warp import cpu_threads, resolve_device
    from splatplan._warp import wp as _wp
    from splatplan.robots import load_robot

    wp = _wp()
    device = resolve_device(args.device)
    robot = load_robot(args.robot)
    e = robot.n_ellipsoids
    rng = np.random.default_rng(0)
    lo = np.where(np.isfinite(robot.joint_limits[:, 0]), robot.joint_limits[:, 0], -5.0)
    hi = np.where(np.isfinite(robot.joint_limits[:, 1]), robot.joint_limits[:, 1], 5.0)
    rows = []
    for b in [int(x) for x in args.batches.split(",")]:
        q = rng.uniform(lo, hi, size=(b, robot.dof))
        if b <= args.numpy_max:
            robot.ellipsoid_frames(q[:16])  # warm-up
            med, times, cpu = _median_time(lambda: robot.ellipsoid_frames(q), max(1, min(args.repeats, 3)), lambda: None)
            rows.append({"method": "numpy_reference", "device": "cpu", "batch": b, "configs_per_s": b / med,
                         "configs_per_cpu_s": b / max(cpu, 1e-9), "ellipsoid_poses_per_s": b * e / med,
                         "seconds_median": med})  # fmt: skip
        qw = wp.array(q.astype(np.float32), dtype=wp.float32, device=device)
        oc = wp.empty(b * e, dtype=wp.vec3, device=device)
        orr = wp.empty(b * e, dtype=wp.mat33, device=device)
        robot.fk_wp(qw, oc, orr)  # warm-up (compile, model upload, thread pool)
        wp.synchronize_device(device)
        med, times, cpu = _median_time(lambda: robot.fk_wp(qw, oc, orr), args.repeats, lambda: wp.synchronize_device(device))
        rows.append({"method": "warp_kernel", "device": device, "batch": b, "configs_per_s": b / med,
                     "configs_per_s_std": float(np.std([b / t for t in times])),
                     "configs_per_cpu_s": b / max(cpu, 1e-9) if device == "cpu" else float("nan"),
                     "ellipsoid_poses_per_s": b * e / med, "seconds_median": med})  # fmt: skip
        del qw, oc, orr
    result = {
        "robot": robot.name,
        "dof": robot.dof,
        "n_ellipsoids": e,
        "device": device,
        "cpu": platform.processor() or platform.machine(),
        "threads": cpu_threads(),
        "load_average_1min": os.getloadavg()[0],
        "inputs": "q as wp.array(float32) on the device, outputs preallocated wp.arrays (vec3 centres, mat33 rotations)",
        "rows": rows,
    }
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")

    print(f"FK of {robot.name} ({robot.dof} dof, {e} ellipsoids) on {device} ({result['threads']} CPU threads)")
    print(f"load average (1 min) {result['load_average_1min']:.1f}: on a shared machine configs/s (wall) understates the kernel;")
    print("configs per CPU-second (process CPU time of all threads) is the per-core rate")
    print("| method | device | batch | configs/s (wall) | configs per CPU-second | ellipsoid poses/s | median time (s) |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['method']} | {r['device']} | {r['batch']:,} | {r['configs_per_s']:,.0f} | {r['configs_per_cpu_s']:,.0f} |"
              f" {r['ellipsoid_poses_per_s']:,.0f} | {r['seconds_median']:.4f} |")  # fmt: skip
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
