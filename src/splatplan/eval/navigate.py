"""E6 image-goal navigation study: the Go2 in the ``apartment`` explores with an exploration-mode RRT,
renders and encodes every node's view at several headings, retrieves the node that best matches
each of 10 target images, and drives there with base MPPI and the collision cost.

Targets: one held-out pose near each of 10 distinct objects / furniture pieces (0.5-1.0 m beyond
the piece's half diagonal, facing it within +-15 deg, at a random yaw, never a rendered heading),
collision-free with a 5 cm exact margin, at least 5 cm from every tree node (never a node's own
view) and within 0.4 m of one (inside the explored free space: a place the exploration never
reached cannot be retrieved; with the default settings the tree covers the living room and the
bedroom, the kitchen's doorways being too narrow for the Go2 at yaw 0 / the metric's margin). Per trial: retrieval error (m) = distance from the
retrieved node to the target position, yaw error (deg) of the retrieved heading, whether the drive
reached the node (within ``goal_tol_m``) and the smallest exact clearance of any Go2 ellipsoid to
the analytic geometry (floor excluded, see :mod:`splatplan.tasks.navigate`) over the executed path.

``run(NavigateStudyConfig()) -> NavigateStudyResult``; ``report(result, out)`` writes
``navigate.json``, ``navigate.md``, ``navigate_tree.png`` and ``navigate_trial<i>.png``.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._config import bounded
from .._files import atomic_path
from ..tasks.navigate import NavigateConfig
from ._study import ImageGoalStudyConfig, StudyResult, write_outputs

if TYPE_CHECKING:
    from ..robots.robot import Robot

#: Target landmarks (box labels of the apartment; "table" = the coffee table, the first table box),
#: in order of preference: the first 10 with a valid held-out pose are used.
LANDMARKS = (
    "object_green_plant", "object_yellow_box", "object_orange_ball", "object_cyan_chest", "object_magenta_box",
    "bed", "wardrobe", "shelf", "sofa", "table", "object_red_bin", "object_lime_stool", "object_blue_crate", "fridge", "counter",
)  # fmt: skip
#: Retrieval success radius (m).
RETRIEVAL_RADIUS_M = 0.5


def quick_task_config(cfg):
    """Smaller task settings for ``--quick`` (< 1 min on 2 busy cores): a smaller tree, 32 px views,
    index nodes 0.2 m apart; the full run's 24 headings (at 12, or nodes 0.3 m apart, a target
    between two index views is retrieved about 0.5 m off)."""
    return replace(cfg, tree_nodes=500, index_spacing_m=0.2, n_headings=24, image_size=32, max_steps=150)


def target_poses(robot: Robot, nav, nodes: np.ndarray, labels=LANDMARKS, n: int = 10, seed: int = 0, margin_m: float = 0.05, min_node_dist_m: float = 0.05, max_node_dist_m: float = 0.4) -> list[dict]:
    """One free held-out pose (x, y, yaw) near each landmark (see the module docstring)."""
    rng = np.random.default_rng(seed)
    gt = nav.task.analytic
    out: list[dict] = []
    for lab in labels:
        if len(out) >= n:
            break
        idx = [i for i, l in enumerate(gt.labels) if l == lab]
        if not idx:
            continue
        c = gt.boxes[idx[0], :2]
        half = float(np.linalg.norm(gt.boxes[idx[0], 3:5]))
        ang = rng.uniform(-np.pi, np.pi, 96)
        d = half + rng.uniform(0.5, 1.0, 96)
        p = c + np.stack([np.cos(ang), np.sin(ang)], 1) * d[:, None]
        yaw = np.arctan2(c[1] - p[:, 1], c[0] - p[:, 0]) + rng.uniform(-np.radians(15), np.radians(15), 96)
        q = np.concatenate([p, yaw[:, None]], 1)
        ok = np.all(np.abs(p) < [3.8, 2.8], axis=1)
        dn = np.min(np.linalg.norm(p[:, None] - nodes[None, :, :2], axis=-1), axis=1)
        ok &= (dn > min_node_dist_m) & (dn < max_node_dist_m)
        if not ok.any():
            continue
        q = q[ok]
        cc, qu, ax = robot.ellipsoids(q)
        clear = gt.ellipsoid_clearance(cc, qu, ax).min(axis=-1)
        free = (clear > margin_m) & ~np.asarray(nav.task.checker.collides_robot(robot, q)).any(axis=-1)
        if not free.any():
            continue
        i = int(np.flatnonzero(free)[0])
        out.append({"landmark": lab, "pose": q[i], "clearance_m": float(clear[i])})
    return out


def plot_top(ax, gt, tree=None, alpha_tree: float = 0.35) -> None:
    """Top view of the apartment boxes (floor omitted) and optionally the tree's edges."""
    from matplotlib.patches import Rectangle
    from matplotlib.transforms import Affine2D

    from ..scenes.splats import quat_to_rotmat

    for box, lab in zip(gt.boxes, gt.labels):
        if lab == "floor":
            continue
        c, h, q = box[:3], box[3:6], box[6:10]
        yaw = float(np.arctan2(quat_to_rotmat(q)[1, 0], quat_to_rotmat(q)[0, 0]))
        color = "0.35" if lab == "wall" else ("tab:purple" if lab.startswith("object") else "tan")
        rect = Rectangle((-h[0], -h[1]), 2 * h[0], 2 * h[1], color=color, alpha=0.7, lw=0)
        rect.set_transform(Affine2D().rotate(yaw).translate(c[0], c[1]) + ax.transData)
        ax.add_patch(rect)
    if tree is not None:
        nodes, parents = tree
        for i, p in enumerate(parents):
            if p >= 0:
                ax.plot([nodes[p, 0], nodes[i, 0]], [nodes[p, 1], nodes[i, 1]], "-", color="tab:blue", lw=0.5, alpha=alpha_tree)
        ax.plot(nodes[:, 0], nodes[:, 1], ".", color="tab:blue", ms=2, alpha=alpha_tree)
    ax.set_xlim(-4.2, 4.2)
    ax.set_ylim(-3.2, 3.2)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")


