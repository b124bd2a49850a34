"""Arm planning speed on MotionBenchMaker problems: RRT-Connect's planning time, the configurations
it checks and where the time goes.

Each problem's scene is prepared as ``splatplan eval mbm`` prepares it (:func:`splatplan.eval.mbm._prepare`:
100k splats with the real-capture look, floaters filtered, the checker at n_sigma 0), without the
covering-radius diagnostic; problems whose endpoints are not both free are skipped. Each remaining
problem is planned through :func:`splatplan.planners.plan` (no refinement, ``seed + index`` as in
the benchmark, the given margin, the edge resolution a quarter of the robot's smallest semi-axis).
Every returned path is re-checked with the plain edge check (:meth:`EdgeChecker.path_free`, every
check sample of every edge at the edge resolution): a fast path may never return a path that the
slow check calls in collision.

    python benchmarks/planners_mbm.py [--robot URDF] [--families a,b] [--n-per-family 10] [--margin-m 0]
        [--time-limit 10] [--threads N] [--out benchmarks/results/mbm/rrtconnect_fast_fit.json]

Prints a table (per family and overall: solved / both free, median and p95 planning time (wall),
the median CPU time of the process (all threads; steadier than wall time on a loaded machine),
configurations checked per plan, the time split) and writes JSON with one row per problem. Timings
depend on the machine's load: the JSON records the 1-minute load average before and after.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_MBM = ROOT.parent / "shared" / "data" / "mbm"


def run(args) -> dict:
    from splatplan.eval.mbm import MBMConfig, _prepare, check_inputs, list_tasks
    from splatplan.planners import RRTConfig, plan
    from splatplan.planners.robot_links import LinkGeometry, robot_collides
    from splatplan.planners.rrt import EdgeChecker
    from splatplan.robots import load_robot

    cfg = MBMConfig(problems=args.problems, families=tuple(args.families.split(",")), n_per_family=args.n_per_family, n_splats=args.n_splats,
                    margin_m=args.margin_m, check_margin=False, time_limit=args.time_limit)  # fmt: skip
    robot = load_robot(str(args.robot))
    plan_robot = robot.inflated(args.margin_m) if args.margin_m > 0 else robot
    res = 0.25 * robot.min_semi_axis
    kw = {"batch_size": args.batch_size} if args.batch_size else {}
    kw.update({"edge_stages": args.edge_stages} if "edge_stages" in RRTConfig.__dataclass_fields__ else {})  # (older versions: one call)
    rcfg = RRTConfig(time_limit_s=args.time_limit, edge_resolution=res, **kw)
    rows = []
    for task in check_inputs(list_tasks(cfg), robot):
        t0 = time.perf_counter()
        prep = _prepare(task, cfg, robot)
        t_prep = time.perf_counter() - t0
        q0, q1 = np.asarray(task.q_start), np.asarray(task.q_goal)
        hit = np.asarray(robot_collides(prep.checker, plan_robot, np.stack([q0, q1]))).any(axis=-1)
        row = {"family": task.family, "index": task.index, "both_free": bool(not hit.any()), "prep_s": t_prep}
        if row["both_free"]:
            c0 = time.process_time()
            r = plan(prep.checker, q0, q1, robot=plan_robot, seed=cfg.seed + task.index, refine=False, planner=args.planner, rrt_config=rcfg)
            cpu = time.process_time() - c0  # CPU seconds of this process (all its threads): steadier than wall time under load
            split = {k: float(v) for k, v in r.info.get("time_split", {}).items()}
            n_e = plan_robot.n_ellipsoids
            row.update(solved=bool(r.success), time_s=float(r.time_s), cpu_s=cpu, n_nodes=int(r.n_nodes), n_iters=int(r.n_iters),
                       configs=int(r.info.get("n_queries", 0)) // n_e, configs_shortcut=int(r.info.get("n_queries_shortcut", 0)) // n_e,
                       time_split=split, path_vertices=len(r.path), length=float(r.length))  # fmt: skip
            if r.success:
                edges = EdgeChecker(prep.checker, LinkGeometry(plan_robot), res)
                row["path_free_slow_check"] = bool(edges.path_free(r.path))
        prep.checker.close()
        rows.append(row)
        print(f"{task.family} {task.index}: " + (f"{'solved' if row['solved'] else 'FAILED'} {row['time_s']:.2f} s, {row['configs']} configs "
              f"({row['configs_shortcut']} shortcut), {row['n_nodes']} nodes, slow check free: {row.get('path_free_slow_check')}"
              if row["both_free"] else "endpoint in collision, skipped"), flush=True)  # fmt: skip
    return {"rows": rows}


def summarise(rows: list[dict]) -> dict:
    out = {}
    fams = sorted({r["family"] for r in rows}) + ["overall"]
    for f in fams:
        rs = [r for r in rows if r["both_free"] and (f == "overall" or r["family"] == f)]
        t = np.array([r["time_s"] for r in rs if r["solved"]])
        split = {k: float(np.median([r["time_split"].get(k, 0.0) for r in rs])) for k in ("sampling", "nearest", "collision", "shortcut", "other")} if rs else {}
        out[f] = {
            "both_free": len(rs), "solved": int(sum(r["solved"] for r in rs)),
            "median_s": float(np.median(t)) if len(t) else None, "p95_s": float(np.percentile(t, 95)) if len(t) else None,
            "max_s": float(t.max()) if len(t) else None,
            "median_cpu_s": float(np.median([r["cpu_s"] for r in rs if r["solved"]])) if len(t) else None,
            "median_configs": float(np.median([r["configs"] for r in rs])) if rs else None,
            "median_split_s": split,
            "slow_check_failures": int(sum(1 for r in rs if r.get("path_free_slow_check") is False)),
        }  # fmt: skip
    return out


def fmt(v) -> str:
    return "-" if v is None else f"{v:.3f}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robot", default=str(DEFAULT_MBM / "panda" / "panda.urdf"))
    ap.add_argument("--problems", default=str(DEFAULT_MBM / "problems"))
    ap.add_argument("--families", default="table_pick,box,bookshelf_small")
    ap.add_argument("--n-per-family", type=int, default=10)
    ap.add_argument("--n-splats", type=int, default=100_000)
    ap.add_argument("--margin-m", type=float, default=0.0)
    ap.add_argument("--time-limit", type=float, default=10.0)
    ap.add_argument("--planner", default="rrtconnect")
    ap.add_argument("--batch-size", type=int, default=None, help="RRTConfig.batch_size (default: the config's)")
    ap.add_argument("--edge-stages", type=int, default=4, help="RRTConfig.edge_stages (1 = every check sample in one call)")
    ap.add_argument("--threads", type=int, default=None, help="CPU threads of the checker (SPLATPLAN_CPU_THREADS)")
    ap.add_argument("--note", default="", help="free text stored in the JSON (e.g. 'before', 'after')")
    ap.add_argument("--out", default=None)
    args = ap.parse_args(argv)
    if args.threads is not None:
        os.environ["SPLATPLAN_CPU_THREADS"] = str(args.threads)
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    res = run(args)
    res["summary"] = summarise(res["rows"])
    res.update(config=vars(args), load_avg_1min=[load0, os.getloadavg()[0]], cpu_count=os.cpu_count(), wall_s=time.perf_counter() - t0)
    print(f"\n{'family':<16} {'solved/free':>11} {'median s':>9} {'p95 s':>7} {'cpu s':>6} {'configs':>8}  split (median s: sampling/nearest/collision/shortcut/other)")
    for f, s in res["summary"].items():
        sp = "/".join(f"{s['median_split_s'].get(k, 0):.3f}" for k in ("sampling", "nearest", "collision", "shortcut", "other"))
        print(f"{f:<16} {s['solved']:>5}/{s['both_free']:<5} {fmt(s['median_s']):>9} {fmt(s['p95_s']):>7} {fmt(s['median_cpu_s']):>6} {s['median_configs'] or 0:>8.0f}  {sp}"
              + (f"  SLOW CHECK FAILED {s['slow_check_failures']}" if s["slow_check_failures"] else ""))  # fmt: skip
    print(f"load average (1 min) {res['load_avg_1min'][0]:.2f} -> {res['load_avg_1min'][1]:.2f} on {os.cpu_count()} cores")
    if args.out:
        p = Path(args.out)
        p.parent.mkdir(parents=True, exist_ok=True)
        tmp = p.with_suffix(p.suffix + ".tmp")
        tmp.write_text(json.dumps(res, indent=1))
        tmp.replace(p)
    return 0


if __name__ == "__main__":
    sys.exit(main())
