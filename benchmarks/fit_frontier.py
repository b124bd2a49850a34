"""How tight a certified ellipsoid model of a link can get per ellipsoid count: the fitter's frontier.

Issue #19 asks, per Panda link, for a union of ellipsoids that contains the collision mesh, reaches
at most 1.5 cm beyond it and totals at most 1.3x its volume, within ~40 ellipsoids for the arm.
This script measures what the optimising fitter (``robots.fit_opt``, the one the shipped models
come from) reaches at each fixed count k, link by link: ``fit_link_opt(polys, OptConfig(), k=k)``
(certified to contain the mesh), then ``robots.fit_measure.measure_link`` (Monte Carlo volume ratio
with its standard error, and the largest reach found by exact distances). k = 1 is also given as
the single minimum-volume enclosing ellipsoid (MVEE) of the link, the classic one-per-link model.

    python benchmarks/fit_frontier.py [--urdf ../shared/data/mbm/panda/panda.urdf] [--ks 1,2,3,4,6,8]
                                      [--links a,b] [--jobs 2] [--out benchmarks/results/fit_frontier]

Writes OUT/fit_frontier.json and OUT/fit_frontier.md (one row per link, a column per k: volume
ratio and reach; and the robot's total union volume / total mesh volume per k); prints the table.
Each (link, k) fit runs in its own process (``--jobs`` at a time); ``cpu_s`` is its process CPU time.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
DEFAULT_URDF = HERE.parent.parent / "shared" / "data" / "mbm" / "panda" / "panda.urdf"


def fit_one(urdf: str, link: str, k: int, samples: int) -> dict:
    """One (link, k): fit, certify, measure. k = 1 is the link's single MVEE."""
    from splatplan.robots.fit import _polytope, mvee
    from splatplan.robots.fit_cover import solids_of
    from splatplan.robots.fit_measure import measure_link
    from splatplan.robots.fit_opt import OptConfig, fit_link_opt
    from splatplan.robots.urdf import read_urdf

    t = time.process_time()
    polys = [_polytope(g, link) for g in read_urdf(urdf).collisions[link] if g.kind in ("mesh", "box")]
    if k == 1:
        pts = np.concatenate([np.asarray(s.vertices) for s in solids_of(polys)])
        c, r, s = mvee(pts)
        d = np.sqrt(np.max(np.sum((((pts - c) @ r) / s) ** 2, axis=1)))  # grow until every vertex is in
        ells = [(c, r, s * max(d, 1.0) * (1.0 + 1e-9))]
    else:
        ells, _ = fit_link_opt(polys, OptConfig(), k=k)
    m = measure_link(ells, polys, n_samples=samples, n_surface=2000, seed=3)
    return {"link": link, "k": k, "n": len(ells), "volume_ratio": m.volume_ratio, "volume_ratio_se": m.volume_ratio_se,
            "reach_m": m.reach_m, "coverage_surface": m.coverage_surface, "coverage_interior": m.coverage_interior,
            "mesh_volume_m3": m.solid_volume, "cpu_s": time.process_time() - t}  # fmt: skip


def table(rows: list[dict], ks: list[int], links: list[str], reach: float, ratio: float) -> str:
    by = {(r["link"], r["k"]): r for r in rows}
    head = "| link | mesh (cm^3) | " + " | ".join(f"k = {k}" + (" (MVEE)" if k == 1 else "") for k in ks) + " |"
    lines = [f"Volume ratio (union / mesh, Monte Carlo) and reach beyond the mesh (cm) per ellipsoid count k; "
             f"**bold**: both targets met (<= {ratio:g}x, <= {100 * reach:g} cm).", "", head, "|---|---|" + "---|" * len(ks)]  # fmt: skip
    for link in links:
        cells = []
        for k in ks:
            r = by.get((link, k))
            if r is None:
                cells.append("-")
                continue
            txt = f"{r['volume_ratio']:.2f}x / {100 * r['reach_m']:.1f}"
            cells.append(f"**{txt}**" if r["volume_ratio"] <= ratio and r["reach_m"] <= reach else txt)
        vol = next((r["mesh_volume_m3"] for r in rows if r["link"] == link), float("nan"))
        lines.append(f"| {link} | {1e6 * vol:.0f} | " + " | ".join(cells) + " |")
    tot = []
    for k in ks:
        rs = [by[(li, k)] for li in links if (li, k) in by]
        v = sum(r["mesh_volume_m3"] for r in rs)
        tot.append(f"{sum(r['volume_ratio'] * r['mesh_volume_m3'] for r in rs) / v:.2f}x, {k * len(rs)} ellipsoids" if rs else "-")
    lines.append("| **robot total** | | " + " | ".join(tot) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--urdf", default=str(DEFAULT_URDF))
    ap.add_argument("--ks", default="1,2,3,4,6,8")
    ap.add_argument("--links", default=None, help="comma-separated (default: every link with mesh or box collision geometry)")
    ap.add_argument("--samples", type=int, default=20000, help="Monte Carlo samples per link for the volume ratio")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default=str(HERE / "results" / "fit_frontier"))
    args = ap.parse_args(argv)
    from splatplan.robots.fit_opt import OptConfig
    from splatplan.robots.urdf import read_urdf

    model = read_urdf(args.urdf)
    links = args.links.split(",") if args.links else [li for li in model.kin.link_names
                                                      if any(g.kind in ("mesh", "box") for g in model.collisions.get(li, []))]  # fmt: skip
    ks = [int(k) for k in args.ks.split(",")]
    jobs = [(args.urdf, li, k, args.samples) for li in links for k in ks]
    t0 = time.time()
    rows = []
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as ex:
        for r in ex.map(fit_one, *zip(*jobs)):
            rows.append(r)
            print(f"{r['link']:<20} k={r['k']}: {r['volume_ratio']:.3f}x +- {r['volume_ratio_se']:.3f}, reach {100 * r['reach_m']:.2f} cm, "
                  f"{r['cpu_s']:.0f} s CPU", file=sys.stderr, flush=True)  # fmt: skip
    cfg = OptConfig()
    md = table(rows, ks, links, cfg.reach, cfg.volume_ratio)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    doc = {"urdf": os.path.relpath(args.urdf, HERE.parent), "ks": ks, "links": links, "opt_config": {"reach": cfg.reach, "volume_ratio": cfg.volume_ratio,
           "steps": cfg.steps, "restarts": cfg.restarts}, "rows": rows, "wall_s": time.time() - t0, "cpu_count": os.cpu_count()}  # fmt: skip
    (out / "fit_frontier.json").write_text(json.dumps(doc, indent=2))
    (out / "fit_frontier.md").write_text(f"Fit frontier of `{doc['urdf']}` (`python benchmarks/fit_frontier.py`)\n\n{md}\n")
    print(md)
    print(f"\nwrote {out / 'fit_frontier.json'}, {out / 'fit_frontier.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