def _arrow(ax, pose, color, label=None) -> None:
    ax.arrow(pose[0], pose[1], 0.35 * np.cos(pose[2]), 0.35 * np.sin(pose[2]), width=0.03, color=color, length_includes_head=True, label=label)


def trial_figure(gt, tree, target_img, match_img, target_pose, match, drive, title: str):
    """One trial: target image, retrieved view, top view with the tree, the target and the drive (a matplotlib Figure)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 4.6), constrained_layout=True)
    gs = fig.add_gridspec(1, 3, width_ratios=[1, 1, 2.2])
    ax = fig.add_subplot(gs[0])
    ax.imshow(np.clip(target_img, 0, 1))
    ax.set_title("target image", fontsize=8)
    ax.axis("off")
    ax = fig.add_subplot(gs[1])
    ax.imshow(np.clip(match_img, 0, 1))
    ax.set_title(f"retrieved view (node {match.node})\ncost {match.cost:.3f}, {match.ratio:.2f} x median" + (" WEAK" if match.weak else ""), fontsize=8)
    ax.axis("off")
    ax = fig.add_subplot(gs[2])
    plot_top(ax, gt, tree)
    if drive is not None:
        s = drive.states
        ax.plot(s[:, 0], s[:, 1], "-", color="tab:green", lw=2, label=f"executed path (clearance {100 * drive.min_clearance_m:.1f} cm)")
    if target_pose is not None:
        _arrow(ax, target_pose, "tab:red", "target pose")
    _arrow(ax, match.pose, "tab:orange", "retrieved node + heading")
    ax.legend(fontsize=7, loc="lower left")
    ax.set_title(title, fontsize=8)
    return fig


def plot_trial(path: Path, gt, tree, target_img, match_img, target_pose, match, drive, title: str) -> None:
    """Write :func:`trial_figure` to ``path`` atomically (PNG, 100 dpi)."""
    _save(trial_figure(gt, tree, target_img, match_img, target_pose, match, drive, title), path)


def _save(fig, path: Path) -> Path:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    return Path(path)


def tree_figure(gt, tree, start, targets=()):
    """The exploration tree, the start and the held-out targets, top view (a matplotlib Figure)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 7), constrained_layout=True)
    ax = fig.subplots()
    plot_top(ax, gt, tree, alpha_tree=0.8)
    ax.plot(start[0], start[1], "ko", ms=7, label="start / tree root")
    for i, t in enumerate(targets):
        _arrow(ax, t["pose"], "tab:red", "held-out target poses" if i == 0 else None)
        ax.annotate(t["landmark"].replace("object_", ""), t["pose"][:2], fontsize=6)
    ax.legend(fontsize=7, loc="lower left")
    ax.set_title(f"exploration tree: {len(tree[0])} collision-free nodes (walls grey, furniture tan, objects purple)", fontsize=9)
    return fig


