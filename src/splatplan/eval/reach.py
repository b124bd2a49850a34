"""E5 visual reaching study (paper Table IV): the Panda's wrist camera reaches 5 goal images in the
``tabletop`` with MPPI and the terminal image cost, with and without the collision cost.

Goals (:func:`splatplan.planners.reach_goals.make_reach_goals` with
:data:`~splatplan.planners.reach_goals.HIDDEN_GOAL_SAMPLER`): random collision-free configurations near
the start (``start_view``: camera above the bin looking down, the default, or ``before_wall``: in front of
the bin just above its front wall), first those whose camera is hidden from the start camera by the exact
scene (the straight camera path runs through the bin's front wall: the paper's goals behind the box walls;
from ``above_bin`` they lie on the table in front of the wall), then some with the camera behind the bin's
front wall; the goal image is the wrist view there.
Per goal and run, ``touched``: the executed trajectory's clearance is <= 0 (the arm touched or cut the
geometry); ``initial plan``: with the collision cost, whether the task's goal search (an initial plan
without the path's collision cost, routed around the geometry, :attr:`~splatplan.tasks.reach.ReachConfig.goal_search`) was kept. Errors: final camera pose vs the goal camera pose.
Clearance: the smallest exact signed distance of any link ellipsoid to the analytic boxes over the
executed (densified) trajectory. Success: translation < ``position_tol`` (5 cm), rotation <
``orientation_tol_deg`` and clearance > 0.

``run(ReachStudyConfig()) -> ReachStudyResult``; ``report(result, out)`` writes ``reach.json``,
``reach.md`` (beside the paper's numbers) and ``reach_goal<i>.png``.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from .._config import bounded
from ..errors import SplatplanError
from ..robots.builtin import DEFAULT_MODEL, PANDA_MODELS
from ..tasks.reach import ReachConfig
from ._study import ImageGoalStudyConfig, StudyResult, write_outputs

#: Paper Table IV: config -> (clearance m, translation error m, rotation error deg).
PAPER = {"without_collision": (-0.021, 0.0147, 3.48), "with_collision": (0.017, 0.031, 5.69)}


def quick_task_config(cfg):
    """Smaller task settings for ``--quick`` (about 30 s a run on 2 quiet cores): the full run's controller
    (K = 32, T = 48, 8 knots, dt = 0.05 s) with a third of its initial-plan iterations and 32 px images.
    A shorter, coarser controller (K = 16, T = 24, 6 knots, dt = 0.1 s) ended 7 cm / 100 deg off the
    study's first goal, with or without the collision cost."""
    return replace(cfg, plan_iters=20, plan_start_iters=10, plan_start_refine=5, refine_plan_iters=10, image_size=32, n_views=4)


