"""The "sky shell" case: quantile tiers against geometric size-class tiers.

A real phone capture (issue #12) holds a shell of ~10k opaque splats of std ~7 m on a 240 m sphere
around a 0.5 m scene. With tiers split at quantiles of the splat size, the tier above the 0.9
quantile holds the shell *and* thousands of ordinary large splats, and its radius (set by the
shell, ~15 m) makes every query scan those ordinary ones. Size classes give the shell its own
tier, whose grid cells near the scene are empty.

Scene: the built-in Stonehenge (level 1, floaters filtered, ~200k splats, 1 unit across) plus
10,242 opaque splats of std (7.39, 7.39, 2.0) on a sphere of radius 240 around it (Fibonacci
lattice, random orientations). Queries: half uniform in the Stonehenge bounds, half within 0.05
of a splat mean; sphere r = 0.015, n_sigma = 1. Also the same queries on Stonehenge alone.
checks/s = queries per second of wall time (median of timed runs after a warm-up).

``real_rows`` (when ``--real DIR`` exists, default ``../shared/data/real``): the same comparison on
real captures (floaters filtered), sphere radius 1% of the smallest side of the 1-99 percentile
box, half the queries uniform in that box and half near splats.

    python benchmarks/metric_shell.py [--device cpu|cuda] [--repeats 5] [--batch 32768] [--real DIR]
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


def sky_shell(n: int = 10242, radius: float = 240.0, std: tuple[float, float, float] = (7.39, 7.39, 2.0), seed: int = 0):
    """(means (n, 3), quats (n, 4) wxyz, scales (n, 3)) of a Fibonacci-lattice shell around the origin."""
    rng = np.random.default_rng(seed)
    i = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * i / n)
    theta = np.pi * (1 + 5**0.5) * i
    means = radius * np.stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)], axis=1)
    q = rng.normal(size=(n, 4))
    return means, q / np.linalg.norm(q, axis=1, keepdims=True), np.tile(np.asarray(std, float), (n, 1))


def with_shell(scene, **kw):
    """``scene`` plus an opaque sky shell (see :func:`sky_shell`)."""
    from splatplan.scenes.splats import Splats

    m, q, s = sky_shell(**kw)
    n = len(m)
    return Splats(
        means=np.concatenate([scene.means, m]),
        quats=np.concatenate([scene.quats, q]),
        scales=np.concatenate([scene.scales, s]),
        opacities=np.concatenate([scene.opacities, np.ones(n)]),
        colors=np.concatenate([scene.colors, np.full((n, 3), 0.6)]),
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--batch", type=int, default=32768)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "metric_shell.json"))
    ap.add_argument("--real", default=str(Path(__file__).resolve().parents[2] / "shared" / "data" / "real"))
    args = ap.parse_args(argv)

    from splatplan._warp import cpu_threads, wp
    from splatplan.eval._common import make_queries
    from splatplan.metric import CollisionChecker
    from splatplan.metric.wp_metric import TierConfig
    from splatplan.scenes.filters import filter_floaters
    from splatplan.scenes.builtin.stonehenge import build_stonehenge

    base, _ = build_stonehenge(level=1, seed=0)
    base, _ = filter_floaters(base)
    lo, hi = base.bounds()
    centers = make_queries(base.means, lo, hi, args.batch, np.random.default_rng(0))
    radius = 0.015
    load0 = os.getloadavg()
    rows = []
    for scene_name, scene in (("stonehenge", base), ("stonehenge+shell", with_shell(base))):
        for tiers_name, tiers in (("quantile (old)", TierConfig(mode="quantile")), ("size classes", TierConfig())):
            checker = CollisionChecker(scene, n_sigma=1.0, device=args.device, tiers=tiers)
            impl = checker._impl
            res = checker.query(centers, None, radius)  # warm-up: compile, build grids
            hit = checker.collides(centers, None, radius)
            wp().synchronize()
            row = {
                "scene": scene_name, "tiers": tiers_name, "n_splats": len(scene), "batch": args.batch,
                "class_counts": list(map(int, impl.class_count)), "class_sigma": [round(s, 5) for s in impl.class_sigma],
                "query_tier_counts": impl.gridset(1.0, checker.config.s2_cap, radius, radius).counts,
                "collides_tier_counts": impl.gridset(1.0, 1.0, radius, radius).counts,
                "n_colliding_total": int(res.n_colliding.sum()), "n_in_collision": int(hit.sum()),
            }  # fmt: skip
            for fn in ("collides", "query"):
                row[f"{fn}_checks_per_s"] = args.batch / _time(lambda fn=fn: getattr(checker, fn)(centers, None, radius), args.repeats)
            rows.append(row)
            checker.close()
    real_rows = _real_rows(Path(args.real), args.device, args.batch, args.repeats)
    same = all(r["n_colliding_total"] == rows[2 * (i // 2)]["n_colliding_total"] for i, r in enumerate(rows))
    result = {
        "device": checker.device,
        "cpu": platform.processor() or platform.machine(),
        "threads": cpu_threads(),
        "radius": radius,
        "n_sigma": 1.0,
        "load_avg_1min_before_after": [round(load0[0], 2), round(os.getloadavg()[0], 2)],
        "exact_counts_agree_between_tierings": bool(same),
        "rows": rows,
        "real_rows": real_rows,
    }
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")

    print(f"Sky shell on {result['device']} ({result['threads']} threads), sphere r={radius}, n_sigma=1, batch {args.batch:,}")
    print(f"(1-min load average before/after: {result['load_avg_1min_before_after']}; counts agree between tierings: {same})")
    print("| scene | tiers | splats | tiers (collides / query) | collides checks/s | full query checks/s |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['scene']} | {r['tiers']} | {r['n_splats']:,} | {len(r['collides_tier_counts'])} / {len(r['query_tier_counts'])} | "
            f"{r['collides_checks_per_s']:,.0f} | {r['query_checks_per_s']:,.0f} |"
        )
    if real_rows:
        print()
        print("Real captures (floaters filtered), sphere r = 1% of the scene's smallest side")
        print("| scene | splats | r | tiers | collides checks/s | full query checks/s |")
        print("|---|---|---|---|---|---|")
        for r in real_rows:
            print(f"| {r['scene']} | {r['n_splats']:,} | {r['radius']:.3g} | {r['tiers']} | {r['collides_checks_per_s']:,.0f} | {r['query_checks_per_s']:,.0f} |")
    print(f"wrote {out}")
    return 0


def _time(fn, repeats: int) -> float:
    from splatplan._warp import wp

    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        wp().synchronize()
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def _real_rows(folder: Path, device: str, batch: int, repeats: int) -> list[dict]:
    """Quantile vs size-class tiers on every scene file in ``folder`` (none when it is absent)."""
    if not folder.is_dir():
        return []
    import splatplan
    from splatplan.metric import CollisionChecker
    from splatplan.metric.wp_metric import TierConfig
    from splatplan.scenes.filters import filter_floaters

    rows = []
    for f in sorted(folder.iterdir()):
        if f.suffix not in (".ply", ".spz", ".splat"):
            continue
        scene, _ = filter_floaters(splatplan.load_scene(f))
        lo, hi = np.percentile(scene.means, [1, 99], axis=0)
        r = float(np.min(hi - lo)) * 0.01
        rng = np.random.default_rng(0)
        h = batch // 2
        c = np.concatenate([rng.uniform(lo, hi, (h, 3)), scene.means[rng.integers(0, len(scene), batch - h)] + rng.normal(0, r, (batch - h, 3))])
        for name, tiers in (("quantile (old)", TierConfig(mode="quantile")), ("size classes", TierConfig())):
            ch = CollisionChecker(scene, n_sigma=1.0, device=device, tiers=tiers)
            ch.query(c, None, r)
            ch.collides(c, None, r)
            row = {"scene": f.name, "n_splats": len(scene), "radius": r, "tiers": name}
            for fn in ("collides", "query"):
                row[f"{fn}_checks_per_s"] = batch / _time(lambda fn=fn: getattr(ch, fn)(c, None, r), repeats)
            rows.append(row)
            ch.close()
    return rows


if __name__ == "__main__":
    sys.exit(main())
