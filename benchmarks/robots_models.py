"""What a Panda collision model costs and how well it fits: coarse (one ellipsoid per link) vs tight vs cover.

Per model: the ellipsoid count; the fit measured per link (``robots.fit_measure``: worst surface
coverage, largest union volume ratio, largest reach beyond the mesh); and the metric's cost per
configuration on the built-in tabletop scene, as configurations/s of ``checker.query_robot`` (all
five outputs) and ``checker.collides_robot`` (the bool), q uniform in the joint limits, the batch
a numpy array (so the timing includes the host transfer). Warm-up first, then the median of timed
runs, as wall-clock configs/s and as configs per CPU-second of the process (``time.process_time``,
every thread; steadier than wall-clock on a shared machine, though spinning worker threads count).
``--mppi-steps N`` (default 3; 0 skips) also times the arm's MPC loop with each model: ``run_arm``
at K = 256, T = 32, collision cost on every step (``eval.arm.arm_throughput``'s setting) on a
200k-splat tabletop, as MPC steps/s (wall) and per CPU-second, after a warm-up step.

    python benchmarks/robots_models.py [--models coarse,tight,cover] [--batch 4096] [--repeats 5]
                                       [--samples 5000] [--mppi-steps 3] [--out benchmarks/results/robots_models.json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", default="coarse,tight,cover")
    ap.add_argument("--batch", type=int, default=4096)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--samples", type=int, default=5000, help="Monte Carlo samples per link for the fit measurement (0: skip)")
    ap.add_argument("--n-splats", type=int, default=None, help="tabletop splat count (default: the scene's)")
    ap.add_argument("--mppi-steps", type=int, default=3, help="timed arm MPC steps per model at K = 256, T = 32 (0: skip)")
    ap.add_argument("--mppi-splats", type=int, default=200_000, help="tabletop splat count of the MPC timing")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "robots_models.json"))
    args = ap.parse_args(argv)

    from splatplan.metric import CollisionChecker
    from splatplan.robots import load_robot
    from splatplan.robots.builtin import DATA, PANDA_MODELS
    from splatplan.robots.fit_measure import measure_robot
    from splatplan.scenes.builtin import build_builtin

    splats, _ = build_builtin("tabletop", n_splats=args.n_splats)
    checker = CollisionChecker(splats, device="cpu")
    rows = []
    for name in args.models.split(","):
        if not (DATA / PANDA_MODELS[name]).is_file():
            print(f"skipping {name}: no {PANDA_MODELS[name]}")
            continue
        robot = load_robot("panda", model=name)
        rng = np.random.default_rng(0)
        q = rng.uniform(robot.joint_limits[:, 0], robot.joint_limits[:, 1], size=(args.batch, robot.dof)).astype(np.float32)
        row = {"model": name, "n_ellipsoids": robot.n_ellipsoids, "batch": args.batch}
        for fn in ("query_robot", "collides_robot"):
            f = getattr(checker, fn)
            f(robot, q[:64])  # warm-up: kernels, thread pool, device copy of the model
            times, cpu = [], []
            for _ in range(args.repeats):
                t, c = time.perf_counter(), time.process_time()
                f(robot, q)
                times.append(time.perf_counter() - t)
                cpu.append(time.process_time() - c)
            row[f"{fn}_configs_per_s"] = args.batch / float(np.median(times))
            row[f"{fn}_configs_per_cpu_s"] = args.batch / max(float(np.median(cpu)), 1e-9)
        if args.mppi_steps > 0:
            row.update(mppi_rate(robot, args.mppi_steps, n_splats=args.mppi_splats))
        if args.samples:
            m = [v for v in measure_robot(robot, n_samples=args.samples, n_surface=500).values() if v is not None]
            row.update(
                min_coverage_surface=min(v.coverage_surface for v in m),
                max_volume_ratio=max(v.volume_ratio for v in m),
                max_reach_m=max(v.reach_m for v in m),
            )
        rows.append(row)
    base = rows[0] if rows else None
    nan = float("nan")
    print("| model | ellipsoids | query_robot configs/s (per CPU-s) | collides_robot configs/s (per CPU-s) | cost vs first (wall / CPU) | arm MPC steps/s (per CPU-s) | min coverage | max volume ratio | max reach (m) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        rel = base["collides_robot_configs_per_s"] / r["collides_robot_configs_per_s"]
        r["cost_vs_first"] = rel
        r["cost_vs_first_cpu"] = rel_cpu = base["collides_robot_configs_per_cpu_s"] / r["collides_robot_configs_per_cpu_s"]
        print(f"| {r['model']} | {r['n_ellipsoids']} | {r['query_robot_configs_per_s']:,.0f} ({r['query_robot_configs_per_cpu_s']:,.0f}) | "
              f"{r['collides_robot_configs_per_s']:,.0f} ({r['collides_robot_configs_per_cpu_s']:,.0f}) | {rel:.2f}x / {rel_cpu:.2f}x | "
              f"{r.get('mpc_steps_per_s', nan):.2f} ({r.get('mpc_steps_per_cpu_s', nan):.2f}) | "
              f"{r.get('min_coverage_surface', nan):.3f} | {r.get('max_volume_ratio', nan):.2f} | {r.get('max_reach_m', nan):.4f} |")  # fmt: skip
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    doc = {"rows": rows, "machine": {"platform": platform.platform(), "cpus": os.cpu_count(), "load_average": list(os.getloadavg())},
           "note": "*_per_s: wall-clock; *_per_cpu_s: per CPU-second of the process (every thread); shared machine unless stated"}
    tmp = out.with_suffix(".tmp")
    tmp.write_text(json.dumps(doc, indent=1))
    os.replace(tmp, out)
    return 0


def mppi_rate(robot, n_steps: int, n_samples: int = 256, horizon: int = 32, n_splats: int = 200_000) -> dict:
    """The arm's MPC rate with ``robot``: ``run_arm`` at K x T with the collision cost on every step
    (``arm_throughput``'s setting), warm-up run first; wall-clock and CPU time (every thread) read
    at the start of each step, over ``n_steps`` steps."""
    from dataclasses import replace

    from splatplan.tasks._common import load_task_scene, replace_mppi
    from splatplan.robots.ik import down_quat
    from splatplan.tasks.arm import ArmConfig, run_arm

    ts = load_task_scene("tabletop", device="cpu", n_splats=n_splats)
    cfg = replace(replace_mppi(ArmConfig(), n_samples=n_samples, horizon=horizon), collision_stride=1, max_steps=1, stop_tol=0.0)
    goal = ([0.64, 0.0, 0.0], down_quat())
    run_arm(robot, ts, *goal, config=cfg, check_goal=False, device="cpu")  # warm-up (kernels, grids)
    stamps = []
    run_arm(robot, ts, *goal, config=replace(cfg, max_steps=n_steps + 1), check_goal=False, device="cpu",
            progress=lambda step, err: stamps.append((time.perf_counter(), time.process_time())))  # fmt: skip
    (w0, c0), (w1, c1) = stamps[0], stamps[n_steps]
    return {"mpc_samples": n_samples, "mpc_horizon": horizon, "mpc_n_splats": len(ts.splats), "mpc_steps": n_steps,
            "mpc_steps_per_s": n_steps / (w1 - w0), "mpc_steps_per_cpu_s": n_steps / max(c1 - c0, 1e-9)}  # fmt: skip


if __name__ == "__main__":
    raise SystemExit(main())
