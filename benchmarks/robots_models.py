"""What a Panda collision model costs and how well it fits: coarse (one ellipsoid per link) vs tight vs cover.

Per model: the ellipsoid count; the fit measured per link (``robots.fit_measure``: worst surface
coverage, largest union volume ratio, largest reach beyond the mesh); and the metric's cost per
configuration on the built-in tabletop scene, as configurations/s of ``checker.query_robot`` (all
five outputs) and ``checker.collides_robot`` (the bool), q uniform in the joint limits, the batch
a numpy array (so the timing includes the host transfer). Warm-up first, then the median of timed
runs. configs/s is wall-clock: under load (shared machine) the ratio between the models is the
number to read; the MPPI rate of the arm studies scales with the same per-configuration cost.

    python benchmarks/robots_models.py [--models coarse,tight,cover] [--batch 4096] [--repeats 5]
                                       [--samples 5000] [--out benchmarks/results/robots_models.json]
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
            times = []
            for _ in range(args.repeats):
                t = time.perf_counter()
                f(robot, q)
                times.append(time.perf_counter() - t)
            row[f"{fn}_configs_per_s"] = args.batch / float(np.median(times))
        if args.samples:
            m = [v for v in measure_robot(robot, n_samples=args.samples, n_surface=500).values() if v is not None]
            row.update(
                min_coverage_surface=min(v.coverage_surface for v in m),
                max_volume_ratio=max(v.volume_ratio for v in m),
                max_reach_m=max(v.reach_m for v in m),
            )
        rows.append(row)
    base = rows[0] if rows else None
    print("| model | ellipsoids | query_robot configs/s | collides_robot configs/s | cost vs first | min coverage | max volume ratio | max reach (m) |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        rel = base["collides_robot_configs_per_s"] / r["collides_robot_configs_per_s"]
        r["cost_vs_first"] = rel
        print(f"| {r['model']} | {r['n_ellipsoids']} | {r['query_robot_configs_per_s']:,.0f} | {r['collides_robot_configs_per_s']:,.0f} | {rel:.2f}x"
              f" | {r.get('min_coverage_surface', float('nan')):.3f} | {r.get('max_volume_ratio', float('nan')):.2f} | {r.get('max_reach_m', float('nan')):.4f} |")  # fmt: skip
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    doc = {"rows": rows, "machine": {"platform": platform.platform(), "cpus": os.cpu_count()}, "note": "wall-clock; shared machine unless stated"}
    tmp = out.with_suffix(".tmp")
    tmp.write_text(json.dumps(doc, indent=1))
    os.replace(tmp, out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
