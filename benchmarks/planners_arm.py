"""Arm planning benchmark: the goal-biased batched RRT vs the batched RRT-Connect, Panda on the
built-in tabletop.

Problems: the arm study's start (:data:`splatplan.eval.arm.START_Q`, gripper in front of the bin's
front wall) to IK goals of random targets behind the wall (:func:`splatplan.eval.arm.pick_targets`;
of the IK solutions, the one with the largest exact clearance that is free against the splats).
Each problem is planned with each planner and a few seeds through
:func:`splatplan.planners.plan` (no refinement, the planner's own 10 s limit). Every returned path
is re-checked against the exact boxes: resampled so that no ellipsoid point moves more than a
quarter of the smallest semi-axis between samples, its smallest exact clearance (negative = the
path cuts the real geometry).

    python benchmarks/planners_arm.py [--problems 6] [--seeds 3] [--n-sigma 0] [--quick] [--out benchmarks/results/planners_arm.json]

Prints a table (per planner: solved, median / p95 time, configurations checked, the time split)
and writes JSON. Timings depend on the machine's load: the JSON records the 1-minute load average.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

PLANNERS = ("rrt", "rrtconnect")


def arm_problems(n: int, n_splats: int, n_sigma: float, seed: int = 0):
    """(checker, ground truth, [(start (7,), goal (7,)), ...]) on the built-in tabletop."""
    from splatplan.eval.arm import START_Q, pick_targets
    from splatplan.metric import CollisionChecker
    from splatplan.planners import robot_collides
    from splatplan.robots import load_robot
    from splatplan.scenes.builtin.tabletop import build_tabletop
    from splatplan.scenes.filters import filter_floaters
    from splatplan.robots.ik import solve_ik

    robot = load_robot("panda")
    splats, gt = build_tabletop(seed, n_splats=n_splats)
    splats, _ = filter_floaters(splats)  # as `splatplan plan` loads a scene (a floater sits in the start's links)
    checker = CollisionChecker(splats, n_sigma=n_sigma)
    start = np.asarray(START_Q, dtype=np.float64)
    if robot_collides(checker, robot, start[None])[0].any():
        raise SystemExit(f"the arm study's start collides with the splats at n_sigma {n_sigma:g} ({n_splats:,} splats): lower --n-sigma")
    out = []
    rng = np.random.default_rng(seed)
    for p, quat in pick_targets(2 * n, seed=seed):
        q, pe, re = solve_ik(robot, p, quat, link="panda_hand_tcp", n_seeds=24, n_iters=60, seed=int(rng.integers(1 << 30)))
        ok = (pe < 3e-3) & (re < np.deg2rad(2.0))
        q = q[ok]
        q = q[~robot_collides(checker, robot, q).any(axis=-1)] if len(q) else q
        if not len(q):
            continue
        c, qq, a = robot.ellipsoids(q)
        best = q[int(np.argmax(gt.ellipsoid_clearance(c, qq, a).min(axis=-1)))]
        out.append((start, best))
        if len(out) == n:
            break
    return robot, checker, gt, out


def exact_clearance(robot, gt, path: np.ndarray) -> float:
    """Smallest exact clearance (m) of the robot's ellipsoids along a path resampled at a quarter
    of the smallest semi-axis of motion (motion bound): the library's one path clearance."""
    from splatplan.planners.clearance import dense_path, path_min_clearance

    return float(path_min_clearance(gt, robot, dense_path(robot, np.asarray(path, dtype=np.float64))))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--problems", type=int, default=6)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--n-sigma", type=float, default=0.0, help="the arm study's start touches the splats of the one-ellipsoid-per-link "
                    "Panda from n_sigma 0.5 on (default 0)")  # fmt: skip
    ap.add_argument("--n-splats", type=int, default=200_000)
    ap.add_argument("--time-limit", type=float, default=10.0)
    ap.add_argument("--quick", action="store_true", help="2 problems, 1 seed, 50k splats")
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent / "results" / "planners_arm.json"))
    a = ap.parse_args(argv)
    if a.quick:
        a.problems, a.seeds, a.n_splats = 2, 1, 50_000
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))
    from splatplan.planners import RRTConfig, plan

    load = float(os.getloadavg()[0])
    robot, checker, gt, probs = arm_problems(a.problems, a.n_splats, a.n_sigma)
    plan(checker, probs[0][0], probs[0][1], robot=robot, refine=False, planner="rrtconnect", rrt_config=RRTConfig(time_limit_s=2.0))  # warm-up
    runs = []
    for pi, (s, g) in enumerate(probs):
        for name in PLANNERS:
            for seed in range(a.seeds):
                res = plan(checker, s, g, robot=robot, refine=False, seed=seed, planner=name, rrt_config=RRTConfig(time_limit_s=a.time_limit))
                runs.append({
                    "problem": pi, "planner": name, "seed": seed, "solved": bool(res.success), "time_s": res.time_s,
                    "n_nodes": res.n_nodes, "configs_checked": res.info["n_queries"] // robot.n_ellipsoids,
                    "path_length": float(res.length) if res.success else None, "time_split": res.info["time_split"],
                    "min_exact_clearance_m": exact_clearance(robot, gt, res.path) if res.success else None,
                })  # fmt: skip
                r = runs[-1]
                print(f"problem {pi} {name:10s} seed {seed}: {'ok ' if r['solved'] else 'FAIL'} {r['time_s']:6.2f} s {r['n_nodes']:6d} nodes", flush=True)
    rows = []
    for name in PLANNERS:
        rs = [r for r in runs if r["planner"] == name]
        t = np.array([r["time_s"] for r in rs if r["solved"]])
        split = {k: float(np.mean([r["time_split"][k] for r in rs])) for k in rs[0]["time_split"]}
        clr = [r["min_exact_clearance_m"] for r in rs if r["solved"]]
        rows.append({
            "planner": name, "solved": sum(r["solved"] for r in rs), "runs": len(rs),
            "median_s": float(np.median(t)) if t.size else None, "p95_s": float(np.percentile(t, 95)) if t.size else None,
            "median_configs": float(np.median([r["configs_checked"] for r in rs])), "mean_time_split_s": split,
            "min_exact_clearance_m": float(min(clr)) if clr else None,
        })  # fmt: skip
    print(f"\nPanda on the built-in tabletop, {a.n_splats:,} splats, n_sigma {a.n_sigma:g}, {len(probs)} problems x {a.seeds} seeds, "
          f"limit {a.time_limit:g} s, load {load:.1f} (timings under this load)")  # fmt: skip
    print(f"{'planner':11s} {'solved':>8s} {'median s':>9s} {'p95 s':>8s} {'configs':>9s} {'min clear m':>12s}  mean time split (s)")
    for r in rows:
        med = "-" if r["median_s"] is None else f"{r['median_s']:.2f}"
        p95 = "-" if r["p95_s"] is None else f"{r['p95_s']:.2f}"
        clr = "-" if r["min_exact_clearance_m"] is None else f"{r['min_exact_clearance_m']:.4f}"
        split = ", ".join(f"{k} {v:.2f}" for k, v in r["mean_time_split_s"].items())
        print(f"{r['planner']:11s} {r['solved']:>3d}/{r['runs']:<4d} {med:>9s} {p95:>8s} {r['median_configs']:>9.0f} {clr:>12s}  {split}")
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    doc = {"n_splats": a.n_splats, "n_sigma": a.n_sigma, "time_limit_s": a.time_limit, "load_1min": load, "rows": rows, "runs": runs}
    tmp = out.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(doc, indent=1) + "\n")
    os.replace(tmp, out)
    print(f"-> {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
