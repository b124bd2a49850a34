"""The Go2 on a real floor (issue #20): `mpc --robot go2` at its defaults to floor goals picked by a
rule on the capture's free-space map, not by hand.

    python benchmarks/real_go2.py [--scene ../shared/data/real/ARVR_Apartments_Toilet.compressed.ply]
                                  [--n-goals 3] [--cell 0.1] [--out benchmarks/results/real_go2.json]

1. ``scene align --drop-floaters`` (auto up, floor at z = 0) into a temporary folder.
2. The free-space map of the aligned floor for the Go2 (:func:`free_map`): every cell centre of a
   ``--cell`` grid over the robust box of the means, at 16 headings, checked with ``collides_robot``
   at `mpc`'s default n_sigma with the default terrain (the floor's splats up to the step height).
3. The rule (:func:`pick_start_and_goals`): the start is the cell free at the most headings (ties:
   the farthest from any fully blocked cell), at the middle of its widest run of free headings;
   the goals are cells of the start's 8-connected free component (free at >= 1 heading) that are
   free at >= 4 of the 16 headings and >= 0.5 m from the start, picked by farthest-point sampling
   from the start (the first goal is the farthest such cell, the next the farthest from both...).
4. ``splatplan mpc --robot go2 --scene ALIGNED --start S --goal G`` for each goal, all other
   settings at their defaults; a goal counts as reached when the final distance is < 0.3 m and the
   min metric clearance over the executed motion is > 0 (the issue's target).

Prints a markdown table and writes JSON. Skips (exit 0, says so) when the scene file is absent.
Timings on a shared machine are indicative only.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
BATHROOM = REPO / ".." / "shared" / "data" / "real" / "ARVR_Apartments_Toilet.compressed.ply"
N_YAWS = 16


def free_map(robot, checker, lo, hi, cell: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """xs (X,), ys (Y,), yaws (N_YAWS,), free (X, Y, N_YAWS) bool: the Go2 at each cell centre and heading."""
    xs = np.arange(lo[0] + cell / 2, hi[0], cell)
    ys = np.arange(lo[1] + cell / 2, hi[1], cell)
    yaws = np.linspace(-np.pi, np.pi, N_YAWS, endpoint=False)
    X, Y, W = np.meshgrid(xs, ys, yaws, indexing="ij")
    q = np.stack([X, Y, W], axis=-1).reshape(-1, 3)
    hit = np.asarray(checker.collides_robot(robot, q)).any(axis=-1)
    return xs, ys, yaws, ~hit.reshape(X.shape)


def pick_start_and_goals(xs, ys, yaws, free, n_goals: int = 3, min_open: int = 4, min_dist: float = 0.5):
    """The rule of the module docstring: (start (x, y, yaw), goals (G, 2), component mask (X, Y))."""
    from scipy import ndimage

    n_open = free.sum(axis=-1)  # (X, Y) free headings per cell
    if not n_open.any():
        raise SystemExit("no cell of the floor is free for the Go2 at any heading")
    room = ndimage.distance_transform_edt(n_open > 0)  # cells to the nearest fully blocked cell
    key = n_open * 1000.0 + room
    i, j = np.unravel_index(int(np.argmax(key)), key.shape)
    f = free[i, j].astype(int)  # widest run of free headings (circular), its middle
    best, at = -1, 0
    for k in range(N_YAWS):
        run = 0
        while run < N_YAWS and f[(k + run) % N_YAWS]:
            run += 1
        if run > best:
            best, at = run, k
    start = np.array([xs[i], ys[j], yaws[(at + best // 2) % N_YAWS]])
    lab, _ = ndimage.label(n_open > 0, structure=np.ones((3, 3)))
    comp = lab == lab[i, j]
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    cand = comp & (n_open >= min_open) & (np.hypot(X - start[0], Y - start[1]) >= min_dist)
    pts = np.c_[X[cand], Y[cand]]
    goals = []
    d = np.linalg.norm(pts - start[:2], axis=1)
    for _ in range(min(n_goals, len(pts))):
        k = int(np.argmax(d))
        goals.append(pts[k])
        d = np.minimum(d, np.linalg.norm(pts - pts[k], axis=1))
    return start, np.asarray(goals), comp


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default=str(BATHROOM), help="a capture (aligned here with --drop-floaters)")
    ap.add_argument("--n-goals", type=int, default=3)
    ap.add_argument("--cell", type=float, default=0.1, help="free-space map cell (m)")
    ap.add_argument("--max-steps", type=int, default=None, help="cap on the MPC steps (default: mpc's default)")
    ap.add_argument("--out", default=str(REPO / "benchmarks" / "results" / "real_go2.json"))
    args = ap.parse_args(argv)
    if not Path(args.scene).is_file():
        print(f"skipped: {args.scene} is not present")
        return 0
    t0 = time.perf_counter()
    tmp = Path(tempfile.mkdtemp(prefix="real_go2_"))
    try:
        return _run(args, tmp, t0)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _run(args, tmp: Path, t0: float) -> int:
    from splatplan.scenes.align import AlignConfig, align_scene, robust_box
    from splatplan.scenes.load import load_scene, save_scene
    from splatplan.tasks._common import base_terrain, load_task_scene
    from splatplan.tasks.base import BaseConfig, load_go2

    aligned, res = align_scene(load_scene(args.scene, filter_floaters=False), AlignConfig(drop_floaters=True))
    room = tmp / "room.ply"
    save_scene(aligned, room)
    cfg = BaseConfig()
    robot = load_go2()
    ts = load_task_scene(str(room), n_sigma=cfg.n_sigma, terrain=base_terrain(cfg))
    lo, hi, _ = robust_box(aligned.means, 1.0, 0.0)
    t_map = time.perf_counter()
    xs, ys, yaws, free = free_map(robot, ts.checker, lo, hi, args.cell)
    t_map = time.perf_counter() - t_map
    start, goals, comp = pick_start_and_goals(xs, ys, yaws, free, args.n_goals)
    n_open = free.sum(axis=-1)
    print(f"aligned: up {res.up.to_json()['up_axis']}, {res.n_floaters} floaters dropped; free map {free.shape} in {t_map:.0f} s: "
          f"{int((n_open > 0).sum())} of {n_open.size} cells free at some heading, {int(free.sum())} free poses; start's component {int(comp.sum())} cells")  # fmt: skip
    print(f"start {start.round(3).tolist()} (free at {int(n_open[np.argmin(abs(xs - start[0])), np.argmin(abs(ys - start[1]))])} of {N_YAWS} headings); goals {goals.round(3).tolist()}")
    rows = []
    env = dict(os.environ, SPLATPLAN_NO_TQDM="1")
    for k, g in enumerate(goals):
        out = tmp / f"goal{k}"
        cmd = [sys.executable, "-m", "splatplan.cli", "mpc", "--robot", "go2", "--scene", str(room), "--start", ",".join(f"{v:.4f}" for v in start),
               "--goal", ",".join(f"{v:.4f}" for v in g), "--out", str(out)]  # fmt: skip
        if args.max_steps is not None:
            cmd += ["--base-max-steps", str(args.max_steps)]
        t = time.perf_counter()
        p = subprocess.run(cmd, capture_output=True, text=True, env=env)
        wall = time.perf_counter() - t
        if not (out / "result.json").is_file():
            rows.append({"goal": g.round(4).tolist(), "error": (p.stdout + p.stderr).strip()[-400:], "wall_s": wall})
            print(f"goal {k} {g.round(2).tolist()}: no result ({(p.stdout + p.stderr).strip()[-200:]})")
            continue
        r = json.loads((out / "result.json").read_text())
        ok = r["final_position_error_m"] < 0.3 and r["min_clearance_m"] > 0
        rows.append({"goal": g.round(4).tolist(), "final_distance_m": r["final_position_error_m"], "min_clearance_m": r["min_clearance_m"],
                     "clearance_source": r["clearance_source"], "reached": bool(ok), "mpc_success": r["success"], "routed": r["extra"].get("route") is not None,
                     "n_steps": r["extra"]["n_steps"], "steps_per_s": r["steps_per_s"], "wall_s": wall, "stdout": p.stdout.strip()})  # fmt: skip
        print(f"goal {k} {g.round(2).tolist()}: distance {r['final_position_error_m']:.3f} m, clearance {r['min_clearance_m'] * 100:+.2f} cm, "
              f"{'route' if rows[-1]['routed'] else 'goal only'}, {r['extra']['n_steps']} steps, {'reached' if ok else 'NOT reached'}", flush=True)  # fmt: skip
    table = ["| goal (x, y) | final distance (m) | min metric clearance (cm) | route | MPC steps | reached (< 0.3 m, clearance > 0) |", "|---|---|---|---|---|---|"]
    for r in rows:
        if "error" in r:
            table.append(f"| {r['goal']} | - | - | - | - | no result |")
        else:
            table.append(f"| ({r['goal'][0]:.2f}, {r['goal'][1]:.2f}) | {r['final_distance_m']:.3f} | {r['min_clearance_m'] * 100:+.2f} | "
                         f"{'yes' if r['routed'] else 'no'} | {r['n_steps']} | {'yes' if r['reached'] else 'no'} |")  # fmt: skip
    print("\n".join(table))
    result = {
        "benchmark": "real_go2", "scene": str(Path(args.scene).name), "n_splats_aligned": len(aligned), "n_floaters_dropped": res.n_floaters,
        "n_sigma": cfg.n_sigma, "cell_m": args.cell, "n_yaws": N_YAWS, "free_cells": int((n_open > 0).sum()), "free_poses": int(free.sum()),
        "component_cells": int(comp.sum()), "start": start.round(4).tolist(), "rule": "start: most free headings; goals: farthest-point sampling over the start's component, >= 4/16 headings free, >= 0.5 m away",
        "goals": rows, "n_reached": int(sum(r.get("reached", False) for r in rows)), "time_s": time.perf_counter() - t0,
        "map": {"xs": xs.round(4).tolist(), "ys": ys.round(4).tolist(), "n_free_headings": n_open.tolist()},
        "note": "timings from a shared machine",
    }  # fmt: skip
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    tmp_out = Path(str(args.out) + ".tmp")
    tmp_out.write_text(json.dumps(result, indent=1))
    os.replace(tmp_out, args.out)
    Path(args.out).with_suffix(".md").write_text("\n".join(table) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
