"""How many goal candidates of the E5 visual reaching study each filter of the goal sampler keeps,
for each built-in Panda model (``reach_candidates``, the study's seed, scene and camera).

    python benchmarks/reach_goal_filters.py [--models tight,coarse] [--n-candidates 1024]

Prints a table and writes ``benchmarks/results/reach_goal_filters.{json,md}``: candidates left after
each filter in turn (all / camera behind the bin's front wall), and what the view filter would keep
with the earlier per-pixel alpha bar (every pixel > 0.98) instead of the mean. The candidates are
the same for every model (same seed, same kinematics); the models differ from the clearance on.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from splatplan.eval._study import write_outputs
from splatplan.planners.reach_goals import VIEW_MIN_ALPHA, VIEW_MIN_CONTRAST, reach_candidates, reach_start
from splatplan.render import SplatRenderer
from splatplan.render.cameras import wrist_camera
from splatplan.robots import load_robot
from splatplan.tasks._common import load_task_scene
from splatplan.tasks.reach import ReachConfig

LABELS = {
    "move": "camera move 5..15 cm (behind the wall or hidden from the start 5..20 cm)",
    "turn": "camera turn < 30 deg",
    "clearance": "exact clearance > 2 cm",
    "metric": "metric finds no collision",
    "self_collision": "no self-collision",
    "view": f"view: mean alpha > {VIEW_MIN_ALPHA} and pixel std > {VIEW_MIN_CONTRAST}",
}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", default="tight,coarse")
    ap.add_argument("--n-candidates", type=int, default=1024)
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "results" / "reach_goal_filters.json")
    a = ap.parse_args(argv)
    cfg = ReachConfig()  # the study's task settings: scene splats, camera, n_sigma, seed
    ts = load_task_scene("tabletop", n_sigma=cfg.n_sigma, device="cpu", n_splats=cfg.n_splats)
    res = {"n_candidates": a.n_candidates, "seed": cfg.mppi.seed, "n_splats": cfg.n_splats, "view_px": cfg.image_size, "n_sigma": cfg.n_sigma, "models": {}}
    with SplatRenderer(ts.splats, "cpu") as rend:
        for model in a.models.split(","):
            robot = load_robot("panda", model=model)
            cam = wrist_camera(robot, cfg.image_size, cfg.fov_deg, cfg.camera_link)
            c = reach_candidates(robot, ts, rend, cam, q_start=reach_start(robot, cfg.camera_link), n_candidates=a.n_candidates, seed=cfg.mppi.seed)
            rendered = np.isfinite(c.alpha_min)
            per_pixel = rendered & (np.nan_to_num(c.alpha_min) > VIEW_MIN_ALPHA) & (np.nan_to_num(c.view_std) > VIEW_MIN_CONTRAST)
            res["models"][model] = {
                "n_ellipsoids": robot.n_ellipsoids,
                "behind_wall": int(c.behind_wall.sum()),
                "after": [{"filter": f, "all": n_all, "behind_wall": n_b, "hidden_from_start": n_h} for f, n_all, n_b, n_h in c.counts()],
                "view_per_pixel_alpha": {"all": int(per_pixel.sum()), "behind_wall": int((per_pixel & c.behind_wall).sum())},
            }
    models = list(res["models"])
    lines = [f"Goal candidates of `make_reach_goals` (seed {res['seed']}, {res['n_candidates']} candidates, tabletop with {res['n_splats']:,} splats, "
             f"views at {res['view_px']} px, metric n_sigma = {res['n_sigma']}) left after each filter in turn, all / camera behind the wall:", "",
             "| filter | " + " | ".join(f"{m} ({res['models'][m]['n_ellipsoids']} ellipsoids)" for m in models) + " |", "|---" * (len(models) + 1) + "|",
             "| camera in `BEHIND_WALL` | " + " | ".join(f"- / {res['models'][m]['behind_wall']}" for m in models) + " |"]  # fmt: skip
    for k, f in enumerate(LABELS):
        lines.append(f"| {LABELS[f]} | " + " | ".join(f"{res['models'][m]['after'][k]['all']} / {res['models'][m]['after'][k]['behind_wall']}" for m in models) + " |")
    lines.append(f"| view with the earlier per-pixel bar (every pixel alpha > {VIEW_MIN_ALPHA}) | " + " | ".join(
        f"{res['models'][m]['view_per_pixel_alpha']['all']} / {res['models'][m]['view_per_pixel_alpha']['behind_wall']}" for m in models) + " |")  # fmt: skip
    md = "\n".join(lines) + "\n"
    a.out.parent.mkdir(parents=True, exist_ok=True)
    paths = write_outputs(a.out.parent, a.out.stem, res, md, indent=1)
    print(md)
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


if __name__ == "__main__":
    sys.exit(main())
