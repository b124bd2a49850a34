"""`splatplan eval mbm` (serial, the library's run_mbm) with the process CPU time of each planning call
recorded in its row (``cpu_s``: both checker threads; steadier than wall time on a shared machine).

    python benchmarks/mbm_cpu.py OUT [--families table_pick,box,bookshelf_small] [--n-per-family 10] [--margin-m M]

Writes OUT/mbm.json, OUT/mbm.md (as `eval mbm`) and OUT/cpu_summary.json (solved, free endpoints,
problems started (both endpoints free or escaped), median / p95 wall and CPU time of the solved plans, worst exact clearance, the 1-minute load average
before and after, one short row per problem); prints the summary. Runs whatever ``splatplan`` is
importable, so the same script times an older checkout (``PYTHONPATH=OLD/src``) for a before/after.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--families", default="table_pick,box,bookshelf_small")
    ap.add_argument("--n-per-family", type=int, default=10)
    ap.add_argument("--margin-m", type=float, default=None, help="planning margin (m); default: derived per scene")
    args = ap.parse_args(argv)
    import splatplan.eval.mbm as mbm

    cpu: list[float] = []
    orig_plan, orig_solve = mbm._plan, mbm.solve_problem

    def timed_plan(*a, **k):
        c = time.process_time()
        r = orig_plan(*a, **k)
        cpu.append(time.process_time() - c)
        return r

    def timed_solve(task, ctx):
        cpu.clear()
        row = orig_solve(task, ctx)
        row["cpu_s"] = cpu[-1] if cpu else None
        return row

    mbm._plan, mbm.solve_problem = timed_plan, timed_solve
    os.makedirs(args.out, exist_ok=True)
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    cfg = mbm.MBMConfig(families=tuple(args.families.split(",")), n_per_family=args.n_per_family, margin_m=args.margin_m)
    rows = mbm.run_mbm(cfg, args.out, progress=False).rows
    sol = [r for r in rows if r["solved"]]
    t = np.array([r["time_s"] for r in sol])
    c = np.array([r["cpu_s"] for r in sol])

    def pct(v, q):
        return float(np.percentile(v, q)) if len(v) else None

    summ = {
        "splatplan": os.path.dirname(mbm.__file__), "margin_m": args.margin_m, "solved": len(sol),
        "both_free": sum(bool(r["start_free"] and r["goal_free"]) for r in rows),
        "started": sum(bool(r.get("started", r["start_free"] and r["goal_free"])) for r in rows),
        "free_endpoints": sum(int(r["start_free"]) + int(r["goal_free"]) for r in rows), "endpoints": 2 * len(rows),
        "median_wall_s": pct(t, 50), "p95_wall_s": pct(t, 95), "median_cpu_s": pct(c, 50), "p95_cpu_s": pct(c, 95),
        "worst_clearance_m": min(r["min_exact_clearance_m"] for r in sol) if sol else None,
        "negative_clearance_paths": sum(r["min_exact_clearance_m"] < 0 for r in sol),
        "load_avg_1min": [load0, os.getloadavg()[0]], "total_s": time.perf_counter() - t0,
        "rows": [{k: r.get(k) for k in ("family", "index", "solved", "time_s", "cpu_s", "n_nodes", "path_length", "min_exact_clearance_m",
                                        "start_free", "goal_free", "started", "start_escape", "goal_escape", "timed_out")} for r in rows],
    }  # fmt: skip
    with open(os.path.join(args.out, "cpu_summary.json"), "w") as f:
        json.dump(summ, f, indent=1)
    print(json.dumps({k: v for k, v in summ.items() if k != "rows"}))
    return summ


if __name__ == "__main__":
    main(sys.argv[1:])
