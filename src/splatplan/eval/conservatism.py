"""Study E3 (paper Table II, Fig. 4): planning conservatism versus n_sigma.

Protocol (SPEC section 4, E3): on the built-in Stonehenge (level 1, floaters filtered as the paper
does), a sphere robot of radius 0.015 plans in the plane z = 0.06 from the scene centre to random
goals on the scene border with the batched RRT (32 nodes per iteration, stride 0.03, edges
checked every r/4 with the sphere grown by half that spacing (the planner's default for a sphere
robot); no shortcut, see SHORTCUT), then the zeroth-order refinement (one MPPI update over the whole path). For n_sigma in 0, 0.25, ..., 2 we
report path length, d_min (closest distance from the densely resampled path to a splat mean) and
smoothness (:func:`splatplan.planners.metrics.smoothness`), before ("rrt" = the raw RRT path)
and after refinement, as mean and standard deviation over the successful trials. The same goals
(all collision-free at the most conservative n_sigma) are used for every n_sigma.

Every knob is a field of :class:`ConservatismConfig` (``splatplan eval conservatism --help``).

:func:`run` plans the trials (``run(ConservatismConfig(...)) -> ConservatismResult``, no files
written but the engine's results file when asked); :func:`report` writes ``conservatism.json``,
``conservatism.md`` (ours beside the paper's Table II) and ``fig4_paths.png`` (paths at n_sigma 0,
0.5, 1, 1.5 over the top view).
"""

from __future__ import annotations

import functools
import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._config import bounded
from ..errors import PlanningError, SplatplanError
from ..planners import RRTConfig, plan
from ..planners.metrics import clearance, d_min, smoothness
from .._progress import progress
from ..robots import load_robot, point_radius
from ._common import load_stonehenge_filtered, mean_std
from ._study import StudyConfig, config_dict, write_outputs
from ..metric.config import MetricConfig  # the paper-reproduction studies run the paper's exact settings

__all__ = ["ConservatismConfig", "ConservatismResult", "PAPER_TABLE_II", "markdown", "report", "run"]

#: The paper's Table II: n_sigma -> (mean, std) per column.
PAPER_TABLE_II: dict[float, dict[str, tuple[float, float]]] = {
    0.00: dict(length_rrt=(0.6017, 0.0841), length_refined=(0.5748, 0.0778), dmin_rrt=(0.0236, 0.0114), dmin_refined=(0.0300, 0.0135), smoothness_rrt=(0.0124, 0.0051), smoothness_refined=(0.0003, 0.0003)),
    0.25: dict(length_rrt=(0.5818, 0.0723), length_refined=(0.5477, 0.0599), dmin_rrt=(0.0252, 0.0121), dmin_refined=(0.0345, 0.0118), smoothness_rrt=(0.0133, 0.0049), smoothness_refined=(0.0003, 0.0002)),
    0.50: dict(length_rrt=(0.5685, 0.0580), length_refined=(0.5441, 0.0465), dmin_rrt=(0.0225, 0.0086), dmin_refined=(0.0311, 0.0115), smoothness_rrt=(0.0136, 0.0058), smoothness_refined=(0.0004, 0.0003)),
    0.75: dict(length_rrt=(0.6390, 0.1773), length_refined=(0.5875, 0.1298), dmin_rrt=(0.0267, 0.0112), dmin_refined=(0.0345, 0.0133), smoothness_rrt=(0.0134, 0.0047), smoothness_refined=(0.0003, 0.0003)),
    1.00: dict(length_rrt=(0.6048, 0.0806), length_refined=(0.5590, 0.0636), dmin_rrt=(0.0301, 0.0122), dmin_refined=(0.0360, 0.0141), smoothness_rrt=(0.0151, 0.0058), smoothness_refined=(0.0003, 0.0003)),
    1.25: dict(length_rrt=(0.6643, 0.1626), length_refined=(0.6084, 0.1160), dmin_rrt=(0.0286, 0.0112), dmin_refined=(0.0334, 0.0165), smoothness_rrt=(0.0158, 0.0074), smoothness_refined=(0.0003, 0.0003)),
    1.50: dict(length_rrt=(0.6772, 0.1912), length_refined=(0.6275, 0.1575), dmin_rrt=(0.0330, 0.0100), dmin_refined=(0.0378, 0.0142), smoothness_rrt=(0.0136, 0.0074), smoothness_refined=(0.0003, 0.0003)),
    1.75: dict(length_rrt=(0.7822, 0.2598), length_refined=(0.7031, 0.2138), dmin_rrt=(0.0358, 0.0072), dmin_refined=(0.0440, 0.0073), smoothness_rrt=(0.0173, 0.0066), smoothness_refined=(0.0002, 0.0002)),
    2.00: dict(length_rrt=(0.7721, 0.2593), length_refined=(0.7072, 0.2272), dmin_rrt=(0.0392, 0.0093), dmin_refined=(0.0459, 0.0091), smoothness_rrt=(0.0147, 0.0057), smoothness_refined=(0.0002, 0.0002)),
}

