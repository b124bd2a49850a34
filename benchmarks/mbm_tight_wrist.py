"""Experiment: does a tighter wrist and hand model free the MBM endpoints the margin blocks?

The endpoints that are not free at the defaults are blocked by the wrist (panda_link5, panda_link6)
and the hand, whose ellipsoids reach 14-15 mm beyond the mesh (``eval mbm`` rows,
``*_blocked_by``). This refits those links with the optimising fitter at a 4 mm reach target and
10 ellipsoids each (the rest of the shipped tight fit kept), then runs ``eval mbm`` with that model.

    python benchmarks/mbm_tight_wrist.py [--links panda_link4,...] [--reach 0.004] [--k 10]
        [--base MODEL.yaml] [--n-per-family 10] [--out benchmarks/results/mbm/tight_wrist]

Writes OUT/panda_tight_wrist.yaml (the model), OUT/mbm.json and OUT/mbm.md, prints the overall summary.
``--base`` starts from that model instead of the shipped default fit (the shipped escape model,
``src/splatplan/robots/data/mbm_panda_tight_wrist.yaml``, is this script's output for panda_link4-7
and panda_hand at 4 mm / 10 each, then again with ``--base`` it, ``--links panda_link5 --reach 0.002
--k 16``: that link's model reached 6.6 mm beyond its mesh at a bookshelf goal). ``--n-per-family 0``
fits and writes the model only.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--links", default="panda_link4,panda_link5,panda_link6,panda_link7,panda_hand")
    ap.add_argument("--reach", type=float, default=0.004)
    ap.add_argument("--k", type=int, default=10)
    ap.add_argument("--n-per-family", type=int, default=10)
    ap.add_argument("--base", default=None, help="start from this ellipsoid YAML (default: the shipped default fit)")
    ap.add_argument("--out", default=str(REPO / "benchmarks" / "results" / "mbm" / "tight_wrist"))
    args = ap.parse_args(argv)
    import splatplan.eval.mbm as mbm
    from splatplan.robots import fit, fit_opt, load_robot
    from splatplan.robots.fit import EllipsoidSet
    from splatplan.robots.fit_cache import cached_fit
    from splatplan.robots.urdf import read_urdf

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    cfg = mbm.MBMConfig(families=("table_pick", "box", "bookshelf_small"), n_per_family=args.n_per_family)
    urdf = str(cfg.robot_path())
    model = read_urdf(urdf)
    base = fit.load_yaml(args.base) if args.base else cached_fit(model, "opt")[0]  # the shipped default fit
    links = args.links.split(",")
    t0 = time.perf_counter()
    new = fit.fit_model(model, method="opt", config=fit_opt.OptConfig(reach=args.reach, min_per_link=args.k, max_per_link=args.k, budget_per_link=0), links=links)
    fit_s = time.perf_counter() - t0
    keep = [i for i, name in enumerate(base.link) if name not in links]
    ells = EllipsoidSet([base.link[i] for i in keep] + list(new.link), np.concatenate([base.center[keep], new.center]),
                        np.concatenate([base.rot[keep], new.rot]), np.concatenate([base.semi_axes[keep], new.semi_axes]),
                        {**base.report, **new.report}, [])  # fmt: skip
    yaml = out / "panda_tight_wrist.yaml"
    note = f"{links} refitted: reach target {args.reach} m, {args.k} each ({fit_s:.0f} s)"
    if args.base:
        note = f"{Path(args.base).name} with {note}"
    fit.save_yaml(ells, yaml, robot="panda", urdf=urdf, note=note)
    if args.n_per_family <= 0:
        print({"fit_s": fit_s, "n_ellipsoids": ells.n, "model": str(yaml)})
        return {"fit_s": fit_s, "n_ellipsoids": ells.n}
    mbm.make_context = lambda c: mbm.MBMContext(c, load_robot(str(c.robot_path()), ellipsoids=str(yaml)))
    res = mbm.run_mbm(cfg, out, progress=False)
    s = res.summary["overall"]
    summary = {"fit_s": fit_s, "n_ellipsoids": ells.n, **{k: s[k] for k in ("free_endpoints", "problems_both_free", "solved", "median_time_s", "p95_time_s",
                                                                         "negative_clearance_paths", "worst_exact_clearance_m", "blocked_by_link", "median_configs")}}  # fmt: skip
    print(summary)
    return summary


if __name__ == "__main__":
    main(sys.argv[1:])
