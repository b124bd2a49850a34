"""Endpoint escapes on MotionBenchMaker (MBM): how often a blocked endpoint is left, seed by seed.

    python benchmarks/mbm_escapes.py [--families table_pick,box,bookshelf_small] [--n-per-family 10]
        [--seeds 32] [--out benchmarks/results/mbm/escapes]

For every endpoint of the first N problems of each family that the robot grown by the derived margin
does not clear (``eval mbm``'s defaults: splats per surface area, n_sigma 0, the shipped escape model),
:func:`~splatplan.planners.escape_endpoint` runs once per seed, in two settings on the same endpoints:

* **first round only** (``retry=0``): ``n_directions`` straight segments, towards the other endpoint
  and random (seeded);
* **with the second round** (the default): where the first finds no way out, ``retry`` x as many,
  led by the push directions (the blocking ellipsoids moved away from their splats).

An escape that fails leaves the problem unstarted. Per endpoint and overall: the failures, the share
of escapes that needed the second round, the median and p95 wall time of an escape. Writes OUT.json
(every endpoint and setting, the date and machine) and OUT.md (the table), prints the table.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SETTINGS = (("first round only", 0), ("with the second round", None))


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--families", default="table_pick,box,bookshelf_small")
    ap.add_argument("--n-per-family", type=int, default=10)
    ap.add_argument("--seeds", type=int, default=32)
    ap.add_argument("--out", default=str(REPO / "benchmarks" / "results" / "mbm" / "escapes"))
    args = ap.parse_args(argv)
    import splatplan.eval.mbm as mbm
    from splatplan.errors import PlanningError
    from splatplan.planners.escape import RETRY_FACTOR, escape_endpoint
    from splatplan.planners.robot_links import LinkGeometry
    from splatplan.scenes.moveit import load_moveit_request

    cfg = mbm.MBMConfig(families=tuple(args.families.split(",")), n_per_family=args.n_per_family)
    ctx = mbm.make_context(cfg)
    robot = ctx.robot
    rows: list[dict[str, Any]] = []
    for task in mbm.list_tasks(cfg):
        prep = ctx.prepared(task)
        checker, margin = prep.checker, prep.splat_margin
        q0, q1 = load_moveit_request(task.request, robot)
        full = LinkGeometry(robot.inflated(margin.margin))
        for name, q, other in (("start", q0, q1), ("goal", q1, q0)):
            if not full.collides(checker, q[None])[0]:
                continue
            row: dict[str, Any] = {"family": task.family, "index": task.index, "endpoint": name}
            for label, retry in SETTINGS:
                times, fails, second, finest = [], 0, 0, 0
                for seed in range(args.seeds):
                    t = time.perf_counter()
                    try:
                        e = escape_endpoint(checker, robot, q, margin, toward=other, seed=seed, escape_robot=ctx.escape_robot, geometry=full,
                                            retry=RETRY_FACTOR if retry is None else retry)  # fmt: skip
                        second += int(e.info["rounds"] == 2)
                    except PlanningError as ex:
                        fails += 1
                        finest += int("finest" in str(ex))
                    times.append(time.perf_counter() - t)
                row[label] = {"failures": fails, "seeds": args.seeds, "second_round": second, "refused_as_too_close": finest,
                              "median_ms": 1e3 * float(np.median(times)), "p95_ms": 1e3 * float(np.percentile(times, 95))}  # fmt: skip
            rows.append(row)
            print(f"{task.family} {task.index} {name}: " + ", ".join(f"{lab} {row[lab]['failures']}/{args.seeds} failed" for lab, _ in SETTINGS), flush=True)
    summary: dict[str, dict[str, Any]] = {}
    for label, _ in SETTINGS:
        tot = sum(r[label]["seeds"] for r in rows)
        summary[label] = {"escapes": tot, "failures": sum(r[label]["failures"] for r in rows), "second_round": sum(r[label]["second_round"] for r in rows),
                          "median_ms": float(np.median([r[label]["median_ms"] for r in rows])) if rows else float("nan")}  # fmt: skip
    result = {"date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
              "machine": f"{platform.machine()}, {len(os.sched_getaffinity(0))} cores, {platform.python_version()}", "families": cfg.families, "n_per_family": cfg.n_per_family, "seeds": args.seeds,
              "retry_factor": RETRY_FACTOR, "rows": rows, "summary": summary}  # fmt: skip
    lines = [f"MBM endpoint escapes ({result['date']}, {platform.machine()}; first {cfg.n_per_family} problems per family, "
             f"n_sigma {cfg.n_sigma:g}, {args.seeds} seeds per blocked endpoint)", "",
             "| endpoint | first round only: failed | median | with the second round: failed | needed it | median |", "|---|---|---|---|---|---|"]  # fmt: skip
    a, b = (lab for lab, _ in SETTINGS)
    for r in rows:
        lines.append(f"| {r['family']} {r['index']} {r['endpoint']} | {r[a]['failures']}/{r[a]['seeds']} | {r[a]['median_ms']:.1f} ms | "
                     f"{r[b]['failures']}/{r[b]['seeds']} | {r[b]['second_round']} | {r[b]['median_ms']:.1f} ms |")  # fmt: skip
    sa, sb = summary[a], summary[b]
    lines.append(f"| all | {sa['failures']}/{sa['escapes']} | {sa['median_ms']:.1f} ms | {sb['failures']}/{sb['escapes']} | {sb['second_round']} | {sb['median_ms']:.1f} ms |")
    lines += ["", "(failed: the escape found no way out, the problem does not start; needed it: escapes the first round could not make)"]
    table = "\n".join(lines)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps(result, indent=1))
    out.with_suffix(".md").write_text(table + "\n")
    print(table)
    return result


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
