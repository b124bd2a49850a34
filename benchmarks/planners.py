"""Planner benchmarks (issue targets, this 2-core CPU; every row names the robot body it used).

1. RRT, sphere r = 0.015, built-in Stonehenge (200k splats), n_sigma = 1, plane z = 0.06: centre ->
   random free border goals; median time after warm-up, success rate; every returned path is
   re-checked (``n_colliding == 0`` on every segment sampled at <= r/2, endpoints included) and
   its clearance to the exact geometry (SDF - r > 0, sampled every r/2).
2. MPPI, planar base on Stonehenge (K = 256, T = 30, 2 iterations per MPC step) driving through
   the ring, for two bodies: one sphere r = 0.015 (the README's figure) and the default
   ``PlanarBase`` body ellipsoid (0.03, 0.015, 0.012). The ellipsoid costs more because the metric
   kernel has a fast path for spheres only and its search radius grows with the largest semi-axis
   and the ratio largest / smallest semi-axis.
3. MPPI, Panda arm (``JointIntegrator(load_robot("panda"))``, every link ellipsoid of its default
   model in the collision cost: the tight model's 53 since issue 19, the committed results are the
   coarse model's 11; one query per iteration on (K = 256, T = 32, 7); the static link0 is queried
   once and cached, ``CollisionCost``), 1 iteration per MPC step, reaching a target over the
   built-in tabletop at 200k splats: every step, every step without the static cache, the
   ``"auto"`` time stride (with its stride and gap), strides 2 and 4; plus the time of one such
   collision query on the (unit-size) Stonehenge, where the Panda's ellipsoids (up to 0.24 m
   semi-axes) each cover a large part of the 1 m scene.
4. Real captures in ``../shared/data/real`` (skipped when absent), ``splatplan plan`` defaults
   (sphere r = 0.015, n_sigma = 1, scene-scaled RRT settings, 10 s limit): start and goal drawn
   automatically as far-apart free points of the robust scene box.

    python benchmarks/planners.py [--goals 50] [--quick] [--only panda] [--out benchmarks/results/planners.json]

``--only panda`` reruns just the Panda MPPI rows and merges them into the existing JSON.

Writes JSON and a markdown table (planners.md) next to it. Timings depend on the machine's load:
the JSON records the 1-minute load average at the start of each section.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

#: the planning robot: the studies' sphere (splatplan.robots.DEFAULT_POINT_ROBOT) and its radius
ROBOT = "sphere:0.015"
RADIUS = 0.015
REAL = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real"
#: real captures planned on (file, short name)
REAL_SCENES = (("uav4geo_truck.splat", "truck"), ("ARVR_Apartments_Toilet.compressed.ply", "bathroom"),
               ("equinor_banana_splat.ply", "banana"), ("playcanvas_biker.spz", "biker"))  # fmt: skip


def _load() -> float:
    return float(os.getloadavg()[0])


def border_goals(checker, n: int, z: float, rng: np.random.Generator, r_border: float = 0.47) -> np.ndarray:
    """n collision-free goals on a circle of radius r_border (the scene border), plane z."""
    goals = []
    while len(goals) < n:
        ang = rng.uniform(0, 2 * np.pi, 4 * n)
        cand = np.stack([r_border * np.cos(ang), r_border * np.sin(ang), np.full_like(ang, z)], 1)
        free = ~checker.collides(cand, None, RADIUS)
        goals.extend(cand[free].tolist())
    return np.asarray(goals[:n])


def bench_rrt(scene, gt, n_goals: int, seed: int = 0) -> dict:
    from splatplan.metric import CollisionChecker
    from splatplan.planners import RRTConfig, edge_points, plan
    from splatplan.planners.metrics import clearance
    from splatplan.scenes.builtin.stonehenge import PLANE_Z

    load = _load()
    checker = CollisionChecker(scene, n_sigma=1.0)
    rng = np.random.default_rng(seed)
    goals = border_goals(checker, n_goals, PLANE_Z, rng)
    start = np.array([0.0, 0.0, PLANE_Z])
    cfg = RRTConfig(box_lo=(-0.5, -0.5, PLANE_Z), box_hi=(0.5, 0.5, PLANE_Z), time_limit_s=10.0)
    plan(checker, start, goals[0], robot=ROBOT, refine=False, seed=seed, rrt_config=cfg)  # warm-up
    times, ok, n_col, clear, lengths = [], 0, [], [], []
    for i, g in enumerate(goals):
        res = plan(checker, start, g, robot=ROBOT, refine=False, seed=seed + i, rrt_config=cfg)
        times.append(res.time_s)
        if not res.success:
            continue
        ok += 1
        lengths.append(res.length)
        # every segment sampled at <= r/2, its endpoints included (the planner checks at r/4)
        dense = edge_points(res.path[:-1], res.path[1:], RADIUS / 2, include_start=True).reshape(-1, 3)
        n_col.append(int(checker.query(dense, None, RADIUS).n_colliding.max()))
        clear.append(clearance(res.path, gt.sdf, RADIUS, spacing=RADIUS / 2))
    return {
        "robot": f"sphere r = {RADIUS}",
        "scene": f"stonehenge level 1 ({len(scene):,} splats after the floater filter)",
        "n_goals": n_goals,
        "success_rate": ok / n_goals,
        "time_median_s": float(np.median(times)),
        "time_p90_s": float(np.quantile(times, 0.9)),
        "length_mean": float(np.mean(lengths)) if lengths else float("nan"),
        "paths_with_colliding_splats": int(np.sum(np.asarray(n_col) > 0)),
        "min_clearance_exact": float(np.min(clear)) if clear else float("nan"),
        "paths_with_nonpositive_clearance": int(np.sum(np.asarray(clear) <= 0)),
        "load_avg_1min": load,
    }


def bench_mppi_base(scene, body: str, n_steps: int = 40, seed: int = 0) -> dict:
    from splatplan.metric import CollisionChecker
    from splatplan.planners import MPPI, MPPIConfig, PlanarBase
    from splatplan.scenes.builtin.stonehenge import PLANE_Z

    load = _load()
    checker = CollisionChecker(scene, n_sigma=1.0)
    if body == "sphere":
        dyn = PlanarBase(height=PLANE_Z, offsets=np.zeros((1, 3)), semi_axes=np.array([[RADIUS, RADIUS, RADIUS]]))
        label = f"planar base, one sphere r = {RADIUS}"
    else:
        dyn = PlanarBase(height=PLANE_Z)
        label = "planar base, default body ellipsoid (0.03, 0.015, 0.012)"
    goal = np.array([0.45, 0.1])
    cfg = MPPIConfig(n_samples=256, horizon=30, n_knots=6, dt=0.1, n_iters=2, noise_sigma=(0.1, 0.1, 0.5),
                     u_min=(-0.2, -0.2, -1.0), u_max=(0.2, 0.2, 1.0), seed=seed)  # fmt: skip

    def task(states):  # (K, T, 3) -> (K,): distance of the base to the goal, summed over time
        return np.linalg.norm(states[..., :2] - goal, axis=-1).sum(axis=1)

    mppi = MPPI(dyn, checker, cfg, task_cost=task)
    x = np.array([0.0, 0.0, 0.0])
    mppi.step(x)  # warm-up
    t0 = time.perf_counter()
    hits = 0
    for _ in range(n_steps):
        u, info = mppi.step(x)
        x = dyn.rollout(x, u[None, None, :], cfg.dt)[0, 0]
        c, q, a = dyn.link_poses(x[None])
        hits += int(checker.query(c, q, a).in_collision.any())
    dt = time.perf_counter() - t0
    return {
        "robot": label, "K": cfg.n_samples, "T": cfg.horizon, "iters_per_step": cfg.n_iters, "steps": n_steps,
        "steps_per_s": n_steps / dt, "final_distance_to_goal": float(np.linalg.norm(x[:2] - goal)),
        "steps_in_collision": hits, "load_avg_1min": load,
    }  # fmt: skip


def panda_setup(n_splats: int = 200_000, seed: int = 0, device: str = "cpu"):
    """(robot, scene, checker) of the Panda benchmark: the built-in tabletop at ``n_splats``, floaters filtered."""
    from splatplan.metric import CollisionChecker
    from splatplan.robots import load_robot
    from splatplan.scenes.builtin import build_builtin
    from splatplan.scenes.filters import filter_floaters

    robot = load_robot("panda")
    raw, _ = build_builtin("tabletop", seed=seed, n_splats=n_splats)
    scene, _ = filter_floaters(raw)
    return robot, scene, CollisionChecker(scene, n_sigma=1.0, device=device)


def _timed(fn, spent: dict, key: str):
    """``fn`` that adds its wall time to ``spent[key]``."""

    def wrapped(*a, **kw):
        t = time.perf_counter()
        try:
            return fn(*a, **kw)
        finally:
            spent[key] += time.perf_counter() - t

    return wrapped


def near_configs(robot, x, n: int, seed: int = 0) -> np.ndarray:
    """(n, dof) configurations around ``x`` (normal, 0.1 rad), clipped to the joint limits."""
    rng = np.random.default_rng(seed)
    return np.clip(x + rng.normal(scale=0.1, size=(n, robot.dof)), robot.joint_limits[:, 0], robot.joint_limits[:, 1])


def time_query_robot(checker, robot, q, ellipsoids, repeats: int = 5, **kw) -> float:
    """Median wall seconds of ``checker.query_robot(robot, q, ellipsoids=...)`` after a warm-up,
    waiting for the device's results each time."""
    checker.query_robot(robot, q, ellipsoids=ellipsoids, **kw)
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        r = checker.query_robot(robot, q, ellipsoids=ellipsoids, **kw)
        _ = np.asarray(r.cost.numpy() if hasattr(r.cost, "numpy") else r.cost)[:1]  # wait for the device
        ts.append(time.perf_counter() - t)
    return float(np.median(ts))


