"""Planner benchmarks on the built-in Stonehenge scene (issue targets, this 2-core CPU).

1. RRT from the scene centre to random free goals on the border, in the plane z = 0.06, sphere
   r = 0.015, n_sigma = 1: median time after warm-up, success rate over ``--goals`` goals; every
   returned path is re-checked: ``n_colliding == 0`` on every segment sampled at <= r/2 (endpoints
   included) and positive clearance to the exact geometry (SDF - r > 0, sampled every 0.002).
2. MPPI for the planar base (K = 256, T = 30, one body ellipsoid, 2 iterations per MPC step):
   MPC steps per second while driving towards a goal through the ring.

    python benchmarks/planners.py [--goals 50] [--out benchmarks/results/planners.json]

Writes JSON and a markdown table (planners.md) next to it.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

RADIUS = 0.015


def border_goals(checker, n: int, z: float, rng: np.random.Generator, r_border: float = 0.47) -> np.ndarray:
    """n collision-free goals on a circle of radius r_border (the scene border), plane z."""
    goals = []
    while len(goals) < n:
        ang = rng.uniform(0, 2 * np.pi, 4 * n)
        cand = np.stack([r_border * np.cos(ang), r_border * np.sin(ang), np.full_like(ang, z)], 1)
        free = ~checker.collides(cand, None, RADIUS)
        goals.extend(cand[free].tolist())
    return np.asarray(goals[:n])


def bench_rrt(scene, gt, n_goals: int, seed: int = 0) -> dict:
    from splatplan.metric import CollisionChecker
    from splatplan.planners import RRTConfig, plan
    from splatplan.planners import edge_points
    from splatplan.planners.metrics import clearance
    from splatplan.scenes.stonehenge import PLANE_Z

    checker = CollisionChecker(scene, n_sigma=1.0)
    rng = np.random.default_rng(seed)
    goals = border_goals(checker, n_goals, PLANE_Z, rng)
    start = np.array([0.0, 0.0, PLANE_Z])
    cfg = RRTConfig(box_lo=(-0.5, -0.5, PLANE_Z), box_hi=(0.5, 0.5, PLANE_Z), time_budget_s=10.0)
    plan(checker, start, goals[0], radius=RADIUS, refine=False, seed=seed, rrt_config=cfg)  # warm-up
    times, ok, n_col, clear, lengths = [], 0, [], [], []
    for i, g in enumerate(goals):
        res = plan(checker, start, g, radius=RADIUS, refine=False, seed=seed + i, rrt_config=cfg)
        times.append(res.time_s)
        if not res.success:
            continue
        ok += 1
        lengths.append(res.length)
        # every segment sampled at <= r/2, its endpoints included (as the planner checks edges)
        dense = edge_points(res.path[:-1], res.path[1:], RADIUS / 2, include_start=True).reshape(-1, 3)
        n_col.append(int(checker.query(dense, None, RADIUS).n_colliding.max()))
        clear.append(clearance(res.path, gt.sdf, RADIUS, spacing=RADIUS / 2))
    return {
        "n_goals": n_goals,
        "success_rate": ok / n_goals,
        "time_median_s": float(np.median(times)),
        "time_p90_s": float(np.quantile(times, 0.9)),
        "length_mean": float(np.mean(lengths)) if lengths else float("nan"),
        "paths_with_colliding_splats": int(np.sum(np.asarray(n_col) > 0)),
        "min_clearance_exact": float(np.min(clear)) if clear else float("nan"),
        "paths_with_nonpositive_clearance": int(np.sum(np.asarray(clear) <= 0)),
    }


def bench_mppi(scene, n_steps: int = 40, seed: int = 0) -> dict:
    from splatplan.metric import CollisionChecker
    from splatplan.planners import MPPI, MPPIConfig, PlanarBase
    from splatplan.scenes.stonehenge import PLANE_Z

    checker = CollisionChecker(scene, n_sigma=1.0)
    dyn = PlanarBase(height=PLANE_Z, offsets=np.zeros((1, 3)), semi_axes=np.array([[RADIUS, RADIUS, RADIUS]]))
    goal = np.array([0.45, 0.1])
    cfg = MPPIConfig(n_samples=256, horizon=30, n_knots=6, dt=0.1, n_iters=2, noise_sigma=(0.1, 0.1, 0.5),
                     u_min=(-0.2, -0.2, -1.0), u_max=(0.2, 0.2, 1.0), seed=seed)  # fmt: skip

    def task(states):  # (K, T, 3) -> (K,): distance of the base to the goal, summed over time
        return np.linalg.norm(states[..., :2] - goal, axis=-1).sum(axis=1)

    mppi = MPPI(dyn, checker, cfg, task_cost=task)
    x = np.array([0.0, 0.0, 0.0])
    mppi.step(x)  # warm-up
    t0 = time.perf_counter()
    hits = 0
    for _ in range(n_steps):
        u, info = mppi.step(x)
        x = dyn.rollout(x, u[None, None, :], cfg.dt)[0, 0]
        c, q, a = dyn.link_poses(x[None])
        hits += int(checker.query(c, q, a).in_collision.any())
    dt = time.perf_counter() - t0
    return {
        "K": cfg.n_samples, "T": cfg.horizon, "iters_per_step": cfg.n_iters, "steps": n_steps,
        "steps_per_s": n_steps / dt, "final_distance_to_goal": float(np.linalg.norm(x[:2] - goal)),
        "steps_in_collision": hits,
    }  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--goals", type=int, default=50)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "planners.json"))
    args = ap.parse_args(argv)

    from splatplan.scenes.filters import filter_floaters
    from splatplan.scenes.stonehenge import build_stonehenge

    raw, gt = build_stonehenge(level=1, seed=0)
    scene, _ = filter_floaters(raw)
    rrt = bench_rrt(scene, gt, args.goals)
    mppi = bench_mppi(scene)
    result = {"rrt": rrt, "mppi": mppi}
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    md = "\n".join([
        "| benchmark | measured | target |",
        "|---|---|---|",
        f"| RRT centre -> border, median time after warm-up | {rrt['time_median_s']:.3f} s (p90 {rrt['time_p90_s']:.3f} s) | <= 0.5 s |",
        f"| RRT success over {rrt['n_goals']} random free border goals | {100 * rrt['success_rate']:.0f}% | >= 95% |",
        f"| paths with a colliding splat at resolution r/2 | {rrt['paths_with_colliding_splats']} | 0 |",
        f"| smallest clearance to the exact geometry (SDF - r) | {rrt['min_clearance_exact']:.4f} | > 0 |",
        f"| MPPI planar base, K=256, T=30, 2 iters/step | {mppi['steps_per_s']:.1f} MPC steps/s | >= 20 |",
        f"| MPPI: steps in collision / final distance to goal | {mppi['steps_in_collision']} / {mppi['final_distance_to_goal']:.3f} | 0 / - |",
    ])  # fmt: skip
    (out.parent / "planners.md").write_text(md + "\n")
    print(md)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