def plot_tree(path: Path, gt, tree, start, targets=()) -> None:
    """Write :func:`tree_figure` to ``path`` atomically (PNG, 100 dpi)."""
    _save(tree_figure(gt, tree, start, targets), path)


def markdown(result: dict) -> str:
    lines = [
        f"Image-goal navigation (E6), encoder `{result['encoder']}`, {result['n_nodes']} tree nodes x {result['config']['n_headings']} headings"
        f"{' (--quick)' if result['quick'] else ''}",
        "",
        "| trial | landmark | retrieval error (m) | yaw error (deg) | weak match | reached | min clearance (m) |",
        "|---|---|---|---|---|---|---|",
    ]
    for i, t in enumerate(result["trials"]):
        lines.append(f"| {i} | {t['landmark']} | {t['retrieval_error_m']:.3f} | {t['retrieval_yaw_error_deg']:.1f} | {t['weak']} | {t['reached']} | {t['min_clearance_m']:+.3f} |")
    lines += ["", f"Retrieved node within {RETRIEVAL_RADIUS_M} m: {result['retrieval_rate']:.0%}; success (within {RETRIEVAL_RADIUS_M} m, reached, "
              f"clearance > 0): {result['success_rate']:.0%}; every executed path collision-free: {result['all_paths_collision_free']}."]  # fmt: skip
    return "\n".join(lines) + "\n"


@dataclass
class NavigateStudyConfig(ImageGoalStudyConfig):
    """Knobs of study E6 (defaults = the full run; :meth:`quick_config` = the smoke version)."""

    #: held-out targets (one per landmark of LANDMARKS with a valid pose, in order)
    n_targets: int = bounded(10, ge=1)
    #: the navigation task's settings (tree, view index, drive)
    task: NavigateConfig = field(default_factory=NavigateConfig)

    @classmethod
    def quick_config(cls) -> "NavigateStudyConfig":
        """5 targets, a 500-node tree, 24 headings, 32 px views (< 1 min on 2 busy cores)."""
        return cls(n_targets=5, task=quick_task_config(NavigateConfig()), quick=True)


@dataclass
class NavigateStudyResult(StudyResult):
    """What E6 measured: ``data`` is ``navigate.json``; the rest feeds the figures."""

    #: figure only: (analytic scene, (nodes, parents), start, targets)
    tree: tuple = field(default=(), repr=False)
    #: figure only: per trial, the arguments of :func:`trial_figure`
    trials: list = field(default_factory=list, repr=False)


def _trial(t: dict, m, err: float, yerr: float, drive) -> dict:
    """The JSON record of one trial."""
    return {
        "landmark": t["landmark"], "target_pose": t["pose"].round(4).tolist(), "retrieved_pose": m.pose.round(4).tolist(),
        "retrieval_error_m": round(err, 4), "retrieval_yaw_error_deg": round(yerr, 2), "match_cost": round(m.cost, 5),
        "match_ratio": round(m.ratio, 4), "weak": m.weak, "reached": drive.reached, "final_distance_m": round(drive.final_distance_m, 4),
        "min_clearance_m": round(drive.min_clearance_m, 5), "drive_steps": drive.steps, "drive_time_s": round(drive.time_s, 2),
    }  # fmt: skip