N_SIGMAS = (0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0)
COLUMNS = ("length_rrt", "length_refined", "dmin_rrt", "dmin_refined", "smoothness_rrt", "smoothness_refined")
#: planning plane of the study (scene units, z up)
PLANE_Z = 0.06
#: goals lie on the square |x| = BORDER or |y| = BORDER
BORDER = 0.47
#: greedy shortcut of the RRT path before refinement. The paper refines the raw tree path, so the
#: "rrt" columns are the raw batched-RRT path and the refinement starts from it.
SHORTCUT = False


@dataclass
class ConservatismConfig(StudyConfig):
    """Knobs of study E3 (defaults = the full run; :meth:`quick` = the < 1 min smoke version)."""

    #: n_sigma values to plan with (the same goals for each).
    n_sigmas: tuple[float, ...] = bounded(N_SIGMAS, ge=0)
    #: Border goals per n_sigma (all collision-free at the largest n_sigma).
    n_goals: int = bounded(20, ge=1)
    #: RRT wall-clock budget per plan (s).
    time_budget_s: float = bounded(60.0, gt=0)
    #: RRT node budget per plan.
    max_nodes: int = bounded(50_000, ge=2)
    #: RRT samples drawn (and edges checked) per iteration (the paper grows 32 nodes at a time).
    batch_size: int = bounded(32, ge=1)
    #: RRT maximum edge length (scene units).
    stride: float = bounded(0.03, gt=0)
    #: Spacing of the collision checks along RRT edges (scene units); None = the planner's default
    #: for a sphere robot, r/4 (inner samples checked with the sphere grown by half the spacing).
    edge_resolution: float | None = bounded(None, gt=0)
    #: Robot sphere radius (scene units).
    radius: float = bounded(point_radius(), gt=0)
    #: Height of the planning plane (scene units, z up).
    plane_z: float = PLANE_Z
    #: Built-in Stonehenge level (1..5).
    level: int = bounded(1, ge=1, le=5)
    #: Scene, goal and planner seed (an integer >= 0).
    seed: int = bounded(0, ge=0)

    @classmethod
    def quick_config(cls) -> "ConservatismConfig":
        """3 goals per n_sigma and a 10 s RRT budget (< 1 minute on a laptop CPU)."""
        return cls(n_goals=3, time_budget_s=10.0, quick=True)

    def check(self) -> None:
        """Cross-field rules (the ranges are declared with the fields)."""
        if not self.n_sigmas:
            raise SplatplanError("ConservatismConfig.n_sigmas must not be empty")


def rrt_description(stride: float, batch_size: int, edge_resolution: float | None, radius: float) -> str:
    """The RRT settings in words, from the values actually used (no stale claims)."""
    er = f"edge resolution {edge_resolution:g}" if edge_resolution is not None else f"edge resolution r/4 = {radius / 4:g} (the planner's default for a sphere robot)"
    return f"batched RRT, {batch_size} samples/iter, stride {stride:g}, {er}" + (", greedy shortcut" if SHORTCUT else ", raw tree path (no shortcut)")