def goal_figure(robot, scene, goal, target, runs: dict):
    """The figure of one goal: target, final and intermediate wrist views of every run, and the
    camera paths from the side (a matplotlib Figure, no pyplot state)."""
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    n_views = max(len(r.views) for r in runs.values())
    fig = Figure(figsize=(2.0 * (n_views + 2), 2.3 * len(runs) + 3.2), constrained_layout=True)
    gs = fig.add_gridspec(len(runs) + 1, n_views + 2)
    for row, (name, r) in enumerate(runs.items()):
        ax = fig.add_subplot(gs[row, 0])
        ax.imshow(np.clip(target, 0, 1))
        ax.set_title("target", fontsize=8)
        ax = fig.add_subplot(gs[row, 1])
        ax.imshow(np.clip(r.final_image, 0, 1))
        ax.set_title(f"final ({name.replace('_', ' ')})\n{100 * r.translation_error_m:.1f} cm, {r.rotation_error_deg:.1f} deg", fontsize=7)
        for j, (s, v) in enumerate(r.views):
            ax = fig.add_subplot(gs[row, 2 + j])
            ax.imshow(np.clip(v, 0, 1))
            ax.set_title(f"step {s}", fontsize=7)
    for ax in fig.axes:
        ax.set_xticks([])
        ax.set_yticks([])
    ax = fig.add_subplot(gs[len(runs), :])
    gt = scene.analytic
    for box, lab in zip(gt.boxes, gt.labels):
        c, h = box[:3], box[3:6]
        if lab in ("table", "table_leg"):
            continue
        ax.add_patch(Rectangle((c[0] - h[0], c[2] - h[2]), 2 * h[0], 2 * h[2], color="0.7" if not lab.startswith("object") else "tab:red", alpha=0.5))
    ax.axhline(-0.09, color="saddlebrown", lw=1)
    colors = {"with_collision": "tab:green", "without_collision": "tab:red"}
    for name, r in runs.items():
        tr = r.camera_trace
        ax.plot(tr[:, 0], tr[:, 2], "-", color=colors.get(name, "k"), label=f"{name.replace('_', ' ')} (clearance {100 * r.min_clearance_m:+.1f} cm, moving links {100 * r.extra['min_clearance_moving_links_m']:+.1f} cm)")
    ax.plot(*goal["camera_pose"][[0, 2], 3], "k*", ms=10, label="goal camera")
    ax.plot(*next(iter(runs.values())).camera_trace[0, [0, 2]], "ko", ms=5, label="start camera")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("z (m)")
    ax.set_aspect("equal")
    ax.set_xlim(0.0, 1.0)
    ax.set_ylim(-0.12, 0.5)
    ax.legend(fontsize=7, loc="upper right")
    ax.set_title("wrist-camera path, side view (x-z; grey = walls and shelf, red = objects, brown = table top)", fontsize=8)
    fig.suptitle(f"Visual reaching, {goal['name']}: wrist views along the run", fontsize=9)
    return fig


def plot_goal(path: Path, robot, scene, goal, target, runs: dict) -> None:
    """Write :func:`goal_figure` to ``path`` (PNG, 100 dpi)."""
    goal_figure(robot, scene, goal, target, runs).savefig(path, dpi=100)


def _row(config: str, runs: list) -> dict:
    def ms(v):
        v = np.asarray(v, np.float64)
        return [round(float(v.mean()), 5), round(float(v.std()), 5)] if len(v) else [None, None]

    return {
        "config": config,
        "clearance_m": ms([r.min_clearance_m for r in runs]),
        "clearance_moving_links_m": ms([r.extra["min_clearance_moving_links_m"] for r in runs]),
        "translation_error_m": ms([r.translation_error_m for r in runs]),
        "rotation_error_deg": ms([r.rotation_error_deg for r in runs]),
        "successes": int(sum(r.success for r in runs)),
        "trials": len(runs),
        "collisions": int(sum(r.min_clearance_m <= 0 for r in runs)),  # runs that touched the geometry
        "mpc_steps_per_s": round(float(np.mean([r.steps_per_s for r in runs])), 4) if runs else None,
        "mppi_iterations_per_s": round(float(np.mean([r.iterations_per_s for r in runs])), 4) if runs else None,
    }