def _query_only_s(robot, checker, col, x, n: int, seed: int, repeats: int = 5, lanes: tuple[int, ...] = ()) -> dict:
    """Median seconds of the collision query alone (the cost's checker: its s2_cap) on n
    configurations near ``x`` (moving ellipsoids, FK on the device): q from numpy, and q already on
    the device (wp.array); and for each of ``lanes`` (threads per query, TierConfig.lanes) with q on
    the device."""
    from dataclasses import replace

    from splatplan._warp import wp as _wp

    wp = _wp()
    q = near_configs(robot, x, n, seed)
    mv = np.flatnonzero(~col.static) if col.static is not None else None
    qw = wp.array(q.astype(np.float32), dtype=wp.float32, device=checker.device)
    ws = checker.workspace(n * robot.n_ellipsoids)
    out = {"numpy_q": time_query_robot(checker, robot, q, mv, repeats), "device_q_workspace": time_query_robot(checker, robot, qw, mv, repeats, out=ws)}
    impl = checker._impl  # benchmark only: the same grids with another lane count
    keep = impl.tiers
    try:
        for n_l in lanes:
            impl.tiers = replace(keep, lanes=n_l)
            out[f"lanes_{n_l}"] = time_query_robot(checker, robot, qw, mv, repeats, out=ws)
    finally:
        impl.tiers = keep
    out["lanes_default"] = impl.lanes
    return out