def load_scene(level: int, seed: int):
    """Stonehenge splats at ``level`` with floaters filtered (the paper's preprocessing) + analytic scene."""
    splats, scene, rep = load_stonehenge_filtered(level, seed)
    splats.info["floaters_dropped"] = int(rep.n_dropped)
    return splats, scene


def border_goals(n: int, rng: np.random.Generator, checkers, radius: float, z: float = PLANE_Z, max_tries: int = 10000) -> np.ndarray:
    """``n`` random goals on the square border |x| = BORDER or |y| = BORDER at height z, each
    collision-free for every checker in ``checkers`` (sphere of ``radius``). Returns (n, 3)."""
    goals = []
    axes = (radius, radius, radius)
    for _ in range(max_tries):
        t = rng.uniform(0.0, 4.0)
        side, f = int(t), (t % 1.0) * 2 * BORDER - BORDER
        xy = [(BORDER, f), (f, BORDER), (-BORDER, f), (f, -BORDER)][side]
        g = np.array([xy[0], xy[1], z])
        if all(not bool(c.collides(g[None], None, axes)[0]) for c in checkers):
            goals.append(g)
            if len(goals) == n:
                return np.asarray(goals)
    raise PlanningError(f"could not find {n} collision-free border goals in {max_tries} tries")


def free_start(center, checkers, radius: float, max_offset: float = 0.1) -> np.ndarray:
    """``center`` (3,) if it is collision-free for every checker, else the nearest free point on
    rings of growing radius around it in its horizontal plane (a large floater can make the exact
    centre unusable). Raises PlanningError when nothing within ``max_offset`` is free."""
    center = np.asarray(center, dtype=np.float64)
    axes = (radius, radius, radius)
    for rho in np.arange(0.0, max_offset + 1e-9, 0.005):
        n = 1 if rho == 0 else max(8, int(2 * np.pi * rho / 0.005))
        ang = np.arange(n) * 2 * np.pi / n
        cand = center + rho * np.stack([np.cos(ang), np.sin(ang), np.zeros(n)], axis=1)
        free = np.ones(n, dtype=bool)
        for c in checkers:
            free &= ~c.collides(cand, None, axes)
        if free.any():
            return cand[int(np.argmax(free))]
    raise PlanningError(f"no collision-free start within {max_offset} of {center}")


def _plan_one(checker, start, goal, means_tree, sdf, seed: int, rrt_cfg: RRTConfig, radius: float):
    """One trial: (metric dict, empty on failure; the PlanResult or None on a PlanningError)."""
    try:
        res = plan(checker, start, goal, robot=load_robot(f"sphere:{radius!r}"), refine=True, seed=seed, rrt_config=rrt_cfg)
    except PlanningError:
        return {}, None
    if not res.success:
        return {}, res
    p0 = res.path_shortcut
    p1 = res.path
    return (
        dict(
            length_rrt=res.info["length_rrt"],
            length_refined=res.length,
            dmin_rrt=d_min(p0, means_tree),
            dmin_refined=d_min(p1, means_tree),
            smoothness_rrt=smoothness(p0),
            smoothness_refined=smoothness(p1),
            clearance_rrt=clearance(p0, sdf, radius),
            clearance_refined=clearance(p1, sdf, radius),
            refined=float(res.refined),
            time_s=res.time_s,
            n_nodes=res.n_nodes,
        ),
        res,
    )


def _rrt_config(c: "ConservatismConfig", time_budget_s: float) -> RRTConfig:
    return RRTConfig(
        batch_size=c.batch_size,
        stride=c.stride,
        edge_resolution=c.edge_resolution,
        box_lo=(-0.5, -0.5, c.plane_z),
        box_hi=(0.5, 0.5, c.plane_z),
        time_limit_s=time_budget_s,
        max_nodes=c.max_nodes,
        shortcut=SHORTCUT,
    )


