"""Study E4 (paper Table III, Fig. 5): the metric's linearisation versus Gaussian size.

Scenes M1..M5 are the built-in Stonehenge at levels 1..5 (fewer, larger splats at higher levels,
floaters filtered). Two measurements, both at n_sigma = 1 with a sphere robot of radius 0.015:

1. The metric along **one straight collision-free path** (checker s2_cap raised to 25 so that
   min_s2 is exact up to ~5 radii) (the same segment for every level):
   ``min_s2`` (conservative minimum scaling distance, clipped at the checker's ``s2_cap``) and the
   streaming ``softmin``, against arc length -> ``fig5_metric_along_path.png``. The segment is
   chosen automatically: among random segments (length >= 0.4) in the plane z = 0.06 whose exact
   clearance (``AnalyticScene.sdf`` minus the radius) is at least 0.005 and that are free for
   the M1 checker, the one running closest to the stones (smallest mean clearance),
   so that it passes close by obstacles as in the paper's figure.
2. The planner of study E3 (batched RRT, raw tree path; the paper's Table III reports the RRT
   path, its numbers equal Table II's n_sigma = 1 RRT column) from the centre to random border
   goals: path length and d_min per level M1..M3 (PLAN_LEVELS) -> ``linearization.json`` / ``.md``
   beside the paper's Table III (M1..M3).

Every knob is a field of :class:`LinearizationConfig` (``splatplan eval linearization --help``).
:func:`run` measures (``run(LinearizationConfig(...)) -> LinearizationResult``, no files written);
:func:`report` writes the JSON, the markdown and the figure.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._config import bounded
from ..errors import PlanningError, SplatplanError
from .._progress import progress
from ..robots import point_radius
from ._common import mean_std
from ._study import StudyConfig, config_dict, write_outputs
from .conservatism import PLANE_Z, border_goals, free_start, load_scene, plan_trials
from ..metric.config import MetricConfig  # the paper-reproduction studies run the paper's exact settings

__all__ = ["LinearizationConfig", "LinearizationResult", "PAPER_TABLE_III", "markdown", "report", "run"]

#: The paper's Table III: scene -> (path length mean, std), (closest distance mean, std).
PAPER_TABLE_III = {
    1: {"length": (0.6048, 0.0806), "dmin": (0.030, 0.012)},
    2: {"length": (0.6747, 0.1721), "dmin": (0.031, 0.014)},
    3: {"length": (0.7531, 0.2812), "dmin": (0.035, 0.013)},
}
LEVELS = (1, 2, 3, 4, 5)
#: levels the planner runs on (the paper's Table III: M1..M3). At M4/M5 the largest splats
#: (needles up to ~0.2 long at M5) make most of the border unreachable at n_sigma = 1.
PLAN_LEVELS = (1, 2, 3)
#: border goals per level in the full run (the same goals for every level)
N_GOALS = 40
#: s2_cap of the metric-along-path plot (min_s2 exact below it: within ~5 robot radii)
PLOT_S2_CAP = 25.0
N_SIGMA = 1.0


@dataclass
class LinearizationConfig(StudyConfig):
    """Knobs of study E4 (defaults = the full run; :meth:`quick` = the < 1 min smoke version)."""

    #: Stonehenge levels whose metric is plotted along the straight path (M1..M5).
    levels: tuple[int, ...] = bounded(LEVELS, ge=1, le=5)
    #: Levels the planner runs on (the paper's Table III: M1..M3).
    plan_levels: tuple[int, ...] = bounded(PLAN_LEVELS, ge=1, le=5)
    #: Border goals per level (the same goals for every level).
    n_goals: int = bounded(N_GOALS, ge=1)
    #: RRT wall-clock budget per plan (s).
    time_budget_s: float = bounded(60.0, gt=0)
    #: Conservatism of every checker.
    n_sigma: float = bounded(N_SIGMA, ge=0)
    #: s2_cap of the metric-along-path plot (min_s2 exact below it: within ~5 robot radii).
    plot_s2_cap: float = bounded(PLOT_S2_CAP, ge=1)
    #: Candidate straight segments drawn to pick the plotted one.
    n_candidates: int = bounded(3000, ge=1)
    #: Scene, goal and planner seed (an integer >= 0).
    seed: int = bounded(0, ge=0)

    @classmethod
    def quick_config(cls) -> "LinearizationConfig":
        """3 goals per level and a 10 s RRT budget (< 1 minute)."""
        return cls(n_goals=3, time_budget_s=10.0, quick=True)

    def check(self) -> None:
        """Cross-field rules (the ranges are declared with the fields)."""
        if not set(self.plan_levels) <= set(self.levels):
            raise SplatplanError(f"LinearizationConfig: levels must include plan_levels, got {self.levels} / {self.plan_levels}")


def choose_straight_path(
    scene,
    checkers,
    rng: np.random.Generator,
    n_candidates: int = 3000,
    min_length: float = 0.4,
    min_clearance: float = 0.005,
    z: float = PLANE_Z,
    radius: float = point_radius(),
) -> np.ndarray:
    """A straight segment (2, 3) at height z, at least ``min_length`` long, collision-free for the
    exact geometry (clearance >= ``min_clearance``) and for every checker, running as close to the
    stones as allowed (smallest mean clearance, clearances above 0.05 counted as 0.05)."""
    axes = (radius,) * 3
    p0 = np.concatenate([rng.uniform(-0.47, 0.47, (n_candidates, 2)), np.full((n_candidates, 1), z)], axis=1)
    p1 = np.concatenate([rng.uniform(-0.47, 0.47, (n_candidates, 2)), np.full((n_candidates, 1), z)], axis=1)
    keep = np.linalg.norm(p1 - p0, axis=1) >= min_length
    p0, p1 = p0[keep], p1[keep]
    s = np.linspace(0.0, 1.0, 120)
    pts = p0[:, None] + s[None, :, None] * (p1 - p0)[:, None]  # (C, S, 3)
    clr = (scene.sdf(pts.reshape(-1, 3)) - radius).reshape(len(p0), -1)  # (C, S)
    ok = clr.min(axis=1) >= min_clearance
    score = np.where(ok, np.minimum(clr, 0.05).mean(axis=1), np.inf)
    for i in np.argsort(score):
        if not np.isfinite(score[i]):
            break
        dense = p0[i] + np.linspace(0, 1, 400)[:, None] * (p1[i] - p0[i])
        if not any(c.collides(dense, None, axes).any() for c in checkers):
            return np.stack([p0[i], p1[i]])
    raise PlanningError("no collision-free straight segment found for the metric-along-path plot")


@dataclass
class LinearizationResult:
    """What E4 measured: ``rows`` and ``setup`` are the JSON; the rest feeds Fig. 5."""

    #: one row per planned level: level, [mean, std] of length / dmin (raw RRT) and of the refined
    #: path, success_rate, n_splats, mean_max_scale and the metric along the straight path
    rows: list[dict]
    #: n_sigma, levels, robot, straight path, start, goals, device and the config (tuples as lists)
    setup: dict[str, Any]
    #: figure only: (S,) arc length along the straight path (scene units)
    arc: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    #: figure only: (S,) exact clearance (sdf - r) along it
    clearance_true: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    #: figure only: level -> (min_s2 (S,), softmin (S,), both clipped at plot_s2_cap; splat count)
    along: dict[int, tuple[np.ndarray, np.ndarray, int]] = field(default_factory=dict, repr=False)

    def to_json(self) -> dict[str, Any]:
        """The content of ``linearization.json``."""
        return {"rows": self.rows, "setup": self.setup}


def markdown(result: LinearizationResult) -> str:
    """The markdown table of E4 (ours beside the paper's Table III)."""
    st = result.setup
    fmt = lambda ms: "n/a" if not np.isfinite(ms[0]) else f"{ms[0]:.4f} ± {ms[1]:.4f}"  # noqa: E731
    lines = [
        "# E4: linearisation effect (paper Table III)",
        "",
        f"Stonehenge levels {', '.join(f'M{lv}' for lv in st['levels'])} (larger and fewer splats with the level), n_sigma = {st['n_sigma']:g}, "
        f"sphere r = {st['robot_radius']}, {st['n_goals']} border goals from the centre; raw RRT paths (as E3). mean ± std.",
        "",
        "| scene | splats | path length (ours) | path length (paper) | d_min (ours) | d_min (paper) | success | min over path of min_s2 |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in result.rows:
        p = PAPER_TABLE_III.get(r["level"])
        lines.append(
            f"| M{r['level']} | {r['n_splats']} | {fmt(r['length'])} | {fmt(p['length']) if p else '—'} | "
            f"{fmt(r['dmin'])} | {fmt(p['dmin']) if p else '—'} | {r['success_rate']:.2f} | {r['metric_along_path']['min_s2_min']:.3f} |"
        )
    return "\n".join(lines) + "\n"


def _plan_row(lv: int, splats, scene, checker, start, goals, cfg: LinearizationConfig, along: dict) -> dict:
    """The planner of E3 from the centre to every goal at level ``lv``: length and d_min of the raw RRT path."""
    from scipy.spatial import cKDTree

    trials, _ = plan_trials(checker, start, goals, cKDTree(splats.means.astype(np.float64)), scene.sdf, cfg.seed, cfg.time_budget_s, tag=f"M{lv}")
    ok = [r for r in trials if r]
    return {
        "level": int(lv),
        "length": mean_std([r["length_rrt"] for r in ok], finite_only=True),
        "dmin": mean_std([r["dmin_rrt"] for r in ok], finite_only=True),
        "length_refined": mean_std([r["length_refined"] for r in ok], finite_only=True),
        "dmin_refined": mean_std([r["dmin_refined"] for r in ok], finite_only=True),
        "success_rate": len(ok) / max(1, len(trials)),
        "n_splats": len(splats),
        "mean_max_scale": float(splats.scales.max(axis=1).mean()),
        "metric_along_path": along,
    }


def run(config: LinearizationConfig) -> LinearizationResult:
    """Run study E4 (the protocol of the module docstring); writes no file.

    Args:
        config: the knobs (:meth:`LinearizationConfig.quick_config`: 3 goals per level, 10 s budget); validated here.

    Returns:
        :class:`LinearizationResult`: ``rows`` (one per planned level) and ``setup``, plus the curves of Fig. 5.
    """
    from ..metric import CollisionChecker

    cfg = config.validate()
    rng = np.random.default_rng(cfg.seed)
    scenes = {}
    for lv in progress(cfg.levels, desc="build scenes"):
        splats, scene = load_scene(lv, cfg.seed)
        scenes[lv] = (splats, scene, CollisionChecker(splats, n_sigma=cfg.n_sigma, device=cfg.device, config=MetricConfig.paper()))
    analytic = scenes[cfg.levels[0]][1]  # the geometry is the same at every level (same layout seed)
    checkers = [scenes[lv][2] for lv in cfg.plan_levels]
    radius = point_radius()  # the robot: the studies' sphere DEFAULT_POINT_ROBOT, as in E3 (whose planner runs here)
    line = choose_straight_path(analytic, [scenes[cfg.levels[0]][2]], rng, n_candidates=cfg.n_candidates, radius=radius)  # free in the first level (and the exact geometry)
    goals = border_goals(cfg.n_goals, rng, checkers, radius)
    start = free_start(np.array([0.0, 0.0, PLANE_Z]), checkers, radius)

    t = np.linspace(0.0, 1.0, 600)
    pts = line[0] + t[:, None] * (line[1] - line[0])  # (S, 3)
    arc = t * float(np.linalg.norm(line[1] - line[0]))
    clr_true = analytic.sdf(pts) - radius
    rows, curves = [], {}
    cap = cfg.plot_s2_cap
    for lv in progress(cfg.levels, desc="levels"):
        splats, scene, ch = scenes[lv]
        q = ch.with_config(s2_cap=cap).query(pts, None, (radius,) * 3)  # exact min_s2 up to a larger distance
        min_s2 = np.minimum(q.min_s2.astype(np.float64), cap)
        soft = np.minimum(q.softmin.astype(np.float64), cap)
        curves[lv] = (min_s2, soft, len(splats))
        along = {"min_s2_min": float(min_s2.min()), "softmin_min": float(soft.min()), "min_s2_mean": float(min_s2.mean())}
        if lv in cfg.plan_levels:
            rows.append(_plan_row(lv, splats, scene, ch, start, goals, cfg, along))
    setup = {
        "n_sigma": cfg.n_sigma,
        "levels": list(cfg.levels),
        "n_goals": cfg.n_goals,
        "robot_radius": radius,
        "plane_z": PLANE_Z,
        "straight_path": line.tolist(),
        "straight_path_min_true_clearance": float(clr_true.min()),
        "start": start.tolist(),
        "goals": goals.tolist(),
        "length_dmin_of": "batched RRT path (as the paper's Table III: its M1 row equals Table II's n_sigma=1 RRT column)",
        "device": str(checkers[0].device),
        "quick": bool(cfg.quick),
        "seed": int(cfg.seed),
        "config": config_dict(cfg),
    }
    return LinearizationResult(rows=rows, setup=setup, arc=arc, clearance_true=clr_true, along=curves)


def metric_figure(result: LinearizationResult):
    """Fig. 5: min_s2 (top) and softmin (bottom, with the true clearance) along the straight path per level. Returns the Figure."""
    from matplotlib.figure import Figure

    st, arc = result.setup, result.arc
    cap = st["config"]["plot_s2_cap"]
    fig = Figure(figsize=(8, 7.0))
    axs = fig.subplots(2, 1, sharex=True)
    for lv, (min_s2, soft, n_splats) in result.along.items():
        axs[0].plot(arc, min_s2, label=f"M{lv} ({n_splats // 1000}k splats)")
        axs[1].plot(arc, soft, label=f"M{lv}")
    axs[0].set_ylabel(f"conservative scaling distance\n(min s2~, clipped at {cap:g})")
    axs[0].axhline(1.0, color="k", lw=0.6, ls=":", label="1 = touching (below: collision)")
    axs[1].set_ylabel("smooth minimum over nearby splats\n(softmin of s2~)")
    axs[1].axhline(1.0, color="k", lw=0.6, ls=":")
    ax2 = axs[1].twinx()
    ax2.plot(arc, result.clearance_true, color="0.6", lw=0.8, ls="--", label="true clearance (right axis)")
    ax2.set_ylabel("true clearance to the stones (scene units)", color="0.5")
    ax2.legend(loc="upper right", fontsize=7)
    axs[1].set_xlabel("distance along the straight path (scene units)")
    axs[0].legend(fontsize=7)
    axs[1].legend(loc="upper left", fontsize=7)
    axs[0].set_title(f"Metric along a straight collision-free path (n_sigma = {st['n_sigma']:g}, sphere r = {st['robot_radius']}); "
                     "M1..M5: larger and fewer splats", fontsize=9)  # fmt: skip
    fig.tight_layout()
    return fig


def report(result: LinearizationResult, out_dir: str | Path) -> list[Path]:
    """Write ``linearization.json``, ``linearization.md`` and ``fig5_metric_along_path.png`` into ``out_dir`` (an existing folder)."""
    return write_outputs(out_dir, "linearization", result.to_json(), markdown(result), (("fig5_metric_along_path.png", metric_figure(result), 120),))