def bench_mppi_panda(
    n_steps: int, setup=None, seed: int = 0, quick: bool = False, time_stride: int | str = 1, stonehenge: bool = True, static_shortcut: bool = True,
    n_samples: int = 256, profile: bool = False, lanes_sweep: tuple[int, ...] = (), prune_margin: float | None = None, prune_chunks: int = 4,
) -> dict:
    """Panda MPPI over the tabletop; ``time_stride`` an integer or "auto" (see CollisionCost).

    ``profile``: also report the wall seconds per MPC step spent in each cost object (the rest is
    sampling, the B-spline, rollouts and the weights)."""
    from splatplan.planners import MPPI, CollisionCost, ControlEffortCost, GoalPoseCost, JointIntegrator, JointLimitCost, MPPIConfig
    from splatplan.planners.mppi import CostWeights
    from splatplan.planners.costs import fk_device
    from splatplan.planners.mppi import joint_speed_bound
    from splatplan.scenes.builtin.tabletop import TARGET_REGION
    from splatplan.scenes.filters import filter_floaters

    load = _load()
    robot, scene, checker = setup or panda_setup(seed=seed)
    target = 0.5 * (TARGET_REGION[0] + TARGET_REGION[1])
    cfg = MPPIConfig(n_samples=n_samples, horizon=32, n_knots=6, dt=0.05, n_iters=1, noise_sigma=0.4, temperature=0.05,
                     u_min=-1.0, u_max=1.0, seed=seed, prune_margin=prune_margin, prune_chunks=prune_chunks)  # fmt: skip
    dyn = JointIntegrator(robot)
    col = CollisionCost(checker, dyn, weight=1.0, hit_weight=10.0, s2_cap=CostWeights().collision_s2_cap, time_stride=time_stride,
                        speed_bound=joint_speed_bound(dyn, cfg.u_min, cfg.u_max), static_shortcut=static_shortcut)  # fmt: skip
    costs = [
        col,
        GoalPoseCost(robot, position=target, link="panda_hand_tcp" if "panda_hand_tcp" in robot.link_names else None, terminal_factor=4.0, device=fk_device(checker)),
        ControlEffortCost(0.01),
        JointLimitCost(robot, weight=100.0),
    ]
    mppi = MPPI(dyn, checker, cfg, costs=costs)
    spent = {type(c).__name__: 0.0 for c in costs}
    if profile:
        for c in costs:
            c.evaluate = _timed(c.evaluate, spent, type(c).__name__)
            if hasattr(c, "chunk_terms"):  # the pruned evaluation's collision queries
                c.chunk_terms = _timed(c.chunk_terms, spent, type(c).__name__)
    x = robot.q_default.copy()
    hand_idx = costs[1].link_index
    d0 = float(np.linalg.norm(robot.link_poses(x)[hand_idx, :3, 3] - target))
    mppi.step(x)  # warm-up (builds the metric grids)
    spent.update({k: 0.0 for k in spent})
    t0 = time.perf_counter()
    c0 = time.process_time()
    us, pruned = [], []
    for _ in range(n_steps):
        u, info = mppi.step(x)
        us.append(u)
        pruned.append(info.n_pruned)
        x = dyn.rollout(x, u[None, None, :], cfg.dt)[0, 0]
    dt = time.perf_counter() - t0
    cpu = time.process_time() - c0
    hand = robot.link_poses(x)[hand_idx, :3, 3]
    n_static = int(col.static.sum()) if col.static is not None else 0
    out = {
        "robot": f"panda, all {robot.n_ellipsoids} link ellipsoids (semi-axes {robot.min_semi_axis:.3f}..{robot.semi_axes.max():.3f} m)",
        "scene": f"tabletop ({len(scene):,} splats after the floater filter)",
        "K": cfg.n_samples, "T": cfg.horizon, "iters_per_step": cfg.n_iters, "steps": n_steps,
        "collision_time_stride": col.stride(cfg.dt, cfg.horizon), "time_stride_option": time_stride,
        "max_gap_m": col.max_gap_m, "step_motion_bound_m": col.step_motion(cfg.dt) if col.auto_stride else None,
        "static_ellipsoids_cached": n_static,
        "steps_per_s": n_steps / dt, "configs_per_s": n_steps * cfg.n_samples * cfg.horizon / dt, "cpu_s_per_step": cpu / n_steps,
        "final_hand_distance_m": float(np.linalg.norm(hand - target)), "start_hand_distance_m": d0, "load_avg_1min": load,
        "device": str(checker.device), "prune_margin": prune_margin, "prune_chunks": prune_chunks, "pruned_samples_per_step": float(np.mean(pruned)),
        "_controls": np.asarray(us),
    }  # fmt: skip
    if profile:
        out["_final_x"] = x.copy()  # for follow-up timings (gpu_rates pops it)
        out["cost_s_per_step"] = {k: v / n_steps for k, v in spent.items()}
        out["query_only_s"] = _query_only_s(robot, col.checker, col, x, cfg.n_samples * cfg.horizon, seed, lanes=lanes_sweep)
    if not stonehenge:
        return out
    # one collision query of the same batch size on the unit-size Stonehenge, for comparison
    from splatplan.metric import CollisionChecker
    from splatplan.scenes.builtin.stonehenge import build_stonehenge

    sraw, _ = build_stonehenge(level=1, seed=seed)
    sh, _ = filter_floaters(sraw)
    sc = CollisionChecker(sh, n_sigma=1.0).with_config(s2_cap=CostWeights().collision_s2_cap)
    n_cfg = 64 if quick else 512  # a slice of the (K, T) batch; the full batch's time is projected
    qb = np.clip(robot.q_default + np.random.default_rng(seed).normal(scale=0.2, size=(n_cfg, 7)), robot.joint_limits[:, 0], robot.joint_limits[:, 1])
    sc.query_robot(robot, qb[:4])
    ts = time.perf_counter()
    sc.query_robot(robot, qb)
    t_sh = (time.perf_counter() - ts) * cfg.n_samples * cfg.horizon / n_cfg
    return {**out, "stonehenge_query_s": t_sh, "stonehenge_splats": len(sh)}


