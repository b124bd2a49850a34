"""Why CollisionSplatting's E1 average precision trails SPLANNING's (issue #34, part 3).

Study E1 (``splatplan eval pr``) reports AP 0.969 for CollisionSplatting at n_sigma = 1 against
0.992 for SPLANNING. This script explains the gap with measurements, on E1's own scene, query grid,
exact labels and scores (it imports :class:`~splatplan.eval._pr_scoring.PRSetup`,
:func:`~splatplan.eval._pr_scoring.cs_query`, the culled SPLANNING evaluation of
:mod:`~splatplan.eval._pr_culling` and the metrics of :mod:`~splatplan.eval._pr_metrics`; nothing of
the protocol is re-implemented):

1. **Operating points**: precision, FP and FN counts at the threshold giving recall 0.95 and at the
   best-F1 threshold, for CollisionSplatting (n_sigma 0 and 1, and the opacity-scaled variant d2)
   and SPLANNING.
2. **Where the errors come from** (CollisionSplatting n_sigma = 1, default scene): every false
   positive / negative by the query's exact clearance (sdf - r), by the splat that decides its score
   (argmin over splats of s2~: floater or surface, opacity, size, the inflation n_sigma * s_d / r
   with s_d the splat's std along the query direction, and whether the query collides with the
   splat's *mean* at all, i.e. at n_sigma = 0), and by where it is (ground or stone, nearest stone).
3. **What the opacity-scaled variant changes**: FPs at recall 0.95 removed and added, by category.
4. **Metric, scene or grid?** The comparison rerun (CollisionSplatting n_sigma 0/1, d2, SPLANNING)
   on the same queries and labels with the scene changed toward a trained scene (floaters removed;
   surface splats opaque; the needle tail of the size distribution clipped; all splats halved), on
   the evaluation set with the near-boundary free queries left out, and on the lattice shifted by
   half a cell.

Writes ``pr_gap.json`` and ``pr_gap.md`` (date, machine, every number quoted) into ``--out``.

    python benchmarks/pr_gap.py --out benchmarks/results          # full (E1's full grid)
    python benchmarks/pr_gap.py --quick --out /tmp/pr_gap         # smoke (E1's quick settings)
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

RECALL_TARGET = 0.95


# ---------------------------------------------------------------------------------------------
# scoring (E1's own functions)
# ---------------------------------------------------------------------------------------------


def cs_scores(splats, q: np.ndarray, r: float, device: str, n_sigma: float, **changes) -> tuple[np.ndarray, np.ndarray]:
    """CollisionSplatting (-softmin, min_s2) on ``q`` with E1's ``cs_query``."""
    from splatplan.eval._pr_scoring import cs_query
    from splatplan.metric import CollisionChecker

    chk = CollisionChecker(splats, n_sigma=1.0, device=device).with_config(n_sigma=float(n_sigma), **changes)
    min_s2, soft = cs_query(chk, q, r, f"CS n_sigma={n_sigma:g} {changes or ''}")
    return -soft, min_s2


def splanning_scores(splats, q: np.ndarray, r: float, cfg) -> np.ndarray:
    """SPLANNING's collision score on ``q`` with E1's culled evaluation (no clamp: the full score)."""
    import torch

    from splatplan.baselines import BASELINES, as_scene_tensors
    from splatplan.eval._pr_culling import cull_rule, culled_collision_scores

    info = BASELINES["splanning"]
    scene_t = as_scene_tensors(splats, "cpu", torch.float32)
    incl, clamp, _ = cull_rule("splanning", info.cls(scene_t, "cpu"), r)
    s, _, _ = culled_collision_scores(info.cls, scene_t, incl, clamp, q, r, cfg.tile, cfg.block, desc="SPLANNING")
    return s


def operating_points(score: np.ndarray, y: np.ndarray, native: np.ndarray | None = None) -> dict[str, Any]:
    """AP, and (threshold, P, R, FP, FN, predicted mask) at recall >= 0.95, at best F1 and (given
    ``native``, the method's own binary decision) at its own rule."""
    from splatplan.eval._pr_metrics import average_precision, best_f1, precision_recall_curve

    p, rc, thr = precision_recall_curve(score, y)
    out: dict[str, Any] = {"ap": average_precision(p, rc)}
    f1, kf = best_f1(p, rc)
    kr = int(np.argmax(rc >= RECALL_TARGET))
    for name, k in (("recall95", kr), ("best_f1", kf)):
        pred = score >= thr[k]
        out[name] = {
            "threshold": float(thr[k]),
            "precision": float(p[k]),
            "recall": float(rc[k]),
            "f1": float(2 * p[k] * rc[k] / (p[k] + rc[k])) if p[k] + rc[k] > 0 else 0.0,
            "n_fp": int(np.sum(pred & ~y)),
            "n_fn": int(np.sum(~pred & y)),
            "_pred": pred,
        }
    out["best_f1"]["f1"] = f1
    if native is not None:
        tp, fp_, fn_ = int(np.sum(native & y)), int(np.sum(native & ~y)), int(np.sum(~native & y))
        out["own_rule"] = {"precision": tp / max(tp + fp_, 1), "recall": tp / max(tp + fn_, 1), "n_fp": fp_, "n_fn": fn_}
    return out


def strip(d: Any) -> Any:
    """``d`` without the private (``_``) entries, for the JSON."""
    if isinstance(d, dict):
        return {k: strip(v) for k, v in d.items() if not str(k).startswith("_")}
    return d


# ---------------------------------------------------------------------------------------------
# the splat that decides a query's score
# ---------------------------------------------------------------------------------------------


def deciding_splats(splats, q: np.ndarray, r: float, n_sigma: float, ns_per_splat: np.ndarray | None = None, cap: float = 4.0) -> dict[str, np.ndarray]:
    """Per query: the splat with the smallest s2~ (exact: every splat that can have s2~ < cap is
    a candidate), its s2~, its s2 (n_sigma = 0), the number of splats with s2~ < 1 and the smallest
    plain s2 over all candidates (does the query touch any splat *mean*?)."""
    from scipy.spatial import cKDTree

    from splatplan.metric.reference import conservative_s2_ref

    n = len(splats)
    ns = np.full(n, float(n_sigma)) if ns_per_splat is None else np.asarray(ns_per_splat, np.float64)
    smax = splats.scales.max(1).astype(np.float64)
    # two tiers: a KD-tree for splats up to the 99.5th percentile of size, the rest always checked
    s_cut = float(np.percentile(smax, 99.5))
    big = np.nonzero(smax > s_cut)[0]
    small = np.nonzero(smax <= s_cut)[0]
    k = float(ns.max()) * s_cut
    rho = k + np.sqrt(k * k + cap * r * r)
    tree = cKDTree(splats.means[small].astype(np.float64))
    A = np.eye(3)[None] / (r * r)
    out = {k_: np.empty(len(q)) for k_ in ("s2t", "s2", "min_plain_s2")}
    out["idx"] = np.empty(len(q), np.int64)
    out["n_colliding"] = np.empty(len(q), np.int64)
    lists = tree.query_ball_point(q, rho)
    for i in range(len(q)):
        cand = np.r_[small[np.asarray(lists[i], np.int64)], big]
        s2, s2t = conservative_s2_ref(splats.means[cand], splats.quats[cand], splats.scales[cand], q[i : i + 1], A, ns[cand])
        j = int(np.argmin(s2t[0]))
        out["idx"][i] = cand[j]
        out["s2t"][i] = s2t[0, j]
        out["s2"][i] = s2[0, j]
        out["n_colliding"][i] = int(np.sum(s2t[0] < 1.0))
        out["min_plain_s2"][i] = float(s2[0].min())
    return out


