"""Real rooms at the default settings: does a Go2 stand and walk where the floor is
visibly free, and does a 5 cm sphere cross the room?

    python benchmarks/real_rooms.py [--variants default,paper,...] [--n-points 20] [--n-pairs 10]
                                    [--time-limit 10] [--sphere-time-limit 30] [--out benchmarks/results/real_rooms.json]

Rooms (each skipped, and said so, when absent):

* ``bathroom``: the shared capture ``ARVR_Apartments_Toilet.compressed.ply`` aligned as
  ``splatplan scene align FILE --out room.ply`` does (auto up, floor at z = 0, no floater drop),
  then loaded as ``splatplan plan`` loads a file (the default floater filter);
* ``apartment_haze``: the built-in apartment with its real-capture look
  (``splatplan scene apartment --haze``: haze, a mirror layer under the kitchen floor, floor-level
  matter), loaded the same way.

Per room, computed here from the splats alone (no ground truth):

1. **Visible obstacles**: splats with opacity >= 0.3 whose means lie 5 cm to 1.2 m above the floor
   (z = 0 after alignment). **Floor**: cells of a 5 cm grid holding a splat of opacity >= 0.3
   within 5 cm of z = 0. **Visibly free floor points**: floor cells at least 50 cm (xy) from every
   visible obstacle (the Go2 is ~65 cm long).
2. 20 such points (seeded; fewer when the room has fewer), at heading 0 (``--start=X,Y,0``): how many are free for the Go2 at the
   metric variant's settings, with the default terrain rule (``splatplan plan --robot go2``).
3. 10 random pairs of them: ``plan`` (the CLI's planner at its defaults: ``--planner auto``, no
   refinement) with a 10 s limit; a plan
   counts when it is found and every point of the path, densified at 2 cm, lies on the visibly free
   floor in the wide sense: on a floor cell (or within 10 cm of one) and at least 15 cm (the Go2's
   half width) from every visible obstacle.
4. A 5 cm sphere (``sphere:0.05``) in the plane ``--sphere-z`` (0.5 m) above the floor (``plan --planar``: the
   built-in apartment has no ceiling to stop a path over its walls) between the two floor cells
   farthest apart (of 400 seeded ones) that lie at least 25 cm from every visible obstacle, with
   ``--sphere-time-limit``, on the whole scene (no terrain rule); it counts when found and every
   path point, densified at 2 cm, lies >= 5 cm (the sphere's radius, in 3D at the plane's height) from
   every visible obstacle's mean (the sphere flies over low furniture).

Variants (``--variants``, :data:`VARIANTS`): ``default`` (today's ``MetricConfig()`` and
``TerrainConfig()``), ``paper`` (the paper's settings: ``MetricConfig.paper()``, the
paper's n_sigma 1, every splat, opacity-blind inflation, and the "shape" terrain rule) and the
candidates of the README's "Faint splats and the floor" section. Prints a markdown table, writes JSON and the .md beside it.
Timings on a shared machine are indicative only.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
BATHROOM = REPO / ".." / "shared" / "data" / "real" / "ARVR_Apartments_Toilet.compressed.ply"
VISIBLE_OPACITY = 0.3
OBST_Z = (0.05, 1.2)
FLOOR_CELL = 0.05
MIN_CLEAR = 0.5
PATH_CLEAR = 0.15
SPHERE_CLEAR = 0.25
SUPPORT = 0.10

#: candidate treatments of faint splats: name -> (MetricConfig changes from the paper's settings,
#: the terrain rule); "paper" is the paper's settings (the paper's metric, the "shape"
#: terrain rule), "default" today's MetricConfig() and TerrainConfig(); "default_squared" the default
#: with the paper's linearisation in s2 (MetricConfig(linearize="squared")), "distance+band" the
#: paper's metric with only the distance linearisation and the band terrain rule
VARIANTS = {
    "paper": ({}, "shape"),
    "opacity_scaled": ({"opacity_scaled_inflation": True}, "shape"),
    "opacity_min_0.1": ({"opacity_min": 0.1}, "shape"),
    "opacity_scaled+min_0.1": ({"opacity_scaled_inflation": True, "opacity_min": 0.1}, "shape"),
    "opacity_min_0.3": ({"opacity_min": 0.3}, "shape"),
    "n_sigma_0": ({"n_sigma": 0.0}, "shape"),
    "paper+band": ({}, "band"),
    "distance+band": ({"linearize": "distance"}, "band"),
    "default_squared": ({"opacity_scaled_inflation": True, "opacity_min": 0.1}, "band"),
}


def metric_config(name: str):
    from splatplan.metric import MetricConfig

    if name == "default":
        return MetricConfig()
    return replace(MetricConfig.paper(), **VARIANTS[name][0])


def terrain_config(name: str):
    from splatplan.scenes.terrain import TerrainConfig

    return TerrainConfig() if name == "default" else TerrainConfig(rule=VARIANTS[name][1])


def load_rooms(names):
    from splatplan.scenes.align import AlignConfig, align_scene
    from splatplan.scenes.builtin import build_builtin
    from splatplan.scenes.filters import filter_floaters
    from splatplan.scenes.load import load_scene

    rooms = {}
    for name in names:
        if name == "bathroom":
            if not BATHROOM.is_file():
                print(f"skip bathroom: {BATHROOM} is absent")
                continue
            aligned, _ = align_scene(load_scene(BATHROOM, filter_floaters=False), AlignConfig())
            rooms[name] = filter_floaters(aligned)[0]
        elif name == "apartment_haze":
            rooms[name] = filter_floaters(build_builtin("apartment", haze=True)[0])[0]
        else:
            raise SystemExit(f"unknown room {name!r}")
    return rooms


class FreeFloor:
    """The visibly free floor of an aligned room (module docstring, item 1)."""

    def __init__(self, splats):
        from scipy.spatial import cKDTree

        m, o = splats.means.astype(np.float64), splats.opacities
        vis = o >= VISIBLE_OPACITY
        obst = vis & (m[:, 2] >= OBST_Z[0]) & (m[:, 2] <= OBST_Z[1])
        floor = vis & (np.abs(m[:, 2]) <= 0.05)
        self.obst_tree = cKDTree(m[obst, :2])
        self.obst_tree3 = cKDTree(m[obst])  # the same obstacles in 3D (a flying robot's check)
        self.floor_tree = cKDTree(m[floor, :2])
        lo, hi = np.percentile(m[floor, :2], 0.5, axis=0), np.percentile(m[floor, :2], 99.5, axis=0)
        xs, ys = np.arange(lo[0], hi[0], FLOOR_CELL), np.arange(lo[1], hi[1], FLOOR_CELL)
        X, Y = np.meshgrid(xs, ys, indexing="ij")
        cells = np.c_[X.ravel(), Y.ravel()]
        on_floor = self.floor_tree.query(cells, distance_upper_bound=FLOOR_CELL / 2)[0] < np.inf
        clear = self.obst_tree.query(cells)[0]
        self.n_obst, self.n_floor_cells = int(obst.sum()), int(on_floor.sum())
        self.candidates = cells[on_floor & (clear >= MIN_CLEAR)]
        self.sphere_cells = cells[on_floor & (clear >= SPHERE_CLEAR)]

    def on_free_floor(self, xy: np.ndarray) -> np.ndarray:
        sup = self.floor_tree.query(xy, distance_upper_bound=SUPPORT)[0] < np.inf
        return sup & (self.obst_tree.query(xy)[0] >= PATH_CLEAR)


def densify(path: np.ndarray, step: float = 0.02) -> np.ndarray:
    out = [path[:1, :2]]
    for a, b in zip(path[:-1, :2], path[1:, :2]):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        out.append(a + (b - a) * (np.arange(1, n + 1)[:, None] / n))
    return np.concatenate(out)


def _plan(checker, start, goal, robot, seed, time_limit, frozen=None):
    """(found, path or None, message): a start or goal in collision is a plan not found."""
    from splatplan.errors import PlanningError
    from splatplan.planners import RRTConfig, plan

    try:
        res = plan(checker, start, goal, robot=robot, seed=seed, refine=False,  # as `splatplan plan` without --refine
                   rrt_config=RRTConfig(time_limit_s=time_limit, seed=seed, frozen=frozen))
    except PlanningError as e:
        return False, None, str(e).split(": min_s2")[0]
    return bool(res.success), (np.asarray(res.path) if res.success else None), res.message


def run_room(name, splats, variant, args, rng_seed=0):
    from splatplan.metric import CollisionChecker
    from splatplan.robots import load_robot
    from splatplan.scenes.terrain import remove_terrain

    cfg = metric_config(variant)
    ff = FreeFloor(splats)
    rng = np.random.default_rng([rng_seed, 36])
    n_pts = min(args.n_points, len(ff.candidates))  # a small room has fewer
    if n_pts < 2:
        return {"room": name, "variant": variant, "error": f"only {len(ff.candidates)} visibly free floor cells"}
    pts = ff.candidates[rng.choice(len(ff.candidates), n_pts, replace=False)]
    yaws = np.zeros(n_pts)  # heading 0, as `plan --start=X,Y,0`
    go2 = load_robot("go2")
    ground, _ = remove_terrain(splats, terrain_config(variant), n_sigma=cfg.n_sigma)
    checker = CollisionChecker(ground, device="cpu", config=cfg)
    q = np.c_[pts, yaws]
    hit = np.asarray(checker.collides_robot(go2, q)).reshape(len(q), -1)
    free = ~hit.any(axis=1)
    n_hit_ell = hit.sum(axis=1)
    pairs, plans = [], []
    while len(pairs) < min(args.n_pairs, n_pts * (n_pts - 1)):
        i, j = rng.choice(n_pts, 2, replace=False)
        if (i, j) not in pairs:
            pairs.append((int(i), int(j)))
    for k, (i, j) in enumerate(pairs):
        t = time.perf_counter()
        found, path, msg = _plan(checker, q[i], q[j], go2, k, args.time_limit)
        dt = time.perf_counter() - t
        on = None if path is None else bool(ff.on_free_floor(densify(path)).all())
        plans.append({"start": q[i].tolist(), "goal": q[j].tolist(), "found": found, "time_s": dt, "on_free_floor": on,
                      "ok": bool(found and on), "message": msg})
    # the sphere: the two floor cells >= SPHERE_CLEAR from visible obstacles farthest apart (of 400
    # seeded ones), 25 cm up, no terrain rule (a flying robot)
    sc = ff.sphere_cells[rng.choice(len(ff.sphere_cells), min(400, len(ff.sphere_cells)), replace=False)]
    d = np.linalg.norm(sc[:, None] - sc[None], axis=-1)
    a, b = np.unravel_index(int(np.argmax(d)), d.shape)
    sph_checker = CollisionChecker(splats, device="cpu", config=cfg)
    s0, s1 = np.r_[sc[a], args.sphere_z], np.r_[sc[b], args.sphere_z]
    t = time.perf_counter()
    # in the plane z = sphere_z (`plan --planar`): a built-in room has no ceiling to stop a path over the walls
    sfound, spath, smsg = _plan(sph_checker, s0, s1, load_robot("sphere:0.05"), 0, args.sphere_time_limit, frozen=(2,))
    sdt = time.perf_counter() - t
    # clear: no visible obstacle's mean inside the sphere anywhere along the path (3D: it flies over low furniture)
    s_on = None if spath is None else bool((ff.obst_tree3.query(np.c_[densify(spath), np.full(len(densify(spath)), args.sphere_z)])[0] >= 0.05).all())
    return {
        "room": name, "variant": variant, "config": asdict(cfg), "terrain": asdict(terrain_config(variant)), "n_splats": len(splats), "n_visible_obstacles": ff.n_obst,
        "n_free_floor_cells": len(ff.candidates), "points": q.tolist(), "go2_free": free.tolist(), "n_free": int(free.sum()),
        "hit_ellipsoids": n_hit_ell.tolist(), "plans": plans, "n_plans_ok": int(sum(p["ok"] for p in plans)),
        "n_plans_found": int(sum(p["found"] for p in plans)),
        "sphere": {"start": s0.tolist(), "goal": s1.tolist(), "distance": float(d[a, b]), "found": sfound, "time_s": sdt, "path_clear_of_visible_obstacles": s_on,
                   "message": smsg},
    }


def table(rows) -> str:
    head = "| room | variant | Go2 free at visibly free floor points | plans found (10 s) | plans found and on visibly free floor | 5 cm sphere across (m, s) |\n|---|---|---|---|---|---|\n"
    lines = []
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['room']} | {r['variant']} | {r['error']} | | | |")
            continue
        n, m = len(r["points"]), len(r["plans"])
        sp = r["sphere"]
        ok = "yes" if sp["found"] and sp.get("path_clear_of_visible_obstacles", True) else ("path through visible obstacles" if sp["found"] else "no")
        lines.append(f"| {r['room']} | {r['variant']} | {r['n_free']} / {n} | {r['n_plans_found']} / {m} | {r['n_plans_ok']} / {m} | "
                     f"{ok} ({sp['distance']:.1f} m, {sp['time_s']:.1f} s) |")
    return head + "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rooms", default="bathroom,apartment_haze")
    ap.add_argument("--variants", default="default")
    ap.add_argument("--n-points", type=int, default=20)
    ap.add_argument("--n-pairs", type=int, default=10)
    ap.add_argument("--time-limit", type=float, default=10.0)
    ap.add_argument("--sphere-time-limit", type=float, default=30.0)
    ap.add_argument("--sphere-z", type=float, default=0.5, help="the sphere's plane (m above the floor); at 0.25 the built-in apartment's "
                    "large opaque floor splats (stds up to 0.33 m) reach it at n_sigma 1, haze or not")
    ap.add_argument("--out", default=str(REPO / "benchmarks" / "results" / "real_rooms.json"))
    args = ap.parse_args(argv)
    t0 = time.time()
    rooms = load_rooms([r for r in args.rooms.split(",") if r])
    rows = []
    for variant in [v for v in args.variants.split(",") if v]:
        for name, splats in rooms.items():
            r = run_room(name, splats, variant, args)
            rows.append(r)
            print(table([r]).splitlines()[-1], flush=True)
    md = table(rows)
    print(md)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    meta = {"benchmark": "real_rooms", "when": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "machine": f"{platform.machine()}, {platform.python_version()}",
            "wall_s": time.time() - t0, "args": vars(args)}
    out.write_text(json.dumps({**meta, "rows": rows}, indent=1))
    out.with_suffix(".md").write_text(
        f"# Real rooms at the default settings\n\nRun {meta['when']} ({meta['wall_s']:.0f} s); `python benchmarks/real_rooms.py "
        f"--variants {args.variants}`. Rules: see the script's docstring (visible obstacles: opacity >= {VISIBLE_OPACITY}, "
        f"{OBST_Z[0]:g}-{OBST_Z[1]:g} m above the floor; points >= {MIN_CLEAR} m from them; path points on floor support and >= {PATH_CLEAR} m from them).\n\n" + md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
