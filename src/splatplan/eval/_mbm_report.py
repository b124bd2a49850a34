"""MotionBenchMaker benchmark: the summaries of its rows and the Markdown report."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._mbm_config import PUBLISHED, MBMConfig, MBMResult

__all__ = ["report", "summarise"]


def _pct(v: np.ndarray, q: float) -> float | None:
    return float(np.percentile(v, q)) if len(v) else None


def _rho(r: dict) -> float:
    """A row's measured rho (nan when not measured: the results file stores NaN as null)."""
    v = r.get("rho_measured_m")
    return float("nan") if v is None else float(v)


def _any_rho(rows: list[dict]) -> bool:
    """Whether rho was measured for any of the rows."""
    return any(np.isfinite(_rho(r)) for r in rows)


def summarise(rows: list[dict], time_limit: float | None = None) -> dict:
    """Valid / free endpoints, problems started (both endpoints free or escaped), solved / started, median / p95 time, worst clearance (for a list of
    rows); with ``time_limit`` (the iteration-budget mode), also how many solutions took longer."""
    n = len(rows)
    both_free = [r for r in rows if r["start_free"] and r["goal_free"]]
    started = [r for r in rows if r.get("started", r["start_free"] and r["goal_free"])]  # (rows from before escapes: both free)
    solved = [r for r in started if r["solved"]]
    t = np.array([r["time_s"] for r in solved], dtype=np.float64)
    clear = np.array([r["min_exact_clearance_m"] for r in solved], dtype=np.float64)
    return {
        "n_problems": n,
        "valid_endpoints": int(sum(r["start_valid"] + r["goal_valid"] for r in rows)),
        "valid_endpoints_frac": sum(r["start_valid"] + r["goal_valid"] for r in rows) / (2 * n) if n else None,
        "problems_both_valid": int(sum(r["start_valid"] and r["goal_valid"] for r in rows)),
        "free_endpoints": int(sum(r["start_free"] + r["goal_free"] for r in rows)),
        "free_endpoints_frac": sum(r["start_free"] + r["goal_free"] for r in rows) / (2 * n) if n else None,
        "free_endpoints_unmargined_frac": sum(r["start_free_unmargined"] + r["goal_free_unmargined"] for r in rows) / (2 * n) if n else None,
        "problems_both_free": len(both_free),
        "problems_started": len(started),
        "problems_escaped": len(started) - len([r for r in started if r["start_free"] and r["goal_free"]]),
        "solved": len(solved),
        "solved_of_started_frac": len(solved) / len(started) if started else None,
        "median_time_s": _pct(t, 50),
        "p95_time_s": _pct(t, 95),
        "median_cpu_s": _pct(np.array([r["cpu_s"] for r in solved if r.get("cpu_s") is not None], dtype=np.float64), 50),
        "median_configs": _pct(np.array([r["n_configs"] for r in solved if r.get("n_configs") is not None], dtype=np.float64), 50),
        "worst_exact_clearance_m": float(clear.min()) if len(clear) else None,
        "negative_clearance_paths": int(np.sum(clear < 0)),
        "solved_late": None if time_limit is None else int(np.sum(t > time_limit)),
        "margin_m_median": _pct(np.array([r["margin_m"] for r in rows]), 50),
        "rho_measured_m_max": float(np.nanmax([_rho(r) for r in rows])) if rows and _any_rho(rows) else None,
        "bound_holds": int(sum(bool(r["bound_holds"]) for r in rows)),
        "not_free_below_margin": _not_free_below_margin(rows),
        "blocked_by_link": _blocked_by_link(rows),
    }


def _blocked_by_link(rows: list[dict]) -> dict[str, int]:
    """How many endpoints that are not free each link blocks (``*_blocked_by``)."""
    out: dict[str, int] = {}
    for r in rows:
        for end in ("start", "goal"):
            b = r.get(f"{end}_blocked_by")
            if b:
                out[b["link"]] = out.get(b["link"], 0) + 1
    return dict(sorted(out.items(), key=lambda kv: -kv[1]))


def _not_free_below_margin(rows: list[dict]) -> int:
    """Endpoints that are not free for the planning model and whose exact clearance (own model vs
    the primitives) is below the row's margin: no check from the splats alone that keeps the
    zero-negative-clearance guarantee (margin >= rho + r/2) can call those free at this splat
    density; only more splats (rho ~ spacing ~ 1/sqrt(n_splats)) can."""
    n = 0
    for r in rows:
        for end in ("start", "goal"):
            c = r.get(f"{end}_clearance_m")
            n += int(not r[f"{end}_free"] and c is not None and c < r["margin_m"])
    return n


def _engine_text(e: dict | None) -> str:
    if not e or e.get("kind") != "dask":
        return "serial"
    return f"dask ({e.get('workers')} workers at {e.get('scheduler')})"


def _frac_pct(v) -> str:
    return "" if v is None else f" ({100 * v:.0f}%)"


def _fmt(v, spec: str, scale: float = 1.0, none: str = "-") -> str:
    return none if v is None else format(v * scale, spec)


def _margin_text(cfg: MBMConfig) -> str:
    if cfg.margin_m is not None:
        return format(cfg.margin_m, "g") + " m"
    f, fl = format(cfg.margin_spacing_factor, "g"), format(cfg.margin_floor_factor, "g")
    return f"derived (max({f} h - {cfg.n_sigma:g} s_t, {fl} h) + r/2)" if cfg.n_sigma > 0 else f"derived ({f} x NN spacing h + r/2)"