def plan_trials(checker, start, goals, means_tree, sdf, seed: int, time_budget_s: float, tag: str = "", config: ConservatismConfig | None = None) -> tuple[list[dict], list]:
    """Plan start -> each goal (RRT (+ shortcut if SHORTCUT) + refinement) and measure the paths.

    ``config`` supplies the RRT settings and the robot radius (default :class:`ConservatismConfig`).
    Goal i is planned with seed ``seed + i``. Returns per-trial metric dicts (empty dict for a
    failure) and the PlanResults (None for an error).
    """
    c = config or ConservatismConfig()
    cfg = _rrt_config(c, time_budget_s)
    rows, results = [], []
    for i, g in enumerate(progress(goals, desc=tag)):
        row, res = _plan_one(checker, start, g, means_tree, sdf, seed + i, cfg, c.radius)
        rows.append(row)
        results.append(res)
    return rows, results


class ConservatismContext:
    """Per-worker state of E3's tasks: the scene (loaded once), its checkers per n_sigma, the
    k-d tree of the splat means and the analytic SDF."""

    def __init__(self, level: int, seed: int, device: str) -> None:
        from ..metric import CollisionChecker

        self.splats, self.scene = load_scene(level, seed)
        self.base = CollisionChecker(self.splats, n_sigma=0.0, device=device, config=MetricConfig.paper())
        from scipy.spatial import cKDTree

        self.tree = cKDTree(self.splats.means.astype(np.float64))
        self._checkers: dict[float, object] = {}

    def checker(self, n_sigma: float):
        if n_sigma not in self._checkers:
            self._checkers[n_sigma] = self.base.with_config(n_sigma=float(n_sigma))
        return self._checkers[n_sigma]


def make_context(level: int, seed: int, device: str) -> ConservatismContext:
    return ConservatismContext(level, seed, device)


def conservatism_task(spec: dict, ctx: ConservatismContext) -> dict:
    """One E3 trial (n_sigma, goal): the metric row plus both paths (for Fig. 4); seeded from ``spec``."""
    c = ConservatismConfig(**spec["config"])
    row, res = _plan_one(ctx.checker(float(spec["n_sigma"])), np.asarray(spec["start"]), np.asarray(spec["goal"]), ctx.tree, ctx.scene.sdf,
                         int(spec["seed"]), _rrt_config(c, c.time_budget_s), c.radius)  # fmt: skip
    if row and res is not None:
        row["path_rrt"] = res.path_shortcut
        row["path"] = res.path
    return row


def summarise(rows: list[dict], keys=COLUMNS) -> dict:
    ok = [r for r in rows if r]
    out: dict[str, Any] = {k: mean_std([r[k] for r in ok], finite_only=True) for k in keys}
    out["success_rate"] = len(ok) / max(1, len(rows))
    out["n_trials"] = len(rows)
    return out


def _fmt(ms) -> str:
    m, s = ms
    return "n/a" if not np.isfinite(m) else f"{m:.4f} ± {s:.4f}"


@dataclass
class ConservatismResult:
    """What E3 measured: ``rows`` and ``setup`` are the JSON; ``scene`` and ``paths`` feed Fig. 4."""

    #: one row per n_sigma: n_sigma, [mean, std] of every column over the successful trials
    #: (COLUMNS, clearance_rrt / _refined, time_s), success_rate, n_trials, refined_rate
    rows: list[dict]
    #: scene, robot, start, goals, planner, device, engine and the config (tuples as lists)
    setup: dict[str, Any]
    #: figure only: the analytic scene (for the top view)
    scene: Any = field(default=None, repr=False)
    #: figure only: n_sigma -> [(raw RRT path (P, 3), refined path (P', 3))] of the successful trials
    paths: dict[float, list[tuple[np.ndarray, np.ndarray]]] = field(default_factory=dict, repr=False)

    def to_json(self) -> dict[str, Any]:
        """The content of ``conservatism.json``."""
        return {"rows": self.rows, "setup": self.setup}