#: MPPIConfig.prune_margin of the pruned Panda row: pruned samples weigh < exp(-40) = 4e-18 of the best
PRUNE_MARGIN = 40.0


def bench_panda_rows(quick: bool = False) -> dict:
    """Every Panda row: every step (static ellipsoids cached, and not), the auto stride, strides 2 and 4."""
    setup = panda_setup(n_splats=20_000 if quick else 200_000)
    n = 2 if quick else 12
    rows = {
        "mppi_panda": bench_mppi_panda(n, setup, quick=quick),
        "mppi_panda_pruned": bench_mppi_panda(n, setup, quick=quick, stonehenge=False, prune_margin=PRUNE_MARGIN),
        "mppi_panda_no_static_cache": bench_mppi_panda(n, setup, quick=quick, stonehenge=False, static_shortcut=False),
        "mppi_panda_auto_stride": bench_mppi_panda(n, setup, quick=quick, stonehenge=False, time_stride="auto"),
        "mppi_panda_time_stride_2": bench_mppi_panda(n, setup, quick=quick, stonehenge=False, time_stride=2),
        "mppi_panda_time_stride_4": bench_mppi_panda(n, setup, quick=quick, stonehenge=False, time_stride=4),
    }
    # same seed, same start: the pruned run's controls against the unpruned one's
    rows["mppi_panda_pruned"]["max_control_diff_vs_unpruned"] = float(np.abs(rows["mppi_panda_pruned"]["_controls"] - rows["mppi_panda"]["_controls"]).max())
    for r in rows.values():
        r.pop("_controls", None)
    return rows


