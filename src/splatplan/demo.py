"""`splatplan demo`: the main job on the built-in Stonehenge scene.

1. Build the scene (~200k splats, z up, normalised units, x, y in [-0.5, 0.5]), drop floaters.
2. Collision field: the CollisionSplatting metric for the sphere robot
   :data:`~splatplan.robots.DEFAULT_POINT_ROBOT` (r = 0.015) on the plane
   z = 0.06, at n_sigma 0, 1, 2 -> ``collision_field.png``.
3. Planning: batched RRT + zeroth-order refinement from the scene centre to a border goal at
   n_sigma 0, 1, 2 -> ``plans.png`` and a printed table (length, clearance, time).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

N_SIGMAS = (0.0, 1.0, 2.0)


def collision_field(checker, z: float, lo: np.ndarray, hi: np.ndarray, radius: float, res: int = 240):
    """min_s2 of a sphere of ``radius`` (scene units) on a (res x res) grid of the plane at height z.

    Returns:
        (xs (res,), ys (res,), min_s2 (res, res) indexed [iy, ix]).
    """
    xs = np.linspace(lo[0], hi[0], res)
    ys = np.linspace(lo[1], hi[1], res)
    gx, gy = np.meshgrid(xs, ys)
    pts = np.stack([gx, gy, np.full_like(gx, z)], axis=-1)  # (res, res, 3)
    return xs, ys, checker.query(pts, None, radius).min_s2


def _plot_field(path: Path, fields, gt, z: float, lo, hi, radius: float, n_kept_floaters: int = 0, floater_opacity: tuple[float, float] = (0.1, 0.3)) -> None:
    import matplotlib.pyplot as plt
    from matplotlib.layout_engine import ConstrainedLayoutEngine
    from matplotlib.lines import Line2D

    from .eval._plots import top_view_handles
    from .scenes.builtin.stonehenge import plot_top_view

    fig, axes = plt.subplots(1, len(fields), figsize=(5.2 * len(fields), 6.3), constrained_layout=True)
    for ax, (ns, (xs, ys, f)) in zip(np.atleast_1d(axes), fields.items()):
        im = ax.imshow(np.minimum(f, 4.0), origin="lower", extent=(xs[0], xs[-1], ys[0], ys[-1]), cmap="magma", vmin=0, vmax=4)
        ax.contour(xs, ys, f, levels=[1.0], colors="cyan", linewidths=0.8)
        plot_top_view(ax, gt, z, footprints=False)
        for p in ax.patches:
            p.set_alpha(0.25)
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_xlabel("x (scene units)")
        ax.set_ylabel("y (scene units)")
        ax.set_title(f"conservatism n_sigma = {ns:g}" + (" (splat centres only)" if ns == 0 else f" (splats grown by {ns:g} std)"))
    fig.colorbar(im, ax=axes, shrink=0.8, label="conservative scaling distance (min s2~), clipped at 4")
    handles = [
        Line2D([], [], color="cyan", lw=0.8, label="s2~ = 1: the sphere touches a splat (inside = collision)"),
        *top_view_handles(gt, z, footprints=False, alpha=0.25),
    ]
    fig.legend(handles=handles, loc="lower center", ncol=2, fontsize=7, frameon=False)
    floaters = (
        f"\nAt n_sigma = 2 the largest dark disks are the {n_kept_floaters} semi-transparent floaters "
        f"(opacity {floater_opacity[0]:.2f}-{floater_opacity[1]:.2f}) that the default filter keeps (it drops only splats that are both "
        "faint and large);\nthe smaller disks over open ground are long, thin ground splats whose 2-std inflation reaches the plane."
        if n_kept_floaters
        else ""
    )
    fig.suptitle(
        f"Where a sphere of radius r = {radius:g} collides in the plane z = {z} (top view, scene units, z up; dark = close to a splat)."
        + floaters,
        fontsize=9,
    )
    engine = fig.get_layout_engine()
    assert isinstance(engine, ConstrainedLayoutEngine)  # (constrained_layout=True above)
    engine.set(rect=(0, 0.08, 1, 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _plot_plans(path: Path, plans, gt, z: float, start, goal, radius: float) -> None:
    import matplotlib.pyplot as plt

    from .scenes.builtin.stonehenge import plot_top_view

    from matplotlib.lines import Line2D

    from .eval._plots import top_view_handles

    fig, ax = plt.subplots(figsize=(7.0, 8.4), constrained_layout=True)
    plot_top_view(ax, gt, z, inflate=radius)
    colors = {0.0: "tab:blue", 1.0: "tab:orange", 2.0: "tab:green"}
    for ns, res in plans.items():
        if res is None or not res.success:
            continue
        p = np.asarray(res.path)
        raw = np.asarray(res.path_shortcut)
        ax.plot(raw[:, 0], raw[:, 1], ":", color=colors.get(ns, "k"), lw=1.0)
        ax.plot(p[:, 0], p[:, 1], "-", color=colors.get(ns, "k"), lw=2.0, label=f"n_sigma={ns:g} (length {res.length:.3f})")
    ax.plot(*start[:2], "ko", ms=7, label="start")
    ax.plot(*goal[:2], "k*", ms=12, label="goal")
    ax.set_xlabel("x (scene units)")
    ax.set_ylabel("y (scene units)")
    handles, _ = ax.get_legend_handles_labels()
    handles += [Line2D([], [], color="0.3", ls=":", lw=1.0, label="RRT path before refinement\n(dotted, same colour)")]
    ax.legend(handles=handles, loc="lower right", fontsize=7)
    fig.legend(handles=top_view_handles(gt, z, inflate=radius), loc="outside lower center", ncol=2, fontsize=7, frameon=False)
    ax.set_title(f"Plans at three conservatism levels n_sigma, sphere r = {radius:g}, plane z = {z} (top view)", fontsize=9)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _free_border_goal(checkers, start: np.ndarray, robot_radius: float, radius: float = 0.47, first_angle: float = 0.6) -> np.ndarray:
    """A goal on the circle of ``radius`` (scanning counter-clockwise from ``first_angle``) that is
    collision-free for every checker (a sphere robot of ``robot_radius``), the one whose straight line from ``start`` is the most
    obstructed (so the planner has to find a way through or around the ring)."""
    ang = first_angle + np.linspace(0.0, 2 * np.pi, 360, endpoint=False)
    cand = np.stack([radius * np.cos(ang), radius * np.sin(ang), np.full_like(ang, start[2])], axis=1)  # (360, 3)
    free = np.ones(len(cand), dtype=bool)
    for c in checkers:
        free &= ~c.collides(cand, None, robot_radius)
    if not free.any():
        from .errors import PlanningError

        raise PlanningError("no collision-free goal on the scene border for every n_sigma of the demo")
    t = np.linspace(0.0, 1.0, 200)[None, :, None]
    lines = start + t * (cand[:, None, :] - start)  # (360, 200, 3) straight segments
    blocked = checkers[0].collides(lines, None, robot_radius).sum(axis=1)  # (360,) samples in collision
    return cand[int(np.argmax(np.where(free, blocked, -1)))]  # the most obstructed free goal


def run_demo(out_dir: Path, device: str = "auto", seed: int = 0) -> dict:
    """Run the demo, write the PNGs into ``out_dir`` and print a summary. Returns the summary."""
    from .metric import CollisionChecker
    from .planners import RRTConfig, plan
    from .planners.metrics import clearance, d_min, smoothness
    from .robots import DEFAULT_POINT_ROBOT, load_robot
    from .scenes.filters import filter_floaters
    from .scenes.builtin.stonehenge import PLANE_Z, build_stonehenge

    t0 = time.perf_counter()
    robot = load_robot(DEFAULT_POINT_ROBOT)
    r_robot = robot.min_semi_axis  # the sphere's radius (scene units)
    raw, gt = build_stonehenge(level=1, seed=seed)
    scene, rep = filter_floaters(raw)
    lo, hi = scene.bounds()
    print(f"stonehenge: {len(raw):,} splats, {rep.n_dropped} floaters dropped (o < {rep.opacity_below} and max std > {rep.scale_factor} x median); "
          f"bounds {np.round(lo, 3).tolist()} .. {np.round(hi, 3).tolist()} (scene units, z up)")  # fmt: skip

    base = CollisionChecker(scene, n_sigma=0.0, device=device)
    fields = {}
    for ns in N_SIGMAS:
        t = time.perf_counter()
        fields[ns] = collision_field(base.with_config(n_sigma=ns), PLANE_Z, lo, hi, r_robot)
        dt = time.perf_counter() - t
        frac = float((fields[ns][2] < 1.0).mean())
        print(f"  field n_sigma={ns:g}: {fields[ns][2].size:,} poses in {dt:.2f} s, {100 * frac:.1f}% of the plane in collision")
    # ground truth for the same grid: exact SDF < r
    xs, ys, _ = fields[N_SIGMAS[0]]
    gx, gy = np.meshgrid(xs, ys)
    sdf = gt.sdf(np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, PLANE_Z)], 1))
    print(f"  exact geometry: {100 * float((sdf < r_robot).mean()):.1f}% of the plane in collision (sdf < r)")
    out_dir = Path(out_dir)
    n_kept = int(raw.info.get("n_floaters", 0)) - int(rep.n_dropped)  # semi-transparent floaters the default filter keeps
    # the generator appends its floaters last and the filter keeps order
    o_kept = scene.opacities[len(scene) - n_kept :] if n_kept > 0 else np.zeros(1)
    _plot_field(out_dir / "collision_field.png", fields, gt, PLANE_Z, lo, hi, r_robot, n_kept_floaters=n_kept, floater_opacity=(float(o_kept.min()), float(o_kept.max())))

    # planning from the centre to a border goal on the plane, free at every n_sigma shown
    start = np.array([0.0, 0.0, PLANE_Z])
    goal = _free_border_goal([base.with_config(n_sigma=ns) for ns in N_SIGMAS], start, r_robot)
    rrt = RRTConfig(box_lo=(-0.5, -0.5, PLANE_Z), box_hi=(0.5, 0.5, PLANE_Z), time_limit_s=20.0)
    plans, rows = {}, []
    for ns in N_SIGMAS:
        res = plan(base.with_config(n_sigma=ns), start, goal, robot=robot, refine=True, seed=seed, rrt_config=rrt)
        plans[ns] = res
        if res.success:
            rows.append((ns, res.length_shortcut, res.length, d_min(res.path, scene.means),
                         clearance(res.path, gt.sdf, r_robot), smoothness(res.path), res.time_s, res.n_nodes))  # fmt: skip
        else:
            rows.append((ns, float("nan"), float("nan"), float("nan"), float("nan"), float("nan"), res.time_s, res.n_nodes))
    _plot_plans(out_dir / "plans.png", plans, gt, PLANE_Z, start, goal, r_robot)
    print(f"\nplans from {start.round(3).tolist()} to {goal.round(3).tolist()} (sphere r = {r_robot:g}):")
    print("| n_sigma | length RRT | length refined | d_min to splat means | clearance to exact geometry | smoothness | time (s) | nodes |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r[0]:g} | {r[1]:.4f} | {r[2]:.4f} | {r[3]:.4f} | {r[4]:.4f} | {r[5]:.5f} | {r[6]:.2f} | {r[7]} |")
    print(f"\nwrote {out_dir / 'collision_field.png'} and {out_dir / 'plans.png'} in {time.perf_counter() - t0:.1f} s")
    reach = run_reach_demo(out_dir, device=device)
    run_robot_demo(out_dir, device=device)
    return {"floaters_dropped": rep.n_dropped, "plans": rows, "reach": reach}


def run_reach_demo(out: Path, device: str = "auto") -> dict:
    """One short visual-reaching run (E5): the Panda's wrist camera reaches a goal image in the
    tabletop with MPPI, the terminal image cost (the E5 study's weight-free thumbnail pyramid, its
    ``--quick`` settings) and the collision cost -> ``demo_reach.png`` (target image, final image, wrist views, camera path). ~30 s on 2 cores."""
    from .eval.reach import plot_goal, quick_task_config
    from .render import SplatRenderer
    from .robots import load_robot
    from .tasks._common import load_task_scene
    from .planners.reach_goals import HIDDEN_GOAL_SAMPLER, make_reach_goals, reach_start
    from .render.cameras import wrist_camera
    from .tasks.reach import ReachConfig, reach_encoder, run_reach
    from ._warp import resolve_device

    t0 = time.perf_counter()
    dev = resolve_device(device)
    cfg = quick_task_config(ReachConfig())  # exactly the study's --quick run (its first goal, with the collision cost)
    robot = load_robot("panda")
    ts = load_task_scene("tabletop", n_sigma=cfg.n_sigma, device=dev, n_splats=cfg.n_splats)
    cam = wrist_camera(robot, cfg.image_size, cfg.fov_deg, cfg.camera_link)
    q0 = reach_start(robot, cfg.camera_link)
    with SplatRenderer(ts.splats, dev) as rend:
        goal = make_reach_goals(robot, ts, rend, cam, n=1, q_start=q0, n_behind=1, seed=cfg.mppi.seed, **HIDDEN_GOAL_SAMPLER)[0]  # the study's first goal
        target = np.asarray(cam.render(rend, robot, goal["q"][None], background=(cfg.background,) * 3).rgb[0])
        res = run_reach(robot, ts, target, config=cfg, q0=q0, encoder=reach_encoder("thumbnail", device=dev, config=cfg), goal_camera_pose=goal["camera_pose"], renderer=rend, device=dev)
    path = Path(out) / "demo_reach.png"
    plot_goal(path, robot, ts, goal, target, {"with_collision": res})
    print(f"\nvisual reaching ({goal['name']}, {res.encoder}, {cfg.image_size}x{cfg.image_size} renders, K = {cfg.mppi.n_samples}): camera error "
          f"{100 * res.translation_error_m:.1f} cm / {res.rotation_error_deg:.1f} deg, min clearance {100 * res.min_clearance_m:+.2f} cm (moving links {100 * res.extra['min_clearance_moving_links_m']:+.2f} cm), "
          f"{res.steps_per_s:.2f} MPC steps/s; wrote {path} in {time.perf_counter() - t0:.1f} s")
    return res.summary()


def run_robot_demo(out: Path, device: str = "auto") -> dict:
    """Two short MPPI runs with the collision cost over every robot ellipsoid:
    the Panda reaching into the bin behind the front wall of ``tabletop`` -> ``demo_arm.png``, and
    the Go2 walking from the living room of ``apartment`` to a kitchen goal behind the narrow
    (impassable) doorway, given only the goal, with its sensed-obstacle memory (line of sight,
    geodesic goal term: ``BaseConfig.memory``) -> ``demo_go2.png``. ~40-80 s on 2 cores."""
    from dataclasses import replace

    import matplotlib.pyplot as plt

    from ._warp import resolve_device
    from .robots import load_robot
    from .tasks._common import base_terrain, load_task_scene
    from .robots.ik import down_quat
    from .tasks.arm import ArmConfig, run_arm
    from .tasks.base import BaseConfig, load_go2, run_base
    from .tasks.plot import plot_run

    t0 = time.perf_counter()
    dev = resolve_device(device)
    out = Path(out)
    summary = {}
    # the arm task's own K = 64, T = 16 (with the tight default model, K = 48, T = 12 ended 4.6 cm
    # short after 45 steps; these reach the goal in ~33)
    acfg = ArmConfig(max_steps=60, collision_stride=3)
    panda = load_robot("panda")
    ts = load_task_scene("tabletop", n_sigma=acfg.n_sigma, device=dev)
    arm = run_arm(panda, ts, [0.64, 0.02, 0.0], down_quat(0.2), config=acfg, device=dev)
    fig = plot_run(panda, ts, arm, kind="arm", title="Panda reaching behind the wall")
    fig.savefig(out / "demo_arm.png", dpi=90)
    plt.close(fig)
    summary["arm"] = {k: getattr(arm, k) for k in ("success", "final_position_error_m", "min_clearance_m", "steps_per_s")}
    print(f"\narm (Panda, tabletop, K = {acfg.mppi.n_samples}, T = {acfg.mppi.horizon}): end-effector error {100 * arm.final_position_error_m:.1f} cm / "
          f"{arm.final_orientation_error_deg:.1f} deg, min clearance {100 * arm.min_clearance_m:+.2f} cm (exact; moving links {100 * arm.extra['min_clearance_moving_links_m']:+.2f} cm), {arm.steps_per_s:.2f} MPC steps/s")  # fmt: skip
    bcfg = replace(BaseConfig(), max_steps=150, memory=True)
    go2 = load_go2()
    tsb = load_task_scene("apartment", n_sigma=bcfg.n_sigma, device=dev, terrain=base_terrain(bcfg))
    base = run_base(go2, tsb, (2.09, -0.45), start=(-2.3, -0.6, 0.0), config=bcfg, device=dev)
    fig = plot_run(go2, tsb, base, kind="base", title="Go2 (goal only, memory)")
    fig.savefig(out / "demo_go2.png", dpi=90)
    plt.close(fig)
    summary["go2"] = {k: getattr(base, k) for k in ("success", "final_position_error_m", "min_clearance_m", "steps_per_s")}
    print(f"quadruped (Go2, apartment, K = {bcfg.mppi.n_samples}, T = {bcfg.mppi.horizon}): distance to goal {base.final_position_error_m:.2f} m, "
          f"min clearance {100 * base.min_clearance_m:+.1f} cm (exact), "
          + (f"time to goal {base.extra['time_to_goal_s']:.1f} s" if base.success else "goal not reached")
          + f", {base.steps_per_s:.2f} MPC steps/s")  # fmt: skip
    print(f"wrote {out / 'demo_arm.png'} and {out / 'demo_go2.png'} in {time.perf_counter() - t0:.1f} s")
    return summary