def markdown(result: ConservatismResult) -> str:
    """The markdown table of E3 (ours beside the paper's Table II)."""
    st = result.setup
    lines = [
        "# E3: conservatism (paper Table II)",
        "",
        f"Stonehenge level {st['level']} ({st['n_splats']} splats), sphere r = {st['robot_radius']}, plane z = {st['plane_z']}, "
        f"{st['n_goals']} border goals from the centre; {st['rrt']}. 'rrt' = the raw batched-RRT path (no shortcut); "
        "'refined' = after the zeroth-order refinement. mean ± std over successful trials. "
        "Smoothness: our definition (planners/metrics.py); the paper does not define its own.",
        "",
        "| n_sigma | " + " | ".join(f"{c} (ours) | {c} (paper)" for c in COLUMNS) + " | success | refined | true clearance refined |",
        "|" + "---|" * (2 + 2 * len(COLUMNS) + 2),
    ]
    for r in result.rows:
        paper = PAPER_TABLE_II.get(round(r["n_sigma"], 2), {})
        cells = [f"{r['n_sigma']:.2f}"]
        for c in COLUMNS:
            cells += [_fmt(r[c]), _fmt(paper[c]) if c in paper else "—"]
        cells += [f"{r['success_rate']:.2f}", f"{r['refined_rate']:.2f}", _fmt(r["clearance_refined"])]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _trial_tasks(cfg: ConservatismConfig, start: np.ndarray, goals: np.ndarray, device: str) -> list:
    """One engine task per (n_sigma, goal); the key hashes the config, the device and the code."""
    from .engine import Task, code_version

    cfg_dict = config_dict(cfg)
    sig = hashlib.sha1(json.dumps({"config": cfg_dict, "device": device, "code": code_version()}, sort_keys=True).encode()).hexdigest()[:8]
    return [
        Task(f"{sig}/ns={float(ns):g}/goal={i}", {"n_sigma": float(ns), "goal": g.tolist(), "start": start.tolist(), "seed": cfg.seed + i, "config": cfg_dict})
        for ns in cfg.n_sigmas
        for i, g in enumerate(goals)
    ]


def run(config: ConservatismConfig, engine=None, *, results: str | Path | None = None) -> ConservatismResult:
    """Run study E3 (the protocol of the module docstring); writes no file but the engine's ``results``.

    Args:
        config: the knobs (:meth:`ConservatismConfig.quick_config`: 3 goals, 10 s budget); validated here.
        engine: where the trials run (:class:`~splatplan.eval.engine.EngineConfig` or its dict;
            default serial). Every (n_sigma, goal) trial is one task.
        results: JSON-lines file finished trials stream to; a rerun with the same config skips
            them. None: in memory only.

    Returns:
        :class:`ConservatismResult`: ``rows`` (one per n_sigma, [mean, std] per column) and ``setup``.
    """
    from ..metric import CollisionChecker
    from .engine import run_tasks

    cfg = config.validate()
    splats, scene = load_scene(cfg.level, cfg.seed)
    base = CollisionChecker(splats, n_sigma=0.0, device=cfg.device, config=MetricConfig.paper())
    strict = [base.with_config(n_sigma=max(cfg.n_sigmas))]
    start = free_start(np.array([0.0, 0.0, cfg.plane_z]), strict, radius=cfg.radius)
    rng = np.random.default_rng(cfg.seed)
    goals = border_goals(cfg.n_goals, rng, strict, z=cfg.plane_z, radius=cfg.radius)
    tasks = _trial_tasks(cfg, start, goals, str(base.device))
    factory = functools.partial(make_context, cfg.level, cfg.seed, str(base.device))
    ran = run_tasks(tasks, conservatism_task, factory, engine, results, desc="E3 trials")
    rows, paths = [], {}
    for ns in cfg.n_sigmas:
        trials = []
        for t in tasks:
            if t.spec["n_sigma"] != float(ns):
                continue
            r = ran.rows.get(t.key, {})  # a task that raised counts as a failed trial
            trials.append({k: (np.nan if v is None else v) for k, v in r.items()})
        row = {"n_sigma": float(ns), **summarise(trials, COLUMNS + ("clearance_rrt", "clearance_refined", "time_s"))}
        row["refined_rate"] = float(np.mean([t["refined"] for t in trials if t])) if any(trials) else 0.0
        rows.append(row)
        paths[float(ns)] = [(np.asarray(t["path_rrt"]), np.asarray(t["path"])) for t in trials if t]
    setup = {
        "scene": f"stonehenge level {cfg.level}",
        "level": cfg.level,
        "n_splats": len(splats),
        "floaters_dropped": splats.info.get("floaters_dropped", 0),
        "robot_radius": cfg.radius,
        "plane_z": cfg.plane_z,
        "n_goals": cfg.n_goals,
        "start": start.tolist(),
        "goals": goals.tolist(),
        "rrt": rrt_description(cfg.stride, cfg.batch_size, cfg.edge_resolution, cfg.radius) + f", budget {cfg.time_budget_s:g} s / {cfg.max_nodes:,} nodes",
        "refinement": "one MPPI update over the whole path (RefineConfig defaults)",
        "device": str(base.device),
        "engine": ran.engine,
        "n_task_errors": len(ran.errors),
        "quick": bool(cfg.quick),
        "seed": int(cfg.seed),
        "config": config_dict(cfg),
    }
    return ConservatismResult(rows=rows, setup=setup, scene=scene, paths=paths)