def far_free_pairs(checker, robot_radius: float, n_pairs: int, rng: np.random.Generator, n_cand: int = 400) -> list[tuple[np.ndarray, np.ndarray]]:
    """Start/goal pairs of free points of the robust scene box, far apart (the farthest pair first,
    then random pairs at least half as far apart)."""
    from splatplan.planners import robust_scene_box

    lo, hi = robust_scene_box(checker.scene)
    cand = lo + rng.random((n_cand, 3)) * (hi - lo)
    free = cand[~checker.collides(cand, None, robot_radius)]
    d = np.linalg.norm(free[:, None] - free[None], axis=-1)
    i, j = np.unravel_index(np.argmax(d), d.shape)
    pairs = [(free[i], free[j])]
    ii, jj = np.nonzero(np.triu(d >= 0.5 * d.max(), 1))
    for k in rng.permutation(len(ii))[: max(0, n_pairs - 1)]:
        pairs.append((free[ii[k]], free[jj[k]]))
    return pairs


def bench_real(n_pairs: int, seed: int = 0, names: tuple[str, ...] | None = None) -> list[dict]:
    from splatplan.errors import SplatplanError
    from splatplan.metric import CollisionChecker
    from splatplan.planners import RRTConfig, plan
    from splatplan.scenes.load import load_scene

    rows = []
    for fname, name in REAL_SCENES:
        path = REAL / fname
        if not path.exists() or (names is not None and name not in names):
            continue
        try:
            scene = load_scene(path, filter_floaters=True)
        except SplatplanError as exc:
            rows.append({"scene": name, "file": fname, "error": str(exc)})
            continue
        checker = CollisionChecker(scene, n_sigma=1.0)
        rng = np.random.default_rng(seed)
        pairs = far_free_pairs(checker, RADIUS, n_pairs, rng)
        plan(checker, pairs[0][0], pairs[0][1], robot=ROBOT, refine=False, rrt_config=RRTConfig(time_limit_s=1.0))  # warm-up
        for k, (s, g) in enumerate(pairs):
            load = _load()
            res = plan(checker, s, g, robot=ROBOT, refine=False, seed=seed + k, rrt_config=RRTConfig())
            st = res.info["settings"]
            rows.append({
                "scene": name, "file": fname, "n_splats": len(scene), "robot": f"sphere r = {RADIUS}",
                "start": s.round(4).tolist(), "goal": g.round(4).tolist(), "distance": float(np.linalg.norm(g - s)),
                "success": bool(res.success), "time_s": res.time_s, "n_nodes": res.n_nodes, "length": res.length if res.success else None,
                "stride": st["stride"], "edge_resolution": st["edge_resolution"], "message": res.message, "load_avg_1min": load,
            })  # fmt: skip
    return rows