def markdown(result: dict) -> str:
    lines = [
        f"Visual reaching (E5), encoder `{result['encoder']}`, {result['n_goals']} goals, images {result['config']['image_size']}x{result['config']['image_size']}, "
        f"K = {result['config']['mppi']['n_samples']}, T = {result['config']['mppi']['horizon']}{' (--quick)' if result['quick'] else ''}",
        "",
        "| config | clearance (m) | clearance, moving links (m) | translation error (m) | rotation error (deg) | successes | touched the geometry | paper clearance | paper error (m) | paper error (deg) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in result["rows"]:
        p = PAPER[r["config"]]
        f = lambda v, d: "n/a" if v[0] is None else f"{v[0]:+.{d}f} +- {v[1]:.{d}f}"  # noqa: E731
        lines.append(f"| {r['config'].replace('_', ' ')} | {f(r['clearance_m'], 3)} | {f(r.get('clearance_moving_links_m', [None, None]), 3)} | {f(r['translation_error_m'], 4)} | {f(r['rotation_error_deg'], 2)} | "
                     f"{r['successes']}/{r['trials']} | {r.get('collisions', 'n/a')}/{r['trials']} | {p[0]:+.3f} | {p[1]:.4f} | {p[2]:.2f} |")  # fmt: skip
    lines += ["", f"MPC rate on this machine: {result['rows'][0]['mpc_steps_per_s']} MPC steps/s, {result['rows'][0]['mppi_iterations_per_s']} MPPI iterations/s "
              f"(one batched render of K images per iteration, device {result['device']}).",
              "", f"Encoder: {result.get('encoder_description', '')}. The controller sees the goal image only (no goal pose); "
              "the without-collision row uses no collision information at all (no collision cost, no start check)."]  # fmt: skip
    if result.get("goals"):
        lines += ["", "Per goal (hidden: the goal camera is hidden from the start camera by the exact scene, the straight camera path runs through "
                  "the geometry; touched: the run's clearance <= 0):", "", goal_table(result)]  # fmt: skip
    return "\n".join(lines) + "\n"


def goal_table(data: dict) -> str:
    """Per goal and run: where the goal is, success, errors, clearances and whether the arm touched the geometry (markdown)."""
    lines = ["| goal | camera (m) | hidden from start | line of sight (m) | run | initial plan | success | translation error (m) | rotation error (deg) | clearance (m) | clearance, moving links (m) | touched |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for g in data["goals"]:
        los = g.get("line_of_sight_m")
        for name, r in g["runs"].items():
            lines.append(f"| {g['name']} | {', '.join(f'{v:.3f}' for v in g['camera_position'])} | {g.get('occluded', 'n/a')} | {'n/a' if los is None else f'{los:+.3f}'} | "
                         f"{name.replace('_', ' ')} | {initial_plan(r)} | {r['success']} | {r['translation_error_m']:.4f} | {r['rotation_error_deg']:.2f} | {r['min_clearance_m']:+.4f} | "
                         f"{r['min_clearance_moving_links_m']:+.4f} | {r['min_clearance_m'] <= 0} |")  # fmt: skip
    return "\n".join(lines) + "\n"


def initial_plan(run: dict) -> str:
    """Which initial plan a run kept (its summary): the goal search (and its route), the collision-aware plan, or the plain one."""
    if run.get("kept_goal_search"):
        return f"goal search ({run.get('route', 'n/a')})"
    return "collision-aware" if run.get("collision_cost") else "plain"


@dataclass
class ReachStudyConfig(ImageGoalStudyConfig):
    """Knobs of study E5 (defaults = the full run; :meth:`quick_config` = the smoke version)."""

    #: goal images (reachable, collision-free configurations near the start)
    n_goals: int = bounded(5, ge=1)
    #: the reach task's settings
    task: ReachConfig = field(default_factory=ReachConfig)
    #: the built-in Panda's collision model (tight: certified, several ellipsoids per link; coarse: one per link)
    robot_model: str = bounded(DEFAULT_MODEL, choices=tuple(PANDA_MODELS))
    #: the start view (planners.reach_goals.START_VIEWS): above_bin (goals on the table in front of the bin are
    #: hidden behind its front wall) or before_wall (goals inside the bin are)
    start_view: str = bounded("above_bin", choices=("above_bin", "before_wall"))

    @classmethod
    def quick_config(cls) -> "ReachStudyConfig":
        """1 goal, the full controller with fewer initial-plan iterations, 32 px images (about 1 min on 2 quiet cores)."""
        return cls(n_goals=1, task=quick_task_config(ReachConfig()), quick=True)


@dataclass
class ReachStudyResult(StudyResult):
    """What E5 measured: ``data`` is ``reach.json``; ``figures`` feed the per-goal PNGs."""

    #: figure only: per goal (robot, task scene, goal, target image, {config: ReachResult})
    figures: list = field(default_factory=list, repr=False)


def run(config: ReachStudyConfig | None = None, engine=None, *, progress: bool = False) -> ReachStudyResult:
    """Run study E5 (module docstring); writes nothing (see :func:`report`). ``engine`` is accepted
    for the study convention; the runs are serial (one renderer)."""
    from ..render import SplatRenderer
    from ..robots import load_robot
    from ..tasks._common import load_task_scene
    from ..planners.reach_goals import HIDDEN_GOAL_SAMPLER, make_reach_goals, reach_start
    from ..render.cameras import wrist_camera
    from ..tasks.reach import reach_encoder, run_reach

    c = (config or ReachStudyConfig()).validate()
    cfg, device, n_goals = c.task, c.device, c.n_goals
    t0 = time.perf_counter()
    robot = load_robot("panda", model=c.robot_model)
    ts = load_task_scene("tabletop", n_sigma=cfg.n_sigma, device=device, n_splats=cfg.n_splats)
    enc = reach_encoder(c.encoder, c.encoder_weights, device, cfg)
    cam = wrist_camera(robot, cfg.image_size, cfg.fov_deg, cfg.camera_link)
    q0 = reach_start(robot, cfg.camera_link, c.start_view)
    bg = (cfg.background,) * 3
    runs: dict[str, list] = {"with_collision": [], "without_collision": []}
    goals_json, figures = [], []
    with SplatRenderer(ts.splats, device) as rend:
        goals = make_reach_goals(robot, ts, rend, cam, n=n_goals, q_start=q0, n_behind=min(2, n_goals), seed=cfg.mppi.seed, **HIDDEN_GOAL_SAMPLER)
        if len(goals) < n_goals:
            raise SplatplanError(f"found only {len(goals)} of {n_goals} goal configurations (reachable, collision-free, a full and textured wrist view "
                                 f"within reach of the start): ask for fewer goals or change the seed")  # fmt: skip
        for g in goals:
            target = np.asarray(cam.render(rend, robot, g["q"][None], background=bg).rgb[0])
            per = {}
            for name in runs:
                r = run_reach(robot, ts, target, config=cfg, collision=name == "with_collision", q0=q0, encoder=enc, goal_camera_pose=g["camera_pose"], renderer=rend, device=device)
                runs[name].append(r)
                per[name] = r
                if progress:
                    print(f"  {g['name']} {name}: {100 * r.translation_error_m:.1f} cm, {r.rotation_error_deg:.1f} deg, clearance {100 * r.min_clearance_m:+.2f} cm (moving links {100 * r.extra['min_clearance_moving_links_m']:+.2f} cm), {r.time_s:.0f} s")
            figures.append((robot, ts, g, target, per))
            goals_json.append({"name": g["name"], "q": g["q"].round(5).tolist(), "camera_position": g["camera_pose"][:3, 3].round(4).tolist(),
                               "behind_wall": g["behind_wall"], "occluded": g["occluded"], "line_of_sight_m": round(g["line_of_sight_m"], 4),
                               "goal_clearance_m": round(g["clearance_m"], 4),
                               "runs": {k: {**v.summary(), "touched": bool(v.min_clearance_m <= 0)} for k, v in per.items()}})  # fmt: skip
    data = {
        "encoder": enc.name,
        "encoder_description": getattr(enc, "description", ""),
        "rows": [_row(k, v) for k, v in runs.items()],
        "paper": {k: {"clearance_m": v[0], "translation_error_m": v[1], "rotation_error_deg": v[2]} for k, v in PAPER.items()},
        "n_goals": len(goals),
        "quick": bool(c.quick),
        "device": device,
        "robot_model": c.robot_model,
        "start_view": c.start_view,
        "n_ellipsoids": robot.n_ellipsoids,
        "start_q": q0.round(5).tolist(),
        "config": asdict(cfg),
        "goals": goals_json,
        "success_rule": f"translation < {cfg.position_tol} m, rotation < {cfg.orientation_tol_deg} deg, exact clearance > 0",
        "clearance_note": "smallest exact signed distance of any link ellipsoid to the tabletop's analytic boxes over the densified executed trajectory (negative = penetration); "
                          "clearance_moving_links_m: the same without the fixed link0, which stands 2.2 cm above the table in every run",
        "time_s": round(time.perf_counter() - t0, 1),
    }
    return ReachStudyResult(data, figures)


def report(result: ReachStudyResult, out_dir) -> list[Path]:
    """Write ``reach.json``, ``reach.md`` and ``reach_goal<i>.png`` into ``out_dir`` (an existing folder)."""
    figures = ((f"reach_goal{gi}.png", goal_figure(*fig_args), 100) for gi, fig_args in enumerate(result.figures))
    return write_outputs(out_dir, "reach", result.to_json(), markdown(result.to_json()), figures, indent=1)
