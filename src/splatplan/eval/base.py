"""Base study: the Go2 driving from the living room of ``apartment`` to goals in the other rooms,
given **only the goal position** (as the final node of an RRT path would be): with the collision
cost (plain MPPI), with the collision cost and the sensed-obstacle memory
(:class:`~splatplan.planners.memory.ObstacleMemory`, ``BaseConfig.memory``), and without the collision
cost.

Goals: random positions in the bedroom and the kitchen where the Go2 stands collision-free at some
heading with at least 10 cm exact clearance. Start (-2.3, -0.6, yaw 0) in the living room: the
straight line to the kitchen goals runs into the 0.25 m living-kitchen doorway (narrower than the
Go2), a trap that the local planner (:mod:`splatplan.tasks.base`) must get out of through the
0.8 m doorway near the outer wall or through the bedroom. Plain MPPI does not (the kitchen goals
fail with and without the optional stagnation sweeps); with the memory, the goal cost follows the
geodesic distance on the cells sensed so far (unknown = free) that were in the sensor's line of
sight (``BaseConfig.sensor_occlusion``), and the base learns the walls where it sees them. The base's metric runs at
n_sigma = 0.75 (:class:`~splatplan.tasks.base.BaseConfig`; at 1 the 0.8 m living-kitchen doorway
admits no collision-free pose); the reported clearance is the exact one to the boxes.

``run_base_study(out)`` writes ``base.json`` (same row fields as the arm study, plus the time to
goal; ``rows_meaning`` says what each row is, ``memory_cost`` the time spent sensing (of it
``sight_s`` on the line of sight) and on the geodesic field) and ``base.md``.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np

from ..tasks.base import START  # (-2.3, -0.6, yaw 0) in the living room
from ._common import config_rows, mean_std, write_atomic

#: The rows: config name -> (collision cost, memory, what the row is).
CONFIGS = {
    "with_collision": (True, False, "plain MPPI with the collision cost, straight-line goal term (shows the local minimum)"),
    "with_collision_memory": (True, True, "the same plus the sensed-obstacle memory: geodesic goal term on the cells sensed within sensor_radius_m and in line of sight (the target row)"),
    "without_collision": (False, False, "no collision cost (baseline: drives through the walls)"),
}


def pick_goals(n: int, seed: int = 0, min_clearance: float = 0.1) -> list[np.ndarray]:
    """``n`` goal positions (2,) alternating bedroom / kitchen, free for the Go2 at some heading."""
    from ..scenes.builtin.apartment import ROOMS, apartment_layout
    from ..tasks.base import load_go2

    robot = load_go2()
    gt = apartment_layout(seed).scene
    gt = gt.select(np.array([lab != "floor" for lab in gt.labels]))
    rng = np.random.default_rng([seed, 88])
    rooms = ["bedroom", "kitchen"]
    out = []
    for k in range(400):
        if len(out) == n:
            break
        lo, hi = (np.asarray(v, np.float64) for v in ROOMS[rooms[len(out) % 2]])
        xy = lo + 0.3 + rng.random(2) * (hi - lo - 0.6)
        yaws = np.linspace(-np.pi, np.pi, 8, endpoint=False)
        q = np.stack([np.full(8, xy[0]), np.full(8, xy[1]), yaws], axis=1)
        c, qq, a = robot.ellipsoids(q)
        if gt.ellipsoid_clearance(c, qq, a).min(axis=-1).max() >= min_clearance:
            out.append(xy)
    return out


def run_base_study(out_dir, quick: bool = False, seed: int = 0, device: str | None = "cpu") -> dict:
    """Run the study, write ``base.json`` and ``base.md`` into ``out_dir``; returns the JSON dict."""
    from ..tasks._common import base_terrain, load_task_scene
    from ..tasks.base import BaseConfig, load_go2, run_base

    t0 = time.perf_counter()
    n = 1 if quick else 5
    cfg = BaseConfig(max_steps=250)
    cfg = replace(cfg, mppi=replace(cfg.mppi, seed=seed))
    if quick:
        cfg = replace(cfg, max_steps=130)
    goals = pick_goals(n, seed=seed)
    robot = load_go2()
    ts = load_task_scene("apartment", n_sigma=cfg.n_sigma, device=device, terrain=base_terrain(cfg))
    trials = []
    for i, g in enumerate(goals):
        for name, (collision, memory, _) in CONFIGS.items():
            r = run_base(robot, ts, g, start=START, config=replace(cfg, mppi=replace(cfg.mppi, seed=seed + i), memory=memory), collision=collision, device=device)
            mem = r.extra["memory"] or {}
            trials.append({
                "goal": i, "config": name, "goal_position": g.round(4).tolist(),
                "success": r.success, "min_clearance_m": r.min_clearance_m, "final_error_m": r.final_position_error_m,
                "time_to_goal_s": r.extra["time_to_goal_s"] if r.success else None, "n_steps": r.extra["n_steps"],
                "time_s": r.time_s, "steps_per_s": r.steps_per_s, "n_detours": sum(e["event"] == "detour" for e in r.extra["events"]),
                "memory": {k: mem.get(k) for k in ("n_sensed", "n_blocked", "n_queries", "n_recomputes", "sense_s", "first_sense_s", "field_s",
                                                    "occlusion", "n_rays", "n_occluded", "n_opacity_queries", "sight_s")} if mem else None,
            })  # fmt: skip
            print(f"  goal {i} {g.round(2).tolist()} {name:22s}: distance {r.final_position_error_m:.2f} m, clearance {r.min_clearance_m * 100:+.1f} cm, "
                  f"{'reached' if r.success else 'not reached'}, {r.extra['n_steps']} steps, {r.steps_per_s:.2f} steps/s", flush=True)  # fmt: skip
    rows = config_rows(trials, ("min_clearance_m", "final_error_m"), configs=tuple(CONFIGS),
                        extra=lambda t: {"time_to_goal_s": mean_std([x["time_to_goal_s"] for x in t if x["time_to_goal_s"] is not None])})  # fmt: skip
    mt = [x for x in trials if x["memory"]]
    sensing = {
        "sense_s": float(sum(x["memory"]["sense_s"] for x in mt)), "first_sense_s": float(sum(x["memory"]["first_sense_s"] or 0.0 for x in mt)), "field_s": float(sum(x["memory"]["field_s"] for x in mt)),
        "sight_s": float(sum(x["memory"].get("sight_s") or 0.0 for x in mt)), "occlusion": bool(cfg.sensor_occlusion), "sensor_height_m": float(cfg.sensor_height_m),
        "run_s": float(sum(x["time_s"] for x in mt)), "n_steps": int(sum(x["n_steps"] for x in mt)),
    }  # fmt: skip
    result = {
        "study": "base", "quick": bool(quick), "seed": int(seed), "robot": "go2", "scene": "apartment", "start": list(START),
        "n_splats": len(ts.splats), "config": asdict(cfg), "time_s": time.perf_counter() - t0,
        "clearance": "exact signed distance from every Go2 ellipsoid to the boxes other than the floor, over the executed trajectory",
        "success": f"final distance to the goal < {cfg.goal_tol} m and positive clearance throughout",
        "rows": rows, "rows_meaning": {k: v[2] for k, v in CONFIGS.items()}, "memory_cost": sensing, "trials": trials,
    }  # fmt: skip
    out_dir = Path(out_dir)
    write_atomic(out_dir / "base.json", json.dumps(result, indent=1) + "\n")
    md = ["| config | min clearance (m) | final distance (m) | time to goal (s) | successes | positive clearance | steps/s |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        md.append(f"| {r['config']} | {r['min_clearance_m'][0]:+.4f} ± {r['min_clearance_m'][1]:.4f} | {r['final_error_m'][0]:.3f} ± {r['final_error_m'][1]:.3f} | "
                  f"{r['time_to_goal_s'][0]:.1f} | {r['successes']}/{r['trials']} | {r['positive_clearance']}/{r['trials']} | {r['steps_per_s'][0]:.2f} |")  # fmt: skip
    md.append("")
    md += [f"- `{k}`: {v[2]}" for k, v in CONFIGS.items()]
    if sensing["run_s"] > 0:
        md.append(f"- memory cost over the `with_collision_memory` runs: sensing {sensing['sense_s']:.1f} s + geodesic field {sensing['field_s']:.1f} s "
                  f"of {sensing['run_s']:.1f} s ({100 * (sensing['sense_s'] + sensing['field_s']) / sensing['run_s']:.0f} %, {sensing['n_steps']} MPC steps; "
                  f"the first sense of each run, the whole disc, {sensing['first_sense_s']:.1f} s of it"
                  + (f"; line of sight at z = {sensing['sensor_height_m']:.2f} m, {sensing['sight_s']:.1f} s of the sensing)" if sensing["occlusion"] else "; no occlusion: senses through walls)"))  # fmt: skip
    write_atomic(out_dir / "base.md", "\n".join(md) + "\n")
    print("\n".join(md))
    return result