def paths_figure(result: ConservatismResult):
    """Fig. 4: the raw RRT and refined paths at n_sigma 0, 0.5, 1, 1.5 over the top view. Returns the Figure."""
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    from ..scenes.builtin.stonehenge import plot_top_view
    from ._plots import top_view_handles

    st, paths, scene = result.setup, result.paths, result.scene
    z, start, goals = st["plane_z"], np.asarray(st["start"]), np.asarray(st["goals"])
    shown = [ns for ns in (0.0, 0.5, 1.0, 1.5) if ns in paths] or list(paths)[:4]
    fig = Figure(figsize=(4 * len(shown), 5.6))
    axs = fig.subplots(1, len(shown), squeeze=False)[0]
    for ax, ns in zip(axs, shown):
        plot_top_view(ax, scene, z)
        for p0, p1 in paths.get(ns, []):
            ax.plot(p0[:, 0], p0[:, 1], "--", color="tab:blue", lw=0.8, alpha=0.7)
            ax.plot(p1[:, 0], p1[:, 1], "-", color="tab:red", lw=1.2)
        ax.plot(*start[:2], "ko", ms=4)
        ax.plot(goals[:, 0], goals[:, 1], "k*", ms=6)
        ax.set_title(f"conservatism n_sigma = {ns:g}")
        ax.set_xlim(-0.5, 0.5)
        ax.set_ylim(-0.5, 0.5)
        ax.set_aspect("equal")
        ax.set_xlabel("x (scene units)")
        ax.set_ylabel("y (scene units)")
    handles = [
        Line2D([], [], ls="--", color="tab:blue", label="RRT path (raw tree path)"),
        Line2D([], [], color="tab:red", label="after the zeroth-order refinement"),
        Line2D([], [], ls="", marker="o", color="k", ms=4, label="start"),
        Line2D([], [], ls="", marker="*", color="k", ms=6, label="goals on the border"),
        *top_view_handles(scene, z),
    ]
    fig.legend(handles=handles, loc="lower center", ncol=4, fontsize=7, frameon=False)
    fig.suptitle(f"E3: paths of a sphere (r = {st['robot_radius']:g}) in the plane z = {z:g}, top view; larger n_sigma = more conservative", fontsize=10)
    fig.tight_layout(rect=(0, 0.16, 1, 0.95))
    return fig


def report(result: ConservatismResult, out_dir: str | Path) -> list[Path]:
    """Write ``conservatism.json``, ``conservatism.md`` and ``fig4_paths.png`` into ``out_dir`` (an existing folder)."""
    return write_outputs(out_dir, "conservatism", result.to_json(), markdown(result), (("fig4_paths.png", paths_figure(result), 120),))