def _panda_lines(result: dict) -> list[str]:
    panda = result.get("mppi_panda")
    if panda is None:
        return []
    lines = [
        f"| MPPI Panda arm, K=256, T=32, 1 iter/step, {panda['scene']}, collision cost on every step (static link0 cached) | {panda['robot']} | {panda['steps_per_s']:.2f} MPC steps/s ({panda['configs_per_s']:,.0f} configurations/s) | >= 5 |",
    ]
    extra = (
        ("mppi_panda_pruned", lambda r: f"same, hopeless samples pruned (prune_margin = {r['prune_margin']:g}: weight < {np.exp(-r['prune_margin']):.0e} of the best; "
                                         f"{r['pruned_samples_per_step']:.0f} of {r['K']} samples per step; controls equal to {r['max_control_diff_vs_unpruned']:.0e})"),
        ("mppi_panda_no_static_cache", lambda r: "same, every ellipsoid queried on the whole batch (no static cache)"),
        ("mppi_panda_auto_stride", lambda r: f"same, collision_time_stride='auto' (max gap {r['max_gap_m']:.4f} m; a step moves a point <= {r['step_motion_bound_m']:.3f} m -> stride {r['collision_time_stride']})"),
        ("mppi_panda_time_stride_2", lambda r: "same, collision cost on every 2nd step (collision_time_stride=2)"),
        ("mppi_panda_time_stride_4", lambda r: "same, collision cost on every 4th step (collision_time_stride=4)"),
    )
    for key, label in extra:
        r = result.get(key)
        if r is not None and "steps_per_s" in r:
            lines.append(f"| {label(r)} | {r['robot']} | {r['steps_per_s']:.2f} MPC steps/s | >= 5 |")
    if "stonehenge_query_s" in panda:
        lines.append(f"| one Panda collision query, K=256 x T=32 (projected from a slice), Stonehenge ({panda['stonehenge_splats']:,} splats, 1 m across) | {panda['robot']} | {panda['stonehenge_query_s']:.1f} s | - |")
    return lines