def std_along(splats, idx: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Std of splat ``idx`` along the direction from the query to its mean (scene units)."""
    from splatplan.scenes.splats import quat_to_rotmat

    d = splats.means[idx].astype(np.float64) - q
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    rot = quat_to_rotmat(splats.quats[idx].astype(np.float64))  # (n, 3, 3)
    local = np.einsum("nji,nj->ni", rot, d)
    return np.linalg.norm(local * splats.scales[idx].astype(np.float64), axis=1)


def dist_to_ellipsoid(splats, idx: np.ndarray, q: np.ndarray, k: float = 1.0) -> np.ndarray:
    """Exact Euclidean distance from each query to the k-sigma ellipsoid of splat ``idx`` (0 inside),
    by bisection on the Lagrange multiplier (no linearisation)."""
    from splatplan.scenes.splats import quat_to_rotmat

    rot = quat_to_rotmat(splats.quats[idx].astype(np.float64))
    y = np.abs(np.einsum("nji,nj->ni", rot, q - splats.means[idx].astype(np.float64)))  # local frame, by symmetry >= 0
    a = np.maximum(k * splats.scales[idx].astype(np.float64), 1e-12)
    inside = np.sum((y / a) ** 2, 1) <= 1.0
    lo, hi = np.zeros(len(y)), np.linalg.norm(y, axis=1) * a.max(1) + 1e-30
    for _ in range(100):
        t = 0.5 * (lo + hi)
        f = np.sum((a * y / (a * a + t[:, None])) ** 2, 1)
        lo, hi = np.where(f > 1.0, t, lo), np.where(f > 1.0, hi, t)
    t = 0.5 * (lo + hi)
    x = a * a * y / (a * a + t[:, None])
    return np.where(inside, 0.0, np.linalg.norm(y - x, axis=1))


def bin_counts(x: np.ndarray, edges: list[float], labels: list[str]) -> dict[str, int]:
    """Counts of ``x`` in [edges[k], edges[k+1])."""
    b = np.digitize(x, edges[1:-1])
    return {lab: int(np.sum(b == k)) for k, lab in enumerate(labels)}


def nearest_label(geom, pts: np.ndarray) -> np.ndarray:
    """Label of the nearest primitive of the analytic scene for each point."""
    if len(pts) == 0:
        return np.array([], dtype=object)
    d = np.stack([geom.sdf(pts, box_ids=np.array([i])) for i in range(len(geom.boxes))], 1)  # (P, M)
    return np.asarray(geom.labels, dtype=object)[np.argmin(d, 1)]


# ---------------------------------------------------------------------------------------------
# the study
# ---------------------------------------------------------------------------------------------


def _clip_tail(splats, pct: float):
    """Splats with every std clipped at the ``pct`` percentile of the largest std."""
    s = splats.scales.copy()
    cap = float(np.percentile(s.max(1), pct))
    return replace(splats, scales=np.minimum(s, cap).astype(s.dtype)), cap


def _opaque(splats, surface: np.ndarray):
    o = splats.opacities.copy()
    o[surface] = 1.0
    return replace(splats, opacities=o)


def run_study(quick: bool = False, log=print) -> dict[str, Any]:
    from splatplan.eval._pr_config import PRConfig
    from splatplan.eval._pr_scoring import PRSetup
    from splatplan.scenes.builtin.stonehenge import build_stonehenge

    t_all = time.perf_counter()
    cfg = (PRConfig.quick_config() if quick else PRConfig()).validate()
    st = PRSetup(cfg)
    _, geom = build_stonehenge(level=cfg.level, seed=cfg.seed, n_splats=cfg.n_splats)
    r, dev = float(cfg.radius), cfg.device
    q, y = st.q, st.y
    sdf = st.sdf[st.reach]
    clr = sdf - r  # exact clearance of the sphere (< 0: collides)
    sp = st.splats
    n = len(sp)
    n_kept_fl = int(sp.info.get("n_floaters", 0)) - int(st.rep.n_dropped)
    floater = np.zeros(n, bool)
    if n_kept_fl > 0:
        floater[n - n_kept_fl :] = True
    smax = sp.scales.max(1).astype(np.float64)
    med = float(np.median(smax[~floater]))
    gid = [i for i, lab in enumerate(geom.labels) if lab == "ground"]
    ground_splat = (np.abs(geom.sdf(sp.means.astype(np.float64), box_ids=np.array(gid))) < np.abs(geom.sdf(sp.means.astype(np.float64))) + 1e-9) & ~floater
    log(f"scene: {n} splats ({n_kept_fl} kept floaters), {len(q)} queries, {int(y.sum())} positive")

    # ---- 1. scores and operating points ---------------------------------------------------
    t0 = time.perf_counter()
    scores: dict[str, np.ndarray] = {}
    native: dict[str, np.ndarray] = {}
    scores["cs_ns1"], m1 = cs_scores(sp, q, r, dev, 1.0)
    scores["cs_ns0"], m0 = cs_scores(sp, q, r, dev, 0.0)
    scores["cs_ns1_d2"], md2 = cs_scores(sp, q, r, dev, 1.0, opacity_scaled_inflation=True)
    native.update({"cs_ns1": m1 < 1.0, "cs_ns0": m0 < 1.0, "cs_ns1_d2": md2 < 1.0})  # collision iff min_s2 < 1
    t_cs = time.perf_counter() - t0
    t0 = time.perf_counter()
    scores["splanning"] = splanning_scores(sp, q, r, cfg)
    from splatplan.baselines import BASELINES

    native["splanning"] = scores["splanning"] > BASELINES["splanning"].collision_threshold
    t_spl = time.perf_counter() - t0
    log(f"scores: CS {t_cs:.1f} s, SPLANNING {t_spl:.1f} s")
    ops = {k: operating_points(v, y, native[k]) for k, v in scores.items()}
    for k, v in ops.items():
        log(f"  {k:12s} AP {v['ap']:.4f}  P@R95 {v['recall95']['precision']:.4f} (FP {v['recall95']['n_fp']}, FN {v['recall95']['n_fn']})  best F1 {v['best_f1']['f1']:.4f} (FP {v['best_f1']['n_fp']}, FN {v['best_f1']['n_fn']})")

    # ---- 2. where CS n_sigma=1's errors come from --------------------------------------------
    t0 = time.perf_counter()
    o1 = ops["cs_ns1"]
    clr_edges = [-np.inf, -2 * r, -r, 0.0, 0.0025, 0.005, 0.01, 0.02, 0.04, np.inf]
    clr_labels = ["< -2r (deep)", "[-2r, -r)", "[-r, 0)", "[0, 2.5 mm)", "[2.5, 5 mm)", "[5, 10 mm)", "[10, 20 mm)", "[20, 40 mm)", ">= 40 mm"]
    clr_labels = [f"clearance {s}" for s in clr_labels]
    clearance = {
        "edges_scene_units": [float(e) for e in clr_edges],
        "all_queries": bin_counts(clr, clr_edges, clr_labels),
    }
    for m in ("cs_ns1", "cs_ns1_d2", "splanning"):
        for opn in ("recall95", "best_f1"):
            pred = ops[m][opn]["_pred"]
            clearance[f"{m}_{opn}_fp"] = bin_counts(clr[pred & ~y], clr_edges, clr_labels)
            clearance[f"{m}_{opn}_fn"] = bin_counts(clr[~pred & y], clr_edges, clr_labels)

    # deciding splat of every error of CS n_sigma=1 (both operating points) and of its TPs near the boundary as reference
    err_idx = {}
    for opn in ("recall95", "best_f1"):
        pred = o1[opn]["_pred"]
        err_idx[f"{opn}_fp"] = np.nonzero(pred & ~y)[0]
        err_idx[f"{opn}_fn"] = np.nonzero(~pred & y)[0]
    union = np.unique(np.concatenate(list(err_idx.values())))
    dec = deciding_splats(sp, q[union], r, 1.0)
    pos_of = {int(g): i for i, g in enumerate(union)}
    sd_all = std_along(sp, dec["idx"], q[union])
    sdf_mu = geom.sdf(sp.means[dec["idx"]].astype(np.float64))  # offset of the deciding splat from the true surface
    where_lab = nearest_label(geom, q[union])
    splat_lab = np.where(floater[dec["idx"]], "floater", nearest_label(geom, sp.means[dec["idx"]].astype(np.float64)))  # where the deciding splat sits
    ell1 = dist_to_ellipsoid(sp, dec["idx"], q[union], 1.0)  # exact distance to its 1-sigma body
    t_dec = time.perf_counter() - t0

    op_edges = [0.0, 0.1, 0.3, 0.6, 0.9, 1.01]
    op_labels = ["o < 0.1", "0.1 <= o < 0.3", "0.3 <= o < 0.6", "0.6 <= o < 0.9", "o >= 0.9"]
    sz_edges = [0.0, 1.0, 2.0, 4.0, 8.0, np.inf]
    sz_labels = ["max std < 1x median", "1-2x median", "2-4x median", "4-8x median", ">= 8x median"]
    inf_edges = [0.0, 0.1, 0.25, 0.5, 1.0, np.inf]
    inf_labels = ["n s_d / r < 0.1", "0.1-0.25", "0.25-0.5", "0.5-1", ">= 1"]

    def breakdown(gidx: np.ndarray) -> dict[str, Any]:
        ii = np.array([pos_of[int(g)] for g in gidx], np.int64)
        if len(ii) == 0:
            return {"n": 0}
        j = dec["idx"][ii]
        infl = 1.0 * sd_all[ii] / r
        fl = floater[j]
        labs, cnt = np.unique(where_lab[ii], return_counts=True)
        z = q[gidx, 2]
        return {
            "n": int(len(ii)),
            "deciding_splat_floater": int(fl.sum()),
            "deciding_splat_surface": int((~fl).sum()),
            "distinct_deciding_splats": int(len(np.unique(j))),
            "distinct_deciding_floaters": int(len(np.unique(j[fl]))),
            "opacity": bin_counts(sp.opacities[j].astype(np.float64), op_edges, op_labels),
            "size_vs_median": bin_counts(smax[j] / med, sz_edges, sz_labels),
            "inflation_vs_r": bin_counts(infl, inf_edges, inf_labels),
            "median_deciding_max_std": float(np.median(smax[j])),
            "median_deciding_std_along_query": float(np.median(sd_all[ii])),
            "median_deciding_opacity": float(np.median(sp.opacities[j])),
            "median_deciding_splat_offset_from_surface": float(np.median(np.abs(sdf_mu[ii]))),
            "touches_a_splat_mean_at_nsigma0": int(np.sum(dec["min_plain_s2"][ii] < 1.0)),
            "only_by_inflation": int(np.sum(dec["min_plain_s2"][ii] >= 1.0)),
            "median_n_colliding": float(np.median(dec["n_colliding"][ii])),
            "within_r_of_deciding_1sigma_ellipsoid": int(np.sum(ell1[ii] < r)),
            "beyond_r_of_deciding_1sigma_ellipsoid": int(np.sum(ell1[ii] >= r)),
            "median_dist_to_deciding_1sigma_ellipsoid_minus_r": float(np.median(ell1[ii] - r)),
            "deciding_splat_on": {str(a): int(b) for a, b in zip(*np.unique(splat_lab[ii], return_counts=True))},
            "query_z": {f"{a:.4f}": int(b) for a, b in sorted(zip(*np.unique(np.round(z, 5), return_counts=True)), key=lambda t: -t[1])[:6]},
            "n_colliding_0": int(np.sum(dec["n_colliding"][ii] == 0)),
            "ground_z_le_r": int(np.sum(z <= r)),
            "above_ground": int(np.sum(z > r)),
            "nearest_primitive": {str(a): int(b) for a, b in sorted(zip(labs, cnt), key=lambda t: -t[1])},
            "median_clearance": float(np.median(clr[gidx])),
        }

    errors = {k: breakdown(v) for k, v in err_idx.items()}
    # base rates over the scene's splats (what a random splat looks like)
    base = {
        "n_splats": n,
        "n_kept_floaters": n_kept_fl,
        "median_max_std": med,
        "opacity": bin_counts(sp.opacities.astype(np.float64), op_edges, op_labels),
        "size_vs_median": bin_counts(smax / med, sz_edges, sz_labels),
        "floater_max_std": [float(v) for v in np.sort(smax[floater])],
        "ground_splats": int(np.sum(ground_splat)),
        "median_max_std_ground": float(np.median(smax[ground_splat])),
        "median_max_std_stones": float(np.median(smax[~ground_splat & ~floater])),
        "p99_max_std_ground": float(np.percentile(smax[ground_splat], 99)),
        "p99_max_std_stones": float(np.percentile(smax[~ground_splat & ~floater], 99)),
        "floater_opacity": [float(v) for v in np.sort(sp.opacities[floater])],
    }
    log(f"deciding splats: {len(union)} error queries in {t_dec:.1f} s")

    # ---- 3. what d2 (opacity-scaled inflation) changes at recall 0.95 -----------------------
    fp_a = o1["recall95"]["_pred"] & ~y
    fp_d = ops["cs_ns1_d2"]["recall95"]["_pred"] & ~y
    removed = np.nonzero(fp_a & ~fp_d)[0]
    added = np.nonzero(~fp_a & fp_d)[0]
    kept = np.nonzero(fp_a & fp_d)[0]
    d2 = {"fp_default": int(fp_a.sum()), "fp_d2": int(fp_d.sum()), "removed": breakdown(removed), "kept": breakdown(kept), "added": {"n": int(len(added))}}
    if len(added):
        dec_add = deciding_splats(sp, q[added], r, 1.0, ns_per_splat=sp.opacities.astype(np.float64))
        d2["added"].update(
            {
                "deciding_splat_floater": int(floater[dec_add["idx"]].sum()),
                "median_deciding_opacity": float(np.median(sp.opacities[dec_add["idx"]])),
                "median_clearance": float(np.median(clr[added])),
                "clearance": bin_counts(clr[added], clr_edges, clr_labels),
            }
        )

    # ---- 4a. scene counterfactuals (same queries, same labels) ------------------------------
    t0 = time.perf_counter()
    surface_idx = np.nonzero(~floater)[0]
    no_fl = sp.subset(surface_idx)
    opaque = _opaque(no_fl, np.ones(len(no_fl), bool))
    clipped, clip_cap = _clip_tail(no_fl, 95.0)
    halved = replace(no_fl, scales=(no_fl.scales * 0.5).astype(no_fl.scales.dtype))
    trained, _ = _clip_tail(opaque, 95.0)
    scenes = {
        "default": ("today's E1 scene", sp, True),
        "no_floaters": (f"the {n_kept_fl} kept floaters removed", no_fl, True),
        "no_floaters_opaque": ("no floaters, every surface splat opacity 1", opaque, False),
        "no_floaters_tail_clipped": (f"no floaters, every std clipped at the p95 largest std ({clip_cap:.4f})", clipped, False),
        "no_floaters_halved": ("no floaters, every std x 0.5", halved, False),
        "trained_like": ("no floaters, opacity 1, stds clipped at p95 (small, opaque surface splats)", trained, True),
    }
    scene_rows = {}
    for key, (label, s_, with_spl) in scenes.items():
        row: dict[str, Any] = {"label": label, "n_splats": len(s_), "median_max_std": float(np.median(s_.scales.max(1))), "p99_max_std": float(np.percentile(s_.scales.max(1), 99))}
        if key == "default":
            sc = {k: scores[k] for k in ("cs_ns0", "cs_ns1", "cs_ns1_d2", "splanning")}
        else:
            sc = {"cs_ns0": cs_scores(s_, q, r, dev, 0.0)[0], "cs_ns1": cs_scores(s_, q, r, dev, 1.0)[0], "cs_ns1_d2": cs_scores(s_, q, r, dev, 1.0, opacity_scaled_inflation=True)[0]}
            if with_spl or quick:
                sc["splanning"] = splanning_scores(s_, q, r, cfg)
        for k, v in sc.items():
            o = operating_points(v, y)
            row[k] = {"ap": o["ap"], "best_f1": o["best_f1"]["f1"], "precision_at_recall95": o["recall95"]["precision"], "fp_at_recall95": o["recall95"]["n_fp"]}
        if "splanning" in row:
            row["cs_ns1_minus_splanning_ap"] = row["cs_ns1"]["ap"] - row["splanning"]["ap"]
        scene_rows[key] = row
        log(f"  scene {key:26s} " + "  ".join(f"{k} {row[k]['ap']:.4f}" for k in sc))
    t_scenes = time.perf_counter() - t0

    # ---- 4b. the evaluation set and grid -------------------------------------------------------
    t0 = time.perf_counter()
    grid_rows: dict[str, Any] = {}
    from splatplan.eval._pr_metrics import average_precision, precision_recall_curve

    def ap_on(mask: np.ndarray) -> dict[str, float]:
        return {k: average_precision(*precision_recall_curve(v[mask], y[mask])[:2]) for k, v in scores.items()}

    for delta in (0.0025, 0.005, 0.01, 0.02):
        keep = ~((clr >= 0) & (clr < delta))
        grid_rows[f"without_free_within_{delta * 1000:g}mm"] = {"n_queries": int(keep.sum()), "n_removed": int((~keep).sum()), "ap": ap_on(keep)}
    above = q[:, 2] > r
    grid_rows["above_ground"] = {"n_queries": int(above.sum()), "n_positive": int(y[above].sum()), "ap": ap_on(above)}
    grid_rows["ground_z_le_r"] = {"n_queries": int((~above).sum()), "n_positive": int(y[~above].sum()), "ap": ap_on(~above)}
    # the lattice shifted by half a cell (a different pad moves the lattice origin): E1's own setup
    shift_pad = cfg.pad + 0.5 * cfg.spacing / r
    st2 = PRSetup(replace(cfg, pad=shift_pad))
    q2, y2 = st2.q, st2.y
    sc2 = {"cs_ns0": cs_scores(sp, q2, r, dev, 0.0)[0], "cs_ns1": cs_scores(sp, q2, r, dev, 1.0)[0], "cs_ns1_d2": cs_scores(sp, q2, r, dev, 1.0, opacity_scaled_inflation=True)[0], "splanning": splanning_scores(sp, q2, r, cfg)}
    grid_rows["lattice_shifted_half_cell"] = {"pad": shift_pad, "n_queries": int(len(q2)), "n_positive": int(y2.sum()), "ap": {k: operating_points(v, y2)["ap"] for k, v in sc2.items()}}
    # how much of the evaluation set is near the boundary
    grid_rows["query_distribution"] = {
        "negatives": int((~y).sum()),
        "negatives_within_5mm": int(np.sum((clr >= 0) & (clr < 0.005))),
        "negatives_within_10mm": int(np.sum((clr >= 0) & (clr < 0.01))),
        "positives": int(y.sum()),
        "positives_within_5mm_of_boundary": int(np.sum((clr < 0) & (clr >= -0.005))),
    }
    zs, zc = np.unique(np.round(q[:, 2], 6), return_counts=True)
    grid_rows["z_layers"] = {
        f"{z:.4f}": {"n": int(c), "clearance_over_ground_mm": float((z - r) * 1000), "fp_cs_ns1_recall95": int(np.sum(fp_a & (np.abs(q[:, 2] - z) < 1e-6))), "fp_splanning_recall95": int(np.sum(ops["splanning"]["recall95"]["_pred"] & ~y & (np.abs(q[:, 2] - z) < 1e-6)))}
        for z, c in zip(zs, zc)
        if z < 6 * r
    }
    t_grid = time.perf_counter() - t0
    log("  grid: " + "; ".join(f"{k}: " + ", ".join(f"{m} {a:.4f}" for m, a in v["ap"].items()) for k, v in grid_rows.items() if "ap" in v))

    return {
        "study": "E1 precision-recall gap of CollisionSplatting against SPLANNING (issue #34, part 3)",
        "date_utc": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, {platform.platform()}, Python {platform.python_version()}",
        "device": dev,
        "quick": bool(quick),
        "scene": st.scene_name,
        "e1_config": {"spacing": cfg.spacing, "radius": r, "n_splats": cfg.n_splats, "pad": cfg.pad, "tile": cfg.tile, "block": cfg.block},
        "n_queries": int(len(q)),
        "n_positive": int(y.sum()),
        "recall_target": RECALL_TARGET,
        "operating_points": {k: strip(v) for k, v in ops.items()},
        "clearance": clearance,
        "errors_cs_ns1": errors,
        "splat_base_rates": base,
        "d2_vs_default_at_recall95": d2,
        "scenes": scene_rows,
        "grid": grid_rows,
        "seconds": {"scores_cs": t_cs, "scores_splanning": t_spl, "deciding_splats": t_dec, "scenes": t_scenes, "grid": t_grid, "total": time.perf_counter() - t_all},
    }


# ---------------------------------------------------------------------------------------------
# report
# ---------------------------------------------------------------------------------------------

NAMES = {"cs_ns1": "CollisionSplatting n_sigma=1", "cs_ns0": "CollisionSplatting n_sigma=0", "cs_ns1_d2": "CS n_sigma=1, opacity-scaled (d2)", "splanning": "SPLANNING"}


def _zs(e: dict) -> str:
    return ", ".join(f"{z} ({c:,})" for z, c in list(e.get("query_z", {}).items())[:3])


def _pct(a: float, b: float) -> str:
    return f"{100.0 * a / b:.0f}%" if b else "-"


def markdown(res: dict[str, Any]) -> str:
    ops, err, sc, gr, d2 = res["operating_points"], res["errors_cs_ns1"], res["scenes"], res["grid"], res["d2_vs_default_at_recall95"]
    L = [
        "# E1 precision-recall gap: why CollisionSplatting trails SPLANNING",
        "",
        f"Run {res['date_utc']} on {res['machine']} ({'quick: E1 quick settings' if res['quick'] else 'full: E1 full settings'}; "
        f"{res['seconds']['total']:.0f} s). Scene: {res['scene']} ({res['splat_base_rates']['n_splats']:,} splats after the default floater filter, "
        f"{res['splat_base_rates']['n_kept_floaters']} kept floaters), r = {res['e1_config']['radius']}, grid spacing {res['e1_config']['spacing']}; "
        f"E1's evaluation set: {res['n_queries']:,} queries, {res['n_positive']:,} colliding. Scene, queries, labels and scores are E1's own "
        "(`PRSetup`, `cs_query`, the culled SPLANNING evaluation); `python benchmarks/pr_gap.py`.",
        "",
        "## 1. Operating points",
        "",
        "| method | AP | precision at recall 0.95 | FP / FN there | best F1 | FP / FN there | own rule P / R | FP / FN there |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for k, v in ops.items():
        a, b, c = v["recall95"], v["best_f1"], v["own_rule"]
        L.append(f"| {NAMES[k]} | {v['ap']:.4f} | {a['precision']:.4f} | {a['n_fp']:,} / {a['n_fn']:,} | {b['f1']:.4f} | {b['n_fp']:,} / {b['n_fn']:,} | {c['precision']:.3f} / {c['recall']:.4f} | {c['n_fp']:,} / {c['n_fn']:,} |")
    L += ["", "Own rule: CollisionSplatting collision iff min_s2 < 1; SPLANNING p > its threshold (as in E1)."]
    c1, spl = ops["cs_ns1"], ops["splanning"]
    L += [
        "",
        f"AP gap CollisionSplatting n_sigma=1 - SPLANNING: {c1['ap'] - spl['ap']:+.4f}. At recall 0.95 ours makes {c1['recall95']['n_fp']:,} false positives "
        f"against SPLANNING's {spl['recall95']['n_fp']:,}; at n_sigma = 0 (the point cloud of splat means) AP is {ops['cs_ns0']['ap']:.4f}.",
        "",
        "## 2. Where CollisionSplatting n_sigma=1's errors come from",
        "",
        "By the query's exact clearance (sdf - r; < 0 collides):",
        "",
    ]
    cl = res["clearance"]
    keys = list(cl["all_queries"])
    cols = ["all_queries", "cs_ns1_recall95_fp", "cs_ns1_recall95_fn", "cs_ns1_best_f1_fp", "cs_ns1_best_f1_fn", "splanning_recall95_fp", "splanning_recall95_fn", "cs_ns1_d2_recall95_fp"]
    L.append("| clearance | " + " | ".join(c.replace("cs_ns1_d2", "d2").replace("cs_ns1", "ours").replace("_", " ") for c in cols) + " |")
    L.append("|---" * (len(cols) + 1) + "|")
    for kk in keys:
        L.append(f"| {kk.replace('clearance ', '')} | " + " | ".join(f"{cl[c][kk]:,}" for c in cols) + " |")
    fp, fn = err["recall95_fp"], err["recall95_fn"]
    fpb = err["best_f1_fp"]
    base = res["splat_base_rates"]
    L += [
        "",
        "By the splat that decides the score (argmin over splats of s2~ at n_sigma = 1; 'inflation' = n_sigma s_d / r, s_d the splat's std along the query direction):",
        "",
        "| | FP at recall 0.95 | FN at recall 0.95 | FP at best F1 | all splats |",
        "|---|---|---|---|---|",
        f"| queries | {fp['n']:,} | {fn['n']:,} | {fpb['n']:,} | - |",
        f"| deciding splat is a kept floater | {fp.get('deciding_splat_floater', 0):,} ({_pct(fp.get('deciding_splat_floater', 0), fp['n'])}) | {fn.get('deciding_splat_floater', 0):,} | {fpb.get('deciding_splat_floater', 0):,} ({_pct(fpb.get('deciding_splat_floater', 0), fpb['n'])}) | {base['n_kept_floaters']} of {base['n_splats']:,} |",
        f"| distinct deciding splats (floaters) | {fp.get('distinct_deciding_splats', 0):,} ({fp.get('distinct_deciding_floaters', 0)}) | {fn.get('distinct_deciding_splats', 0):,} | {fpb.get('distinct_deciding_splats', 0):,} ({fpb.get('distinct_deciding_floaters', 0)}) | |",
        f"| free only because of the inflation (no splat mean within r) | {fp.get('only_by_inflation', 0):,} ({_pct(fp.get('only_by_inflation', 0), fp['n'])}) | - | {fpb.get('only_by_inflation', 0):,} ({_pct(fpb.get('only_by_inflation', 0), fpb['n'])}) | |",
        f"| median opacity of the deciding splat | {fp.get('median_deciding_opacity', float('nan')):.2f} | {fn.get('median_deciding_opacity', float('nan')):.2f} | {fpb.get('median_deciding_opacity', float('nan')):.2f} | {float(np.median(list(base['opacity'].values()))):.0f} (see bins) |",
        f"| median largest std of the deciding splat (median splat: {base['median_max_std']:.4f}) | {fp.get('median_deciding_max_std', float('nan')):.4f} | {fn.get('median_deciding_max_std', float('nan')):.4f} | {fpb.get('median_deciding_max_std', float('nan')):.4f} | {base['median_max_std']:.4f} |",
        f"| median s_d (std along the query direction) | {fp.get('median_deciding_std_along_query', float('nan')):.4f} | {fn.get('median_deciding_std_along_query', float('nan')):.4f} | {fpb.get('median_deciding_std_along_query', float('nan')):.4f} | |",
        f"| query at z <= r (touches the ground plane) / above | {fp.get('ground_z_le_r', 0):,} / {fp.get('above_ground', 0):,} | {fn.get('ground_z_le_r', 0):,} / {fn.get('above_ground', 0):,} | {fpb.get('ground_z_le_r', 0):,} / {fpb.get('above_ground', 0):,} | |",
        f"| median clearance | {fp.get('median_clearance', float('nan')) * 1000:.1f} mm | {fn.get('median_clearance', float('nan')) * 1000:.1f} mm | {fpb.get('median_clearance', float('nan')) * 1000:.1f} mm | |",
        f"| median splats with s2~ < 1 | {fp.get('median_n_colliding', float('nan')):.0f} | {fn.get('median_n_colliding', float('nan')):.0f} | {fpb.get('median_n_colliding', float('nan')):.0f} | |",
        f"| sphere within r of the deciding splat's exact 1-sigma ellipsoid (the Gaussian's body touches it) | {fp.get('within_r_of_deciding_1sigma_ellipsoid', 0):,} ({_pct(fp.get('within_r_of_deciding_1sigma_ellipsoid', 0), fp['n'])}) | {fn.get('within_r_of_deciding_1sigma_ellipsoid', 0):,} | {fpb.get('within_r_of_deciding_1sigma_ellipsoid', 0):,} ({_pct(fpb.get('within_r_of_deciding_1sigma_ellipsoid', 0), fpb['n'])}) | |",
        f"| farther than r from it (flagged by the first-order inflation only) | {fp.get('beyond_r_of_deciding_1sigma_ellipsoid', 0):,} ({_pct(fp.get('beyond_r_of_deciding_1sigma_ellipsoid', 0), fp['n'])}) | {fn.get('beyond_r_of_deciding_1sigma_ellipsoid', 0):,} | {fpb.get('beyond_r_of_deciding_1sigma_ellipsoid', 0):,} ({_pct(fpb.get('beyond_r_of_deciding_1sigma_ellipsoid', 0), fpb['n'])}) | |",
        f"| median (distance to that ellipsoid - r) | {fp.get('median_dist_to_deciding_1sigma_ellipsoid_minus_r', float('nan')) * 1000:.1f} mm | {fn.get('median_dist_to_deciding_1sigma_ellipsoid_minus_r', float('nan')) * 1000:.1f} mm | {fpb.get('median_dist_to_deciding_1sigma_ellipsoid_minus_r', float('nan')) * 1000:.1f} mm | |",
        f"| deciding splat a ground (surface) splat / other | {fp.get('deciding_splat_on', {}).get('ground', 0):,} / {fp['n'] - fp.get('deciding_splat_on', {}).get('ground', 0):,} | {fn.get('deciding_splat_on', {}).get('ground', 0):,} / {fn['n'] - fn.get('deciding_splat_on', {}).get('ground', 0):,} | {fpb.get('deciding_splat_on', {}).get('ground', 0):,} / {fpb['n'] - fpb.get('deciding_splat_on', {}).get('ground', 0):,} | {base['ground_splats']:,} ground splats |",
        f"| most frequent query heights z (count) | {_zs(fp)} | {_zs(fn)} | {_zs(fpb)} | |",
    ]
    # the line above with the median of a dict of counts is meaningless: replace with bins below
    L = [ln for ln in L if not ln.startswith("| median opacity of the deciding splat")]
    L.append(f"| median opacity of the deciding splat | {fp.get('median_deciding_opacity', float('nan')):.2f} | {fn.get('median_deciding_opacity', float('nan')):.2f} | {fpb.get('median_deciding_opacity', float('nan')):.2f} | - |")
    for title, key in (("opacity", "opacity"), ("largest std / median", "size_vs_median"), ("inflation n s_d / r", "inflation_vs_r")):
        for lab in (fp.get(key) or fn.get(key) or {}):
            allv = base[key].get(lab, None) if key in base else None
            L.append(
                f"| {title}: {lab} | {fp.get(key, {}).get(lab, 0):,} | {fn.get(key, {}).get(lab, 0):,} | {fpb.get(key, {}).get(lab, 0):,} | "
                + (f"{allv:,} ({_pct(allv, base['n_splats'])})" if allv is not None else "-")
                + " |"
            )
    L += [
        "",
        f"Splat sizes: ground splats (sampled at twice the stones' spacing) have median largest std {base['median_max_std_ground']:.4f} (p99 {base['p99_max_std_ground']:.4f}), "
        f"stone splats {base['median_max_std_stones']:.4f} (p99 {base['p99_max_std_stones']:.4f}); the kept floaters {', '.join(f'{v:.3f}' for v in base['floater_max_std'])} "
        f"(opacity {', '.join(f'{v:.2f}' for v in base['floater_opacity'])}).",
    ]
    L += ["", "Nearest stone of the false positives at recall 0.95: " + ", ".join(f"{k} {v:,}" for k, v in list(fp.get("nearest_primitive", {}).items())[:8]) + "; of the false negatives: " + ", ".join(f"{k} {v:,}" for k, v in list(fn.get("nearest_primitive", {}).items())[:8]) + "."]
    L += [
        "",
        "## 3. What the opacity-scaled variant (d2) changes (recall 0.95)",
        "",
        f"False positives: {d2['fp_default']:,} (default) -> {d2['fp_d2']:,} (d2): {d2['removed']['n']:,} removed, {d2['added']['n']:,} added, {d2['kept']['n']:,} kept.",
        f"Removed: deciding splat a floater in {d2['removed'].get('deciding_splat_floater', 0):,}, median opacity {d2['removed'].get('median_deciding_opacity', float('nan')):.2f}, "
        f"median largest std {d2['removed'].get('median_deciding_max_std', float('nan')):.4f}, median clearance {d2['removed'].get('median_clearance', float('nan')) * 1000:.1f} mm. "
        f"Kept: floater in {d2['kept'].get('deciding_splat_floater', 0):,}, median opacity {d2['kept'].get('median_deciding_opacity', float('nan')):.2f}, "
        f"median largest std {d2['kept'].get('median_deciding_max_std', float('nan')):.4f}, median clearance {d2['kept'].get('median_clearance', float('nan')) * 1000:.1f} mm.",
        "",
        "## 4. Metric, scene or grid?",
        "",
        "Same queries and labels; scene changed toward a trained scene's splats (AP; SPLANNING where run):",
        "",
        "| scene | splats | median / p99 largest std | CS n_sigma=0 | CS n_sigma=1 | d2 | SPLANNING | CS n_sigma=1 - SPLANNING | FP at recall 0.95 (CS n_sigma=1) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for k, v in sc.items():
        spl_ap = f"{v['splanning']['ap']:.4f}" if "splanning" in v else "-"
        gap = f"{v['cs_ns1_minus_splanning_ap']:+.4f}" if "cs_ns1_minus_splanning_ap" in v else "-"
        L.append(f"| {v['label']} (`{k}`) | {v['n_splats']:,} | {v['median_max_std']:.4f} / {v['p99_max_std']:.4f} | {v['cs_ns0']['ap']:.4f} | {v['cs_ns1']['ap']:.4f} | {v['cs_ns1_d2']['ap']:.4f} | {spl_ap} | {gap} | {v['cs_ns1']['fp_at_recall95']:,} |")
    L += ["", "The evaluation set and the lattice (AP):", "", "| queries | n | CS n_sigma=0 | CS n_sigma=1 | d2 | SPLANNING | CS n_sigma=1 - SPLANNING |", "|---|---|---|---|---|---|---|"]
    L.append(f"| E1 evaluation set | {res['n_queries']:,} | {ops['cs_ns0']['ap']:.4f} | {ops['cs_ns1']['ap']:.4f} | {ops['cs_ns1_d2']['ap']:.4f} | {ops['splanning']['ap']:.4f} | {ops['cs_ns1']['ap'] - ops['splanning']['ap']:+.4f} |")
    for k, v in gr.items():
        if "ap" not in v:
            continue
        a = v["ap"]
        lab = {"above_ground": "above the ground (z > r)", "ground_z_le_r": "at the ground (z <= r)", "lattice_shifted_half_cell": "lattice shifted by half a cell (E1 pad + spacing / 2r)"}.get(k, k.replace("without_free_within_", "without the free queries within ").replace("mm", " mm"))
        L.append(f"| {lab} | {v['n_queries']:,} | {a['cs_ns0']:.4f} | {a['cs_ns1']:.4f} | {a['cs_ns1_d2']:.4f} | {a['splanning']:.4f} | {a['cs_ns1'] - a['splanning']:+.4f} |")
    L += ["", "Lattice layers near the ground (the ground's top face is z = 0; a sphere collides below z = r):", "", "| z | queries | clearance over the ground | FP at recall 0.95, ours | FP at recall 0.95, SPLANNING |", "|---|---|---|---|---|"]
    for z, v in gr["z_layers"].items():
        L.append(f"| {z} | {v['n']:,} | {v['clearance_over_ground_mm']:.1f} mm | {v['fp_cs_ns1_recall95']:,} | {v['fp_splanning_recall95']:,} |")
    qd = gr["query_distribution"]
    L += [
        "",
        f"Free queries within 5 mm of the decision boundary: {qd['negatives_within_5mm']:,} of {qd['negatives']:,} negatives; within 10 mm: {qd['negatives_within_10mm']:,}.",
        "",
        "## Conclusion",
        "",
    ]
    L += conclusion(res)
    return "\n".join(L) + "\n"


def conclusion(res: dict[str, Any]) -> list[str]:
    """The conclusion, every number from the run (phrased from the signs, so it stays true on --quick)."""
    ops, err, sc, gr, d2 = res["operating_points"], res["errors_cs_ns1"], res["scenes"], res["grid"], res["d2_vs_default_at_recall95"]
    fp = err["recall95_fp"]
    c1, c0, cd, spl = ops["cs_ns1"], ops["cs_ns0"], ops["cs_ns1_d2"], ops["splanning"]
    gap = c1["ap"] - spl["ap"]
    nf, tr, tc, hv = sc["no_floaters"], sc["trained_like"], sc["no_floaters_tail_clipped"], sc["no_floaters_halved"]
    sh = gr["lattice_shifted_half_cell"]["ap"]
    w10 = gr["without_free_within_10mm"]["ap"]
    ab = gr["above_ground"]["ap"]
    n_fl = fp.get("deciding_splat_floater", 0)
    beyond = fp.get("beyond_r_of_deciding_1sigma_ellipsoid", 0)
    big = fp.get("size_vs_median", {}).get("4-8x median", 0) + fp.get("size_vs_median", {}).get(">= 8x median", 0)
    infl = fp.get("inflation_vs_r", {}).get(">= 1", 0)
    zl = gr["z_layers"]
    zmax = max(zl, key=lambda z: zl[z]["fp_cs_ns1_recall95"])
    lay = zl[zmax]
    nfl = res["splat_base_rates"]["n_kept_floaters"]
    base = res["splat_base_rates"]
    share_fl = (nf["cs_ns1"]["ap"] - c1["ap"]) / (spl["ap"] - c1["ap"]) if spl["ap"] != c1["ap"] else float("nan")
    gd = fp.get("deciding_splat_on", {}).get("ground", 0)
    cfp = res["clearance"]["cs_ns1_recall95_fp"]
    far = cfp.get("clearance [20, 40 mm)", 0) + cfp.get("clearance >= 40 mm", 0)
    kept_on_layer = d2["kept"].get("query_z", {}).get(zmax, 0)

    def vs(a: float, b: float) -> str:
        return "above" if a > b else "below"

    return [
        f"- **What the gap is.** AP {c1['ap']:.4f} (n_sigma = 1) against SPLANNING's {spl['ap']:.4f} ({gap:+.4f}). It is false positives: at recall 0.95 both miss "
        f"{c1['recall95']['n_fn']:,} colliding queries (that recall fixes the count), but ours flags {c1['recall95']['n_fp']:,} free ones against SPLANNING's {spl['recall95']['n_fp']:,}. "
        f"{fp.get('only_by_inflation', 0):,} of these ({_pct(fp.get('only_by_inflation', 0), fp['n'])}) have no splat mean within r: the n_sigma inflation alone flags them.",
        f"- **Which splats.** {big:,} of the {fp['n']:,} FPs ({_pct(big, fp['n'])}) are decided by a splat at least 4x the median size (such splats are "
        f"{_pct(base['size_vs_median'].get('4-8x median', 0) + base['size_vs_median'].get('>= 8x median', 0), base['n_splats'])} of the scene), and {infl:,} ({_pct(infl, fp['n'])}) by one whose "
        f"std along the query direction is at least r. {n_fl:,} ({_pct(n_fl, fp['n'])}) are decided by one of the {nfl} semi-transparent floaters the default filter keeps "
        f"(opacity {min(base['floater_opacity'], default=float('nan')):.2f}-{max(base['floater_opacity'], default=float('nan')):.2f}); {gd:,} ({_pct(gd, fp['n'])}) by ground splats, which the generator samples at twice the stones' spacing "
        f"(median largest std {base['median_max_std_ground']:.4f} against {base['median_max_std_stones']:.4f}).",
        f"- **The metric's share.** The distance itself ranks well: at n_sigma = 0 the same metric has AP {c0['ap']:.4f}, {vs(c0['ap'], spl['ap'])} SPLANNING. "
        f"The FPs come from the first-order inflation s2 - n_sigma sigma. It is opacity-blind, and for splats whose std along the query is comparable to r it "
        f"overshoots the Gaussian's own body: {beyond:,} FPs ({_pct(beyond, fp['n'])}) are farther than r from the deciding splat's exact 1-sigma ellipsoid "
        f"(median {fp.get('median_dist_to_deciding_1sigma_ellipsoid_minus_r', float('nan')) * 1000:.1f} mm beyond it).",
        f"- **The scene's share.** Without the {nfl} floaters, ours is {nf['cs_ns1']['ap']:.4f} against {nf['splanning']['ap']:.4f} (gap {nf['cs_ns1_minus_splanning_ap']:+.4f}; "
        f"the floaters account for {100 * share_fl:.0f}% of the gap). Clipping the size tail at p95 gives {tc['cs_ns1']['ap']:.4f}, and halving every splat gives {hv['cs_ns1']['ap']:.4f}. "
        f"Small opaque surface splats (no floaters, opacity 1, tail clipped) give {tr['cs_ns1']['ap']:.4f} against SPLANNING's {tr['splanning']['ap']:.4f} "
        f"(gap {tr['cs_ns1_minus_splanning_ap']:+.4f}). Caveat: level 1's size tail is calibrated on real captures (p99 {sc['default']['p99_max_std']:.4f} = "
        f"{sc['default']['p99_max_std'] / sc['default']['median_max_std']:.1f}x the median here), so a clipped tail is a counterfactual; it is not known to be the paper's scene.",
        f"- **The grid's share.** {lay['fp_cs_ns1_recall95']:,} of the FPs ({_pct(lay['fp_cs_ns1_recall95'], fp['n'])}) lie on one lattice layer, z = {zmax}, only "
        f"{lay['clearance_over_ground_mm']:.1f} mm above the ground's decision boundary (SPLANNING has {lay['fp_splanning_recall95']:,} there). On the lattice shifted by half a cell the gap is "
        f"{sh['cs_ns1'] - sh['splanning']:+.4f} ({sh['cs_ns1']:.4f} vs {sh['splanning']:.4f}). Leaving out the free queries within 10 mm of the boundary does not close it "
        f"({w10['cs_ns1'] - w10['splanning']:+.4f}): {far:,} of the FPs lie 20 mm or more from the surface. Above the ground, the gap is {ab['cs_ns1'] - ab['splanning']:+.4f}.",
        f"- **The opacity-scaled variant (d2)** gives AP {cd['ap']:.4f}. At recall 0.95 it removes {d2['removed']['n']:,} FPs: {d2['removed'].get('deciding_splat_floater', 0):,} "
        f"decided by floaters, median deciding opacity {d2['removed'].get('median_deciding_opacity', float('nan')):.2f}. It keeps {d2['kept']['n']:,} (median opacity "
        f"{d2['kept'].get('median_deciding_opacity', float('nan')):.2f}, {kept_on_layer:,} on the z = {zmax} layer) and adds {d2['added']['n']:,}. Its own rule "
        f"(min_s2 < 1) misses {cd['own_rule']['n_fn']:,} colliding queries (recall {cd['own_rule']['recall']:.4f}) against {c1['own_rule']['n_fn']:,} "
        f"({c1['own_rule']['recall']:.4f}) at n_sigma = 1.",
        "- **Why, and what to change.** The gap is neither a bug nor a property of AP. It comes from CollisionSplatting's conservatism: an opacity-blind, first-order "
        "n_sigma sigma inflation. That inflation meets this scene's few large, semi-transparent floaters and its long tail of large (mostly ground) splats, and the "
        "E1 lattice then puts a whole layer of free queries just above the ground. The metric's ranking is sound (n_sigma = 0). Default n_sigma = 1 is a safety "
        "margin by design, and E1 alone is no reason to lower it. Opacity-aware conservatism (d2) removes the floater part and leaves the size-tail part; "
        "its cost is the extra misses at its own rule listed above. Adopt it as the default only if the real-rooms study (`benchmarks/real_rooms.py`) shows the same floater-driven "
        "closures. For E1's reporting, the half-cell-shifted lattice and the no-floater scene show how much of the gap is grid and floaters.",
    ]


def main(argv: list[str] | None = None) -> dict[str, Any]:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="E1's quick settings (50k splats, grid 0.025): a smoke run")
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent / "results"), help="output folder (pr_gap.json, pr_gap.md)")
    ap.add_argument("--from-json", default=None, help="only rewrite pr_gap.md from this pr_gap.json (no run)")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.from_json:
        res = json.loads(Path(args.from_json).read_text())
    else:
        res = run_study(quick=args.quick)
        (out / "pr_gap.json").write_text(json.dumps(res, indent=2, default=float) + "\n")
    md = markdown(res)
    (out / "pr_gap.md").write_text(md)
    print(md)
    return res


if __name__ == "__main__":
    main(sys.argv[1:])