def run(config: NavigateStudyConfig | None = None, engine=None, *, progress: bool = False) -> NavigateStudyResult:
    """Run study E6 (module docstring); writes nothing (see :func:`report`). ``engine`` is accepted
    for the study convention; the trials are serial (one renderer)."""
    from ..encoders import load_encoder
    from ..render import SplatRenderer
    from ..encoders.view_index import retrieve
    from ..planners.route import tree_branch, wrap_angle
    from ..tasks.navigate import build_view_index, drive_to, explore, head_camera, load_nav_scene, nav_robot

    c = (config or NavigateStudyConfig()).validate()
    cfg, device = c.task, c.device
    t0 = time.perf_counter()
    robot = nav_robot()
    nav = load_nav_scene("apartment", cfg, device=device, seed=cfg.seed)
    enc = load_encoder(c.encoder, weights=c.encoder_weights, device=device)
    tree = explore(robot, nav, cfg)
    nodes, parents = tree.tree_nodes, tree.tree_parents
    t_tree = time.perf_counter() - t0
    targets = target_poses(robot, nav, nodes, n=c.n_targets, seed=cfg.seed)
    cam = head_camera(robot, cfg)
    bg = (cfg.background,) * 3
    trials, figs = [], []
    with SplatRenderer(nav.render_splats, device) as rend:
        index = build_view_index(robot, nav, nodes, enc, rend, cfg)
        for i, t in enumerate(targets):
            img = np.asarray(cam.render(rend, robot, t["pose"][None], background=bg).rgb[0])
            m = retrieve(index, img, cfg.weak_ratio)
            err = float(np.linalg.norm(m.pose[:2] - t["pose"][:2]))
            yerr = float(np.degrees(abs(wrap_angle(m.pose[2] - t["pose"][2]))))
            drive = drive_to(robot, nav, m.pose[:2], cfg, branch=tree_branch(nodes, parents, m.node))
            match_img = np.asarray(cam.render(rend, robot, m.pose[None], background=bg).rgb[0])
            figs.append((nav.task.analytic, (nodes, parents), img, match_img, t["pose"], m, drive,
                         f"trial {i}: target near {t['landmark']}; retrieval error {err:.2f} m, reached {drive.reached}"))  # fmt: skip
            trials.append(_trial(t, m, err, yerr, drive))
            if progress:
                print(f"  trial {i} ({t['landmark']}): retrieval {err:.2f} m / {yerr:.0f} deg, reached {drive.reached}, clearance {100 * drive.min_clearance_m:.1f} cm")
    n = max(len(trials), 1)
    ok = [t["retrieval_error_m"] < RETRIEVAL_RADIUS_M and t["reached"] and t["min_clearance_m"] > 0 for t in trials]
    data = {
        "encoder": enc.name,
        "trials": trials,
        "success_rate": sum(ok) / n,
        "retrieval_rate": sum(t["retrieval_error_m"] < RETRIEVAL_RADIUS_M for t in trials) / n,
        "all_paths_collision_free": all(t["min_clearance_m"] > 0 for t in trials),
        "success_rule": f"retrieved node within {RETRIEVAL_RADIUS_M} m of the target position, drive reached it, exact clearance > 0",
        "n_nodes": int(len(nodes)),
        "n_views": int(len(index.poses)),
        "tree_time_s": round(t_tree, 2),
        "index_render_s": round(index.render_s, 2),
        "index_encode_s": round(index.encode_s, 2),
        "quick": bool(c.quick),
        "device": device,
        "config": asdict(cfg),
        "clearance_note": "smallest exact signed distance of any Go2 ellipsoid (feet lifted 4 cm) to the apartment's analytic boxes without the floor, over the densified executed path",
        "time_s": round(time.perf_counter() - t0, 1),
    }
    return NavigateStudyResult(data, (nav.task.analytic, (nodes, parents), cfg.start, targets), figs)


def report(result: NavigateStudyResult, out_dir) -> list[Path]:
    """Write ``navigate.json``, ``navigate.md``, ``navigate_tree.png`` and ``navigate_trial<i>.png``
    into ``out_dir`` (an existing folder); returns their paths."""
    figures = [("navigate_tree.png", tree_figure(*result.tree), 100)]
    figures += ((f"navigate_trial{i}.png", trial_figure(*args), 100) for i, args in enumerate(result.trials))
    return write_outputs(out_dir, "navigate", result.to_json(), markdown(result.to_json()), figures, indent=1)