def markdown(result: dict) -> str:
    """The markdown table of a (possibly merged) result JSON."""
    rrt, mppi, mppi_body = result["rrt"], result["mppi"], result["mppi_default_body"]
    lines = [
        "| benchmark | robot body | measured | target |",
        "|---|---|---|---|",
        f"| RRT centre -> border (Stonehenge), median time after warm-up | {rrt['robot']} | {rrt['time_median_s']:.3f} s (p90 {rrt['time_p90_s']:.3f} s) | <= 0.5 s |",
        f"| RRT success over {rrt['n_goals']} random free border goals | {rrt['robot']} | {100 * rrt['success_rate']:.0f}% | >= 95% |",
        f"| paths with a colliding splat at resolution r/2 | {rrt['robot']} | {rrt['paths_with_colliding_splats']} | 0 |",
        f"| smallest clearance to the exact geometry (SDF - r) | {rrt['robot']} | {rrt['min_clearance_exact']:.4f} | > 0 |",
        f"| MPPI planar base, K=256, T=30, 2 iters/step | {mppi['robot']} | {mppi['steps_per_s']:.1f} MPC steps/s | >= 20 |",
        f"| MPPI planar base: steps in collision / final distance to goal | {mppi['robot']} | {mppi['steps_in_collision']} / {mppi['final_distance_to_goal']:.3f} | 0 / - |",
        f"| MPPI planar base, K=256, T=30, 2 iters/step | {mppi_body['robot']} | {mppi_body['steps_per_s']:.1f} MPC steps/s | - |",
        *_panda_lines(result),
    ]
    for r in result.get("real", []):
        if "error" in r:
            lines.append(f"| plan on {r['scene']} ({r['file']}), defaults | sphere r = {RADIUS} | not loadable: {r['error'][:80]} | - |")
            continue
        res = f"{r['time_s']:.2f} s, {r['n_nodes']:,} nodes" + ("" if r["success"] else " (no path)")
        lines.append(f"| plan on {r['scene']} ({r['n_splats']:,} splats), defaults, start -> goal {r['distance']:.2f} apart (stride {r['stride']:.3g}) | {r['robot']} | {res} | <= 10 s |")
    loads = [rrt["load_avg_1min"], mppi["load_avg_1min"]]
    lines.append(f"\nLoad average (1 min) during the runs: {', '.join(f'{x:.1f}' for x in loads)} (RRT, MPPI base)"
                 + (f", {result['mppi_panda']['load_avg_1min']:.1f} (Panda)" if "mppi_panda" in result else "")
                 + f" on {result.get('cpu_threads', os.cpu_count())} CPU threads shared with other jobs.")  # fmt: skip
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--goals", type=int, default=50, help="RRT goals on Stonehenge")
    ap.add_argument("--quick", action="store_true", help="tiny sizes (smoke test): fewer MPPI steps, 1 real pair, smaller Panda scene")
    ap.add_argument("--only", choices=("all", "panda"), default="all", help="panda: rerun only the Panda MPPI rows and merge them into the existing JSON")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "planners.json"))
    args = ap.parse_args(argv)
    out = Path(args.out)

    if args.only == "panda":
        if not out.exists():
            raise SystemExit(f"--only panda merges into an existing {out}: run the whole benchmark first")
        result = json.loads(out.read_text())
        for key in [k for k in result if k.startswith("mppi_panda")]:
            del result[key]
        result.update(bench_panda_rows(quick=args.quick))
        result["cpu_threads"] = os.cpu_count()
    else:
        from splatplan.scenes.filters import filter_floaters
        from splatplan.scenes.builtin.stonehenge import build_stonehenge

        raw, gt = build_stonehenge(level=1, seed=0)
        scene, _ = filter_floaters(raw)
        steps = 5 if args.quick else 40
        rrt = bench_rrt(scene, gt, args.goals)
        mppi = bench_mppi_base(scene, "sphere", n_steps=steps)
        mppi_body = bench_mppi_base(scene, "body", n_steps=max(2, steps // 4))
        panda = bench_panda_rows(quick=args.quick)
        real = bench_real(1, names=("banana",)) if args.quick else bench_real(3)
        result = {"rrt": rrt, "mppi": mppi, "mppi_default_body": mppi_body, **panda, "real": real, "cpu_threads": os.cpu_count()}
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    md = markdown(result)
    (out.parent / "planners.md").write_text(md + "\n")
    print(md)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
