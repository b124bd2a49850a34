"""Study E3 (paper Table II, Fig. 4): planning conservatism versus n_sigma.

Protocol (SPEC section 4, E3): on the built-in Stonehenge (level 1, floaters filtered as the paper
does), a sphere robot of radius 0.015 plans in the plane z = 0.06 from the scene centre to random
goals on the scene border with the batched RRT (32 nodes per iteration; no shortcut, see SHORTCUT), then the
zeroth-order refinement (one MPPI update over the whole path). For n_sigma in 0, 0.25, ..., 2 we
report path length, d_min (closest distance from the densely resampled path to a splat mean) and
smoothness (:func:`splatplan.planners.metrics.smoothness`), before ("rrt" = the raw RRT path)
and after refinement, as mean and standard deviation over the successful trials. The same goals
(all collision-free at the most conservative n_sigma) are used for every n_sigma.

Outputs in ``out_dir``: ``conservatism.json``, ``conservatism.md`` (ours beside the paper's
Table II) and ``fig4_paths.png`` (paths at n_sigma 0, 0.5, 1, 1.5 over the top view).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from ..errors import PlanningError
from ..planners import RRTConfig, plan
from ..planners.metrics import clearance, d_min, smoothness
from ._common import load_stonehenge_filtered, progress

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
#: robot sphere radius and planning plane of the study (scene units)
RADIUS = 0.015
PLANE_Z = 0.06
#: goals lie on the square |x| = BORDER or |y| = BORDER
BORDER = 0.47
#: greedy shortcut of the RRT path before refinement. The paper refines the raw tree path, so the
#: "rrt" columns are the raw batched-RRT path and the refinement starts from it.
SHORTCUT = False


def load_scene(level: int, seed: int):
    """Stonehenge splats at ``level`` with floaters filtered (the paper's preprocessing) + analytic scene."""
    splats, scene, report = load_stonehenge_filtered(level, seed)
    splats.info["floaters_dropped"] = int(report.n_dropped)
    return splats, scene


def border_goals(n: int, rng: np.random.Generator, checkers, z: float = PLANE_Z, radius: float = RADIUS, max_tries: int = 10000) -> np.ndarray:
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


def free_start(center, checkers, radius: float = RADIUS, max_offset: float = 0.1) -> np.ndarray:
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


def mean_std(values) -> list[float]:
    """[mean, std] of the finite values ([nan, nan] when there are none)."""
    v = np.asarray([x for x in values if np.isfinite(x)], dtype=np.float64)
    return [float(v.mean()), float(v.std())] if v.size else [float("nan"), float("nan")]


def plan_trials(checker, start, goals, means_tree, sdf, seed: int, time_budget_s: float, tag: str = "") -> tuple[list[dict], list]:
    """Plan start -> each goal (RRT (+ shortcut if SHORTCUT) + refinement) and measure the paths.

    Returns per-trial metric dicts (empty dict for a failure) and the PlanResults (None for an error).
    """
    cfg = RRTConfig(
        batch_size=32,
        stride=0.03,
        box_lo=(-0.5, -0.5, PLANE_Z),
        box_hi=(0.5, 0.5, PLANE_Z),
        time_budget_s=time_budget_s,
        max_nodes=50_000,
        shortcut=SHORTCUT,
    )
    rows, results = [], []
    for i, g in enumerate(progress(goals, desc=tag)):
        try:
            res = plan(checker, start, g, radius=RADIUS, refine=True, seed=seed + i, rrt_config=cfg)
        except PlanningError:
            rows.append({})
            results.append(None)
            continue
        results.append(res)
        if not res.success:
            rows.append({})
            continue
        p0 = res.info["path_shortcut"]
        p1 = res.path
        rows.append(
            dict(
                length_rrt=res.info["length_rrt"],
                length_refined=res.length,
                dmin_rrt=d_min(p0, means_tree),
                dmin_refined=d_min(p1, means_tree),
                smoothness_rrt=smoothness(p0),
                smoothness_refined=smoothness(p1),
                clearance_rrt=clearance(p0, sdf, RADIUS),
                clearance_refined=clearance(p1, sdf, RADIUS),
                refined=float(res.refined),
                time_s=res.time_s,
                n_nodes=res.n_nodes,
            )
        )
    return rows, results


def summarise(rows: list[dict], keys=COLUMNS) -> dict:
    ok = [r for r in rows if r]
    out = {k: mean_std([r[k] for r in ok]) for k in keys}
    out["success_rate"] = len(ok) / max(1, len(rows))
    out["n_trials"] = len(rows)
    return out


def _fmt(ms) -> str:
    m, s = ms
    return "n/a" if not np.isfinite(m) else f"{m:.4f} ± {s:.4f}"


def write_markdown(path: Path, rows: list[dict], header: str) -> None:
    lines = [header, ""]
    lines.append("| n_sigma | " + " | ".join(f"{c} (ours) | {c} (paper)" for c in COLUMNS) + " | success | refined | true clearance refined |")
    lines.append("|" + "---|" * (2 + 2 * len(COLUMNS) + 2))
    for r in rows:
        paper = PAPER_TABLE_II.get(round(r["n_sigma"], 2), {})
        cells = [f"{r['n_sigma']:.2f}"]
        for c in COLUMNS:
            cells += [_fmt(r[c]), _fmt(paper[c]) if c in paper else "—"]
        cells += [f"{r['success_rate']:.2f}", f"{r['refined_rate']:.2f}", _fmt(r["clearance_refined"])]
        lines.append("| " + " | ".join(cells) + " |")
    path.write_text("\n".join(lines) + "\n")


def run_conservatism(out_dir: Path, quick: bool = False, seed: int = 0) -> dict:
    """Run study E3 and write its JSON, markdown table and figure into ``out_dir``.

    Args:
        out_dir: output folder (created if missing).
        quick: 3 goals per n_sigma and a 10 s RRT budget (< 1 minute on a laptop CPU) instead
            of 20 goals and 60 s.
        seed: scene, goal and planner seed.

    Returns:
        The JSON content: ``{"rows": [{"n_sigma", "length_rrt": [mean, std], ...}], ...}``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..metric import CollisionChecker
    from ..scenes.stonehenge import plot_top_view

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    n_goals = 3 if quick else 20
    budget = 10.0 if quick else 60.0
    splats, scene = load_scene(1, seed)
    base = CollisionChecker(splats, n_sigma=0.0, device="auto")
    tree = cKDTree(splats.means.astype(np.float64))
    strict = [base.with_config(n_sigma=max(N_SIGMAS))]
    start = free_start(np.array([0.0, 0.0, PLANE_Z]), strict)
    rng = np.random.default_rng(seed)
    goals = border_goals(n_goals, rng, strict)
    rows, paths = [], {}
    for ns in progress(N_SIGMAS, desc="n_sigma"):
        ch = base.with_config(n_sigma=ns)
        trials, results = plan_trials(ch, start, goals, tree, scene.sdf, seed, budget, tag=f"n_sigma={ns:g}")
        row = {"n_sigma": float(ns), **summarise(trials, COLUMNS + ("clearance_rrt", "clearance_refined", "time_s"))}
        row["refined_rate"] = float(np.mean([t["refined"] for t in trials if t])) if any(trials) else 0.0
        rows.append(row)
        paths[ns] = [(r.info["path_shortcut"], r.path) for r in results if r is not None and r.success]
    out = {
        "rows": rows,
        "setup": {
            "scene": "stonehenge level 1",
            "n_splats": len(splats),
            "floaters_dropped": splats.info.get("floaters_dropped", 0),
            "robot_radius": RADIUS,
            "plane_z": PLANE_Z,
            "start": start.tolist(),
            "goals": goals.tolist(),
            "rrt": "batched RRT, 32 samples/iter, stride 0.03, edge resolution r/2" + (", greedy shortcut" if SHORTCUT else ", raw tree path (no shortcut)"),
            "refinement": "one MPPI update over the whole path (RefineConfig defaults)",
            "device": str(base.device),
            "quick": bool(quick),
            "seed": int(seed),
        },
    }
    (out_dir / "conservatism.json").write_text(json.dumps(out, indent=2))
    write_markdown(
        out_dir / "conservatism.md",
        rows,
        "# E3: conservatism (paper Table II)\n\n"
        f"Stonehenge level 1 ({len(splats)} splats), sphere r = {RADIUS}, plane z = {PLANE_Z}, "
        f"{n_goals} border goals from the centre. 'rrt' = the raw batched-RRT path (no shortcut); "
        "'refined' = after the zeroth-order refinement. mean ± std over successful trials. "
        "Smoothness: our definition (planners/metrics.py); the paper does not define its own.",
    )
    fig, axs = plt.subplots(1, 4, figsize=(16, 4.4))
    for ax, ns in zip(axs, (0.0, 0.5, 1.0, 1.5)):
        plot_top_view(ax, scene, PLANE_Z)
        for p0, p1 in paths.get(ns, []):
            ax.plot(p0[:, 0], p0[:, 1], "--", color="tab:blue", lw=0.8, alpha=0.7)
            ax.plot(p1[:, 0], p1[:, 1], "-", color="tab:red", lw=1.2)
        ax.plot(*start[:2], "ko", ms=4)
        ax.plot(goals[:, 0], goals[:, 1], "k*", ms=6)
        ax.set_title(f"n_sigma = {ns:g}")
        ax.set_xlim(-0.5, 0.5)
        ax.set_ylim(-0.5, 0.5)
        ax.set_aspect("equal")
    axs[0].plot([], [], "--", color="tab:blue", label="RRT")
    axs[0].plot([], [], "-", color="tab:red", label="refined")
    axs[0].legend(loc="lower left", fontsize=7)
    fig.tight_layout()
    fig.savefig(out_dir / "fig4_paths.png", dpi=120)
    plt.close(fig)
    return out