def _density_text(rows: list[dict], cfg: MBMConfig) -> str:
    """How densely the scenes were sampled: the fixed count, or the spacing and the counts it gave."""
    if cfg.n_splats:
        return f"{cfg.n_splats:,} splats per scene"
    n = [r["n_splats_sampled"] for r in rows if r.get("n_splats_sampled")]
    got = f" ({min(n):,}-{max(n):,} splats per scene)" if n else ""
    return f"sampled at {1e3 * cfg.splat_spacing_m:g} mm spacing{got}"


def report(result: MBMResult) -> str:
    """Markdown: one row per family and overall, then the published numbers and what differs."""
    cfg = result.config
    lines = [
        f"MBM on splats: {_density_text(result.rows, cfg)} (floaters: the paper's rule{', then isolated faint splats' if cfg.drop_isolated else ''}), n_sigma {cfg.n_sigma:g}, "
        f"margin {_margin_text(cfg)}, "
        f"time limit {cfg.time_limit:g} s{'' if cfg.max_iters is None else f' (searches run to {cfg.max_iters:,} iterations, no wall-clock limit)'}, robot {Path(result.setup.get('robot', '?')).name} ({result.setup.get('n_ellipsoids')} ellipsoids), "
        f"planner {cfg.planners[0]} (table below: every planner), engine {_engine_text(result.setup.get('engine'))}",
        "",
        "| family | problems | valid endpoints | free endpoints (own model) | both free | started (escapes) | solved / started | median time (s) | p95 time (s) | worst exact clearance (mm) | paths < 0 | margin (mm) | rho max (mm) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for fam, s in result.summary.items():
        n = s["n_problems"]
        if not n:
            continue
        lines.append(
            f"| {fam} | {n} | {s['valid_endpoints']}/{2 * n} ({100 * s['valid_endpoints_frac']:.0f}%) | "
            f"{s['free_endpoints']}/{2 * n} ({100 * s['free_endpoints_frac']:.0f}%; {100 * s['free_endpoints_unmargined_frac']:.0f}%) | {s['problems_both_free']} | "
            f"{s['problems_started']} ({s['problems_escaped']}) | {s['solved']}/{s['problems_started']}{_frac_pct(s['solved_of_started_frac'])} | "
            f"{_fmt(s['median_time_s'], '.3g')} | {_fmt(s['p95_time_s'], '.3g')} | {_fmt(s['worst_exact_clearance_m'], '+.2f', 1e3)} | "
            f"{s['negative_clearance_paths']} | {_fmt(s['margin_m_median'], '.1f', 1e3)} | {_fmt(s['rho_measured_m_max'], '.1f', 1e3)} |"
        )
    o = result.summary.get("overall", {})
    if o.get("n_problems") and o.get("not_free_below_margin") is not None:
        n_not = 2 * o["n_problems"] - o["free_endpoints"]
        lines += ["", f"Endpoints not free for the planning model: {n_not}; of them {o['not_free_below_margin']} lie closer to the "
                      "real geometry (exact clearance) than the margin, so the planning model, whose margin carries the guarantee, cannot "
                      "hold them at this splat density (the margin scales with the splat spacing, ~1/sqrt(n_splats)); an escape "
                      "segment, checked at a finer resolution with a smaller margin (where that is not enough, at a higher n_sigma, "
                      "whose splat ellipsoids cover the surface more closely), opens the problems counted under escapes."]  # fmt: skip
    late = result.summary.get("overall", {}).get("solved_late")
    if late is not None:
        lines += ["", (f"Searches ran to {cfg.max_iters:,} iterations with no wall-clock limit (reproducible anywhere): "
                       f"{late} of the solutions took longer than the {cfg.time_limit:g} s time limit on this machine.")]  # fmt: skip
    if result.summary_by_planner:
        lines += ["", "Planners (same splats, checker, margin, edge resolution and time limit; ours seeded, OMPL's not):", "",
                  "| planner | family | solved / started | median time (s) | p95 time (s) | worst exact clearance (mm) | paths < 0 |",
                  "|---|---|---|---|---|---|---|"]  # fmt: skip
        for p, per in result.summary_by_planner.items():
            for fam, s in per.items():
                if not s["n_problems"]:
                    continue
                lines.append(f"| {p} | {fam} | {s['solved']}/{s['problems_started']}{_frac_pct(s['solved_of_started_frac'])} | "
                             f"{_fmt(s['median_time_s'], '.3g')} | {_fmt(s['p95_time_s'], '.3g')} | "
                             f"{_fmt(s['worst_exact_clearance_m'], '+.2f', 1e3)} | {s['negative_clearance_paths']} |")  # fmt: skip
    if result.failures:
        lines += ["", f"{len(result.failures)} task(s) failed (see failures in mbm.json): "
                  + "; ".join(f"{f['family']}/{f['index']} {f['planner']}: {f['error'][:120]}" for f in result.failures[:5])]  # fmt: skip
    lines += ["", "Published (same benchmark, 7 families x 100 problems; see ../shared/data/mbm/README.md):", "",
              "| planner | solved | median time | p95 time | robot model | scene | hardware |", "|---|---|---|---|---|---|---|"]  # fmt: skip
    for name, ref in PUBLISHED.items():
        lines.append(f"| {name} | {ref['solved']} | {_fmt(ref['median_time_s'], '.3g')} s | {_fmt(ref['p95_time_s'], '.3g')} s | {ref['robot_model']} | {ref['scene']} | {ref['hardware']} |")
    lines += [
        "",
        "What differs here: the scene is splats sampled from the exact primitives (the published planners check the primitives "
        "themselves or a point cloud); the robot is the URDF's ellipsoid model grown by the safety margin; collision checks run "
        "on this machine's shared CPU cores (Warp kernels), timings are contended; only the families listed above were run.",
        "",
    ]
    return "\n".join(lines)
