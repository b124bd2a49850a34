"""Study E1 (paper Fig. 3): precision-recall of collision scores on a grid of query points.

Protocol
--------
* **Scene**: the built-in Stonehenge (level 1, ~200k splats, floaters filtered as the paper
  does) and its analytic boxes, or a splat file with its ``.gt.json`` ground truth.
* **Robot**: a sphere of radius r = 0.015 (scene units).
* **Grid**: the cell centres of a regular lattice of spacing ``spacing`` over the bounding box of
  the splat means padded by ``pad * r`` on every side (z up; for Stonehenge x, y in ~[-0.52, 0.52],
  z in ~[-0.018, 0.235]).
* **Ground truth**: in collision iff the exact signed distance to the boxes is < r.
* **Evaluation set (headline numbers)**: grid points with sdf > -r, i.e. centres that a sphere can
  reach from free space without its centre going deeper than r into a solid. Deeper points are far
  from every splat (splats live on surfaces), so no splat-based method can see them; they are
  reported separately (``all_points``). The set ``above_ground`` keeps the evaluation-set points
  with z > r (no ground contact possible), so only stones decide; the ground plane holds about half
  of all positives and is an easy case.
* **Scores** (larger = more likely in collision), swept over every distinct value:

  - CollisionSplatting at n_sigma = 0, 1, 2 (headline ``collisionsplatting``: n_sigma = 1):
    ``-softmin``, the streaming softmin of s2~ over the neighbourhood, which the paper uses for a
    link's collision state. ``-min(min_s2, s2_cap)`` is reported beside it (``min_s2``): it is the
    quantity the binary decision thresholds (collision iff min_s2 < 1), but as a ranking score it
    saturates: s2~ = max(0, s2 - n_sigma sigma) is 0 in a whole core around every splat
    (|d| <= 2 n_sigma s_d for a sphere, s_d the splat's std along d), so for n_sigma > 0 every query
    in some core ties at 0, free ones near large splats included (``n_zero_min_s2``). The softmin
    breaks the tie by how many splats are that close. (We chose softmin after seeing this tie;
    both are in the outputs.)
  - the four baselines: their ``collision_score`` (see :mod:`splatplan.baselines`).

* **Metrics**: step-wise average precision ``AP = sum_k (R_k - R_{k-1}) P_k`` over the distinct
  thresholds (ties form one step, as scikit-learn's ``average_precision_score``), best F1 over the
  thresholds, and precision/recall of each method's own decision rule.

Exact spatial culling of the baselines
--------------------------------------
Splat-Nav, SAFER-Splat and ATLASNav score a query by a *minimum* over all Gaussians; evaluated
densely that is ~1e10 (query, Gaussian) pairs per method. We evaluate them with each method's own
class, on tiles of nearby queries (side ``tile``) against the subset of Gaussians that can score
below a per-method **clamp** C (a native-score value well beyond the decision boundary), using a
per-Gaussian lower bound on the pair score at distance D = |c - mu_i|:

  ============ ========================= ===================== ======================================
  method       native pair score         clamp C (collision    Gaussian i kept when D < R_i with
                                         iff native < thr)
  ============ ========================= ===================== ======================================
  Splat-Nav    max_t K_i >= D^2/(r+s)^2  4 (thr 1)             R_i = 2.1 (r + s_i), s_i = largest
                                                               level-scaled std; 2.1 > 2 covers the
                                                               10-step bisection's under-estimate of
                                                               max_t K (<= 7% for t* in [.007, .993])
  SAFER-Splat  phi d^2 - r^2, d >= D - s 3 r^2 (d = 2r; thr 0) R_i = 2.05 r + s_i
  ATLASNav     D - 3 sigma_i - r         r (thr 0)             R_i = 2.01 r + 3 sigma_i
  ============ ========================= ===================== ======================================

A query's score is then ``max(subset score, -C)`` (collision orientation): equal to the method's
full score whenever that is above -C (every query near the decision boundary), and tied at -C
otherwise (counted in ``n_clamped``). When no positive is clamped (``n_clamped_positive`` = 0 on
the evaluation set) the clamped queries rank after every positive, so AP and best F1 are exactly
those of the unculled method. SPLANNING sums over Gaussians and culls natively at
``|c - mu| > 6 s_max + r``; we keep every Gaussian within that radius of the tile, so its score is
the full one up to float32 summation order (no clamp). ``culling_check`` re-evaluates a few random
queries near the boundary (and a few clamped ones) over **all** Gaussians and reports the largest
deviation. CollisionSplatting runs its own (exact) kernel on every point.

Fidelity variants (issue #7)
----------------------------
CollisionSplatting is also scored, on the same queries, in the variants of :data:`VARIANTS` at every
n_sigma: (a) today's settings; (b) the paper authors' evaluation filter (every splat with opacity
< 0.1 removed, not only the faint *and* large ones); (c) the log-*mean*-exp softmin with a sharp
temperature (the paper's "recursive softmin", t = 300 on s2~), with a float64 spot check that the
kernel's exponentials do not underflow; (b)+(c); and two options of our own, beyond the paper:
(d1) ``MetricConfig.opacity_min`` (faint splats are free space) and (d2)
``opacity_scaled_inflation`` (inflation n_sigma * o_i * sigma_i). The best baseline is re-scored
on the (b) scene for a like-for-like comparison. The scene is never tuned to the result.

Every knob is a field of :class:`PRConfig` (``splatplan eval pr --help``).

Outputs in ``out_dir``: ``pr.json``, ``pr.png`` (all curves; variants on the right), ``pr.md`` (tables).
"""

from __future__ import annotations

import json
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._config import bounded, check_config
from .._resources import require_bytes
from ..errors import SplatplanError
from .._progress import progress
from .._warp import cpu_threads
from ..robots import point_radius
from ._common import DISPLAY, load_scene_with_gt, set_torch_threads

__all__ = ["PRConfig", "VARIANTS", "precision_recall_curve", "average_precision", "best_f1", "pr_summary", "report", "run_pr"]

#: Order of the baselines in tables and plots.
BASELINE_NAMES = ("splatnav", "safersplat", "atlasnav", "splanning")

#: CollisionSplatting fidelity variants (issue #7): name -> (label, scene, MetricConfig changes).
#: scene "default" = the default floater filter (o < 0.1 *and* max std > 5x median), "opacity" =
#: the paper authors' evaluation filter (every splat with o < eval_opacity_below removed). The
#: values "$lme_t" and "$opacity_min" are taken from :class:`PRConfig`.
VARIANTS: dict[str, tuple[str, str, dict[str, Any]]] = {
    "default": ("(a) today: default floater filter, log-sum-exp softmin t = $default_t", "default", {}),
    "opacity_filter": ("(b) paper's evaluation filter: every splat with opacity < 0.1 removed", "opacity", {}),
    "log_mean_exp": ("(c) log-mean-exp softmin (the paper's recursive softmin), t = $lme_t", "default", {"softmin_mode": "mean", "softmin_t": "$lme_t"}),
    "log_mean_exp_default_t": ("(c') log-mean-exp at today's t = $default_t (separates the aggregation from the temperature)", "default", {"softmin_mode": "mean"}),
    "opacity_filter+log_mean_exp": ("(b)+(c) both", "opacity", {"softmin_mode": "mean", "softmin_t": "$lme_t"}),
    "opacity_min": ("(d1, beyond the paper) metric option opacity_min = $opacity_min on the default scene", "default", {"opacity_min": "$opacity_min"}),
    "opacity_scaled_inflation": ("(d2, beyond the paper) inflation n_sigma * o_i * sigma_i", "default", {"opacity_scaled_inflation": True}),
}


def variant_settings(name: str, cfg: "PRConfig") -> tuple[str, str, dict[str, Any]]:
    """(label, scene kind, MetricConfig changes) of variant ``name`` with ``cfg``'s values filled in."""
    if name not in VARIANTS:
        raise SplatplanError(f"unknown E1 variant {name!r}: choose from {', '.join(VARIANTS)}")
    from ..metric.config import MetricConfig

    label, kind, changes = VARIANTS[name]
    subst = {"$lme_t": cfg.lme_t, "$opacity_min": cfg.opacity_min, "$default_t": MetricConfig().softmin_t}
    changes = {k: subst.get(v, v) if isinstance(v, str) else v for k, v in changes.items()}
    for key, val in subst.items():
        label = label.replace(key, f"{val:g}")
    label = label.replace("opacity < 0.1", f"opacity < {cfg.eval_opacity_below:g}")
    return label, kind, changes


@dataclass
class PRConfig:
    """Knobs of the precision-recall study (defaults = the full run)."""

    #: Lattice spacing of the query grid (scene units); the grid holds the cell centres.
    spacing: float = bounded(0.01, gt=0)
    #: Robot sphere radius (scene units).
    radius: float = bounded(point_radius(), gt=0)
    #: Padding of the domain (bounding box of the splat means) on every side, in units of radius.
    pad: float = bounded(1.0, ge=0)
    #: n_sigma values of CollisionSplatting; the headline ``collisionsplatting`` entry uses 1.0.
    n_sigmas: tuple[float, ...] = bounded((0.0, 1.0, 2.0), ge=0)
    #: Baselines to score (a subset of splatnav, safersplat, atlasnav, splanning).
    baselines: tuple[str, ...] = BASELINE_NAMES
    #: Side of the cubic query tiles the culled baselines are evaluated on (scene units).
    tile: float = bounded(0.02, gt=0)
    #: Side of the coarse blocks used to pre-select candidate Gaussians for the tiles (scene units).
    block: float = bounded(0.1, gt=0)
    #: Built-in Stonehenge level (1..5).
    level: int = bounded(1, ge=1, le=5)
    #: Built-in Stonehenge seed.
    seed: int = bounded(0, ge=0)
    #: Built-in Stonehenge splat count before filtering (None: the level's default, ~200k at level 1).
    n_splats: int | None = bounded(None, ge=1)
    #: Queries near the decision boundary re-scored over all Gaussians per culled baseline.
    n_check: int = bounded(16, ge=0)
    #: Clamped queries re-scored over all Gaussians per culled baseline.
    n_check_clamped: int = bounded(4, ge=0)
    #: Points per plotted curve (curves are thinned for the figure only; metrics use every point).
    plot_points: int = bounded(3000, ge=2)
    #: Seed of the culling-check sample.
    check_seed: int = bounded(0, ge=0)
    #: CollisionSplatting fidelity variants scored at every n_sigma (empty = none): default (a),
    #: opacity_filter (b), log_mean_exp (c), log_mean_exp_default_t (c'), opacity_filter+log_mean_exp,
    #: opacity_min (d1), opacity_scaled_inflation (d2); see VARIANTS.
    variants: tuple[str, ...] = (
        "default",
        "opacity_filter",
        "log_mean_exp",
        "log_mean_exp_default_t",
        "opacity_filter+log_mean_exp",
        "opacity_min",
        "opacity_scaled_inflation",
    )
    #: Opacity threshold of the paper's evaluation filter (variant ``opacity_filter``: every splat below it removed).
    eval_opacity_below: float = bounded(0.1, ge=0, le=1)
    #: Softmin temperature of the log-mean-exp variants (the paper's sharp "recursive softmin", on s2~).
    lme_t: float = bounded(300.0, gt=0)
    #: opacity_min of the ``opacity_min`` variant (splats below it count as free space).
    opacity_min: float = bounded(0.1, ge=0, le=1)
    #: Baseline also scored on the ``opacity_filter`` scene for a like-for-like comparison:
    #: "best" (the best AP on the default scene), a baseline name, or "none".
    variant_baseline: str = "best"
    #: Queries near the surface whose log-mean-exp softmin is re-computed in float64 (underflow check).
    n_softmin_check: int = bounded(64, ge=0)
    #: Free-form note stored in the JSON (e.g. why this is a quick run).
    note: str = ""

    def validate(self) -> "PRConfig":
        """Check every field's declared range (:mod:`splatplan._config`); returns self."""
        return check_config(self)

    @classmethod
    def quick(cls) -> "PRConfig":
        """A < 1 min smoke version: 50k-splat Stonehenge (larger splats), 0.025 grid, tiny check."""
        return cls(
            spacing=0.025,
            tile=0.05,
            block=0.2,
            n_splats=50_000,
            n_check=3,
            n_check_clamped=1,
            plot_points=500,
            variant_baseline="none",
            n_softmin_check=16,
            note="quick run: Stonehenge level 1 with 50,000 splats (not ~200k), grid spacing 0.025; smoke test only",
        )


# ---------------------------------------------------------------------------------------------
# Metrics
# ---------------------------------------------------------------------------------------------


def precision_recall_curve(
    scores: np.ndarray,  # (Q,) larger = more likely positive; finite or +-inf, no NaN
    labels: np.ndarray,  # (Q,) bool ground truth
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Precision and recall at every distinct threshold ("positive iff score >= thr").

    Returns:
        (precision, recall, thresholds), each (T,), thresholds decreasing. Tied scores form a
        single threshold.

    Raises:
        SplatplanError: shapes differ, NaN scores, or no positive label.
    """
    s = np.asarray(scores, dtype=np.float64).reshape(-1)
    y = np.asarray(labels, dtype=bool).reshape(-1)
    if s.shape != y.shape:
        raise SplatplanError(f"scores {s.shape} and labels {y.shape} differ in shape")
    if np.isnan(s).any():
        raise SplatplanError("scores contain NaN")
    n_pos = int(y.sum())
    if n_pos == 0:
        raise SplatplanError("no positive (colliding) query: precision-recall is undefined; enlarge the grid")
    order = np.argsort(-s, kind="stable")
    s, y = s[order], y[order]
    tp = np.cumsum(y)  # (Q,)
    fp = np.cumsum(~y)
    last = np.r_[np.nonzero(s[1:] != s[:-1])[0], len(s) - 1]  # last index of each tie group
    tp, fp = tp[last], fp[last]
    return tp / (tp + fp), tp / n_pos, s[last]


def average_precision(precision: np.ndarray, recall: np.ndarray) -> float:
    """Step-wise AP = sum_k (R_k - R_{k-1}) P_k (R_0 = 0), thresholds in decreasing order."""
    r_prev = np.r_[0.0, recall[:-1]]
    return float(np.sum((recall - r_prev) * precision))


def best_f1(precision: np.ndarray, recall: np.ndarray) -> tuple[float, int]:
    """(max over thresholds of 2PR / (P + R), index of that threshold)."""
    den = precision + recall
    f1 = np.where(den > 0, 2 * precision * recall / np.where(den > 0, den, 1.0), 0.0)
    k = int(np.argmax(f1))
    return float(f1[k]), k


def _decision_prf(pred: np.ndarray, labels: np.ndarray) -> dict[str, float]:
    """Precision, recall, F1 of a binary decision."""
    tp = float(np.sum(pred & labels))
    fp = float(np.sum(pred & ~labels))
    fn = float(np.sum(~pred & labels))
    p = tp / (tp + fp) if tp + fp > 0 else 0.0
    r = tp / (tp + fn) if tp + fn > 0 else 0.0
    return {"precision": p, "recall": r, "f1": 2 * p * r / (p + r) if p + r > 0 else 0.0}


def pr_summary(scores: np.ndarray, labels: np.ndarray, native_threshold: float | None = None) -> dict[str, Any]:
    """AP, best F1 (+ its threshold) and, given the method's own threshold, its P/R/F1.

    Args:
        scores: (Q,) collision scores (larger = collision).
        labels: (Q,) bool ground truth.
        native_threshold: the method decides "collision" iff score > this (strict).
    """
    p, r, thr = precision_recall_curve(scores, labels)
    f1, k = best_f1(p, r)
    out: dict[str, Any] = {"ap": average_precision(p, r), "best_f1": f1, "best_f1_threshold": float(thr[k])}
    if native_threshold is not None:
        d = _decision_prf(np.asarray(scores) > native_threshold, np.asarray(labels, bool))
        out.update({f"native_{k_}": v for k_, v in d.items()})
    return out


def _thin_curve(p: np.ndarray, r: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """At most ~n points of a PR curve, always keeping the first and last."""
    if len(p) <= n:
        return p, r
    idx = np.unique(np.r_[np.linspace(0, len(p) - 1, n).astype(int), len(p) - 1])
    return p[idx], r[idx]


# ---------------------------------------------------------------------------------------------
# Grid
# ---------------------------------------------------------------------------------------------


#: bytes per grid cell across the study (centres, exact SDF, labels, every method's scores): an estimate
GRID_BYTES_PER_CELL = 128


def make_grid(lo: np.ndarray, hi: np.ndarray, spacing: float) -> tuple[np.ndarray, dict]:
    """Cell centres of the lattice of ``spacing`` covering [lo, hi] -> ((Q, 3) float64, spec)."""
    n_float = np.maximum(1.0, np.ceil((np.asarray(hi, np.float64) - lo) / spacing - 1e-9))  # cells per axis (float: no overflow)
    require_bytes(float(np.prod(n_float)) * GRID_BYTES_PER_CELL, f"the query grid of spacing {spacing:g} ({float(np.prod(n_float)):.3g} cells)", "the resolution: a larger --spacing")
    n = n_float.astype(int)
    axes = [lo[k] + spacing * (np.arange(n[k]) + 0.5) for k in range(3)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    spec = {"lo": lo.tolist(), "hi": (lo + spacing * n).tolist(), "spacing": spacing, "shape": n.tolist()}
    return pts, spec


# ---------------------------------------------------------------------------------------------
# Culled baseline evaluation
# ---------------------------------------------------------------------------------------------


def _cull_rule(name: str, obj: Any, r: float) -> tuple[np.ndarray, float | None, str]:
    """(per-Gaussian inclusion radius R_i (N,), clamp in collision-score units or None, text).

    See the module docstring for the derivation of each rule.
    """
    if name == "splatnav":
        s = obj.lam.max(dim=-1).values.sqrt().double().numpy()  # level-scaled largest std
        return 2.1 * (r + s), -4.0, "clamp max_t K >= 4; keep |c-mu| < 2.1 (r + s_max)"
    if name == "safersplat":
        s = obj.semi_axes.max(dim=-1).values.double().numpy()
        return 2.05 * r + s, -3.0 * r * r, "clamp h >= 3 r^2 (d >= 2r); keep |c-mu| < 2.05 r + s_max"
    if name == "atlasnav":
        return 2.01 * r + obj.ball.double().numpy(), -r, "clamp score >= r; keep |c-mu| < 2.01 r + 3 sigma"
    if name == "splanning":
        return (obj.cull.double().numpy() + r) * (1 + 1e-4) + 1e-6, None, "no clamp; keep |c-mu| <= 6 s_max + r (native cull)"
    raise SplatplanError(f"no culling rule for baseline {name!r}")


def _box_dist(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Euclidean distance (P,) from points (P, 3) to the axis-aligned box [lo, hi] (0 inside)."""
    d = np.maximum(np.maximum(lo - p, p - hi), 0.0)
    return np.sqrt(np.einsum("ij,ij->i", d, d))


def _subset(scene_t: Any, idx: np.ndarray) -> Any:
    """SceneTensors restricted to Gaussians ``idx``."""
    import torch

    from ..baselines import SceneTensors

    t = torch.as_tensor(idx, dtype=torch.long)
    return SceneTensors(scene_t.means[t], scene_t.rotations[t], scene_t.scales[t], scene_t.opacities[t])


def culled_collision_scores(
    cls: type,
    scene_t: Any,  # SceneTensors of the full scene
    incl_radius: np.ndarray,  # (N,) Gaussian i can matter for centre c only if |c - mu_i| < R_i
    clamp: float | None,  # collision-score floor (None: no clamp)
    queries: np.ndarray,  # (Q, 3) sphere centres, scene units
    radius: float,
    tile: float,
    block: float,
    desc: str = "",
) -> tuple[np.ndarray, np.ndarray, int]:
    """A baseline's collision score on many queries, each tile against its nearby Gaussians only.

    Returns:
        (scores (Q,) float64, clamped (Q,) bool, number of (query, Gaussian) pairs evaluated).
        Queries with no candidate get ``clamp`` (or the method's score against an empty
        neighbourhood, 0, when ``clamp`` is None: SPLANNING's p with I = 0).
    """
    means = scene_t.means.double().numpy()  # (N, 3)
    q = np.asarray(queries, dtype=np.float64)
    floor = 0.0 if clamp is None else clamp
    out = np.full(len(q), floor)
    clamped = np.ones(len(q), bool) if clamp is not None else np.zeros(len(q), bool)
    origin = q.min(0)
    tkey = np.floor((q - origin) / tile).astype(np.int64)  # (Q, 3) tile index
    per_block = max(1, int(min(round(block / tile), 2**40)))  # a block larger than the domain is one block (no int64 overflow)
    bkey = tkey // per_block
    order = np.lexsort((tkey[:, 2], tkey[:, 1], tkey[:, 0], bkey[:, 2], bkey[:, 1], bkey[:, 0]))
    tk, bk = tkey[order], bkey[order]
    t_start = np.r_[0, np.nonzero(np.any(tk[1:] != tk[:-1], axis=1))[0] + 1, len(q)]
    b_start = np.r_[0, np.nonzero(np.any(bk[1:] != bk[:-1], axis=1))[0] + 1, len(q)]
    def tiles():  # yields (query ids, Gaussian ids) per tile with candidates
        ti = 0
        for b0, b1 in zip(b_start[:-1], b_start[1:]):
            bq = q[order[b0:b1]]
            cand = np.nonzero(_box_dist(means, bq.min(0), bq.max(0)) < incl_radius)[0]  # block candidates
            while ti < len(t_start) - 1 and t_start[ti] < b1:
                qi = order[t_start[ti] : t_start[ti + 1]]
                ti += 1
                if len(cand) == 0:
                    yield qi, None
                    continue
                tq = q[qi]
                keep = cand[_box_dist(means[cand], tq.min(0), tq.max(0)) < incl_radius[cand]]
                yield qi, (keep if len(keep) else None)

    def evaluate(task):
        qi, keep = task
        if keep is None:
            return qi, None, 0
        obj = cls(_subset(scene_t, keep), "cpu")
        s = np.asarray(obj.collision_score(q[qi], radius, batch=len(qi)), dtype=np.float64)
        return qi, s, len(qi) * len(keep)

    n_pairs = 0
    bar = progress(total=len(t_start) - 1, desc=desc, unit="tile")
    # one tile per core: the tiles are too small for intra-op threads
    with set_torch_threads(1), ThreadPoolExecutor(max_workers=cpu_threads()) as pool:
        for qi, s, n in pool.map(evaluate, tiles()):
            bar.update(1)
            if s is None:
                continue
            n_pairs += n
            if clamp is None:
                out[qi] = s
            else:
                out[qi] = np.maximum(s, clamp)
                clamped[qi] = s <= clamp
    bar.close()
    return out, clamped, n_pairs


def _culling_check(
    name: str,
    full_obj: Any,
    queries: np.ndarray,
    scores: np.ndarray,
    clamped: np.ndarray,
    near: np.ndarray,
    radius: float,
    cfg: PRConfig,
) -> dict[str, Any]:
    """Re-score a random sample over all Gaussians; report the largest deviation from the culled run."""
    rng = np.random.default_rng(cfg.check_seed)
    pick_near = np.nonzero(near & ~clamped)[0]
    pick_cl = np.nonzero(clamped)[0]
    a = rng.choice(pick_near, min(cfg.n_check, len(pick_near)), replace=False) if len(pick_near) else np.zeros(0, int)
    b = rng.choice(pick_cl, min(cfg.n_check_clamped, len(pick_cl)), replace=False) if len(pick_cl) else np.zeros(0, int)
    idx = np.r_[a, b].astype(int)
    if len(idx) == 0:
        return {"n": 0}
    full = np.concatenate([np.asarray(full_obj.collision_score(queries[i : i + 1], radius, batch=1), np.float64) for i in idx])
    dev_exact = np.abs(full[: len(a)] - scores[a])
    rel = dev_exact / np.maximum(np.abs(full[: len(a)]), 1e-30)
    viol = full[len(a) :] - scores[b]  # clamped: the full score must be <= the clamp (<= 0 here)
    return {
        "n": int(len(idx)),
        "n_clamped": int(len(b)),
        "max_abs_dev": float(dev_exact.max()) if len(a) else 0.0,
        "max_rel_dev": float(rel.max()) if len(a) else 0.0,
        "max_clamp_violation": float(max(0.0, viol.max())) if len(b) else 0.0,
    }


# ---------------------------------------------------------------------------------------------
# The study
# ---------------------------------------------------------------------------------------------


def _plot(curves: dict[str, tuple[np.ndarray, np.ndarray, float]], path: Path, title: str, curves_v: dict | None = None, variants: dict | None = None) -> None:
    """Left: every method's PR curve. Right (when variants ran): CollisionSplatting's fidelity
    variants at n_sigma = 1, with the best baseline on the same scenes for reference."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    two = bool(curves_v)
    fig, axs = plt.subplots(1, 2 if two else 1, figsize=(12.8 if two else 6.4, 5.4), dpi=130, squeeze=False)
    ax = axs[0][0]
    styles = {
        "collisionsplatting": dict(color="C3", lw=2.4),
        "collisionsplatting_nsigma0": dict(color="C3", lw=1.0, ls="--"),
        "collisionsplatting_nsigma2": dict(color="C3", lw=1.0, ls=":"),
        "collisionsplatting_min_s2": dict(color="0.4", lw=1.0, ls="-."),
        "splatnav": dict(color="C0", lw=1.5),
        "safersplat": dict(color="C1", lw=1.5),
        "atlasnav": dict(color="C2", lw=1.5),
        "splanning": dict(color="C4", lw=1.5),
    }
    for key, (p, r, ap) in curves.items():
        label = {
            "collisionsplatting": "CollisionSplatting $n_\\sigma$=1, softmin score",
            "collisionsplatting_nsigma0": "CollisionSplatting $n_\\sigma$=0, softmin score",
            "collisionsplatting_nsigma2": "CollisionSplatting $n_\\sigma$=2, softmin score",
            "collisionsplatting_min_s2": "CollisionSplatting $n_\\sigma$=1, min $\\tilde s^2$ score",
        }.get(key, DISPLAY.get(key, key))
        ax.plot(r, p, label=f"{label}  AP {ap:.3f}", drawstyle="steps-post", **styles.get(key, {}))
    panels = [(ax, title)]
    if two:
        axv = axs[0][1]
        for i, (key, (p, r, ap)) in enumerate(curves_v.items()):
            if key in (variants or {}):  # decreasing widths and varied dashes: identical curves stay visible
                label, st = variants[key]["label"], dict(color=f"C{i}", lw=max(0.8, 3.2 - 0.4 * i), ls=("-", "--", "-.", ":")[i % 4])
            else:  # a baseline on the opacity-filtered scene
                label, st = f"{DISPLAY.get(key.replace('_opacity', ''), key)} on the (b) scene (reference)", dict(color="0.3", lw=1.2, ls="--")
            axv.plot(r, p, label=f"{label}  AP {ap:.3f}", drawstyle="steps-post", **st)
        panels.append((axv, "CollisionSplatting fidelity variants at $n_\\sigma$ = 1 (same queries; identical variants overlap)"))
    for a, t in panels:
        a.set_xlabel("recall (share of colliding queries flagged)")
        a.set_ylabel("precision (share of flagged queries that collide)")
        a.set_xlim(0, 1.0)
        a.set_ylim(0, 1.02)
        a.grid(alpha=0.3)
        a.set_title(t, fontsize=9)
        a.legend(loc="lower left", fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _variants_markdown(res: dict) -> list[str]:
    """The fidelity-variants table (issue #7): AP per n_sigma and the decision at n_sigma = 1."""
    variants = res.get("variants") or {}
    if not variants:
        return []
    ns_keys = list(next(iter(variants.values()))["by_n_sigma"])
    rows = [
        "",
        "## CollisionSplatting fidelity variants",
        "",
        "Same queries and labels as above; score `-softmin`. (a) is today's setting (the table above); (b) and (c) are what "
        "the paper's authors do (evaluation filter; log-mean-exp \"recursive softmin\" with a sharp temperature); "
        "(d1), (d2) are options of our own, **beyond the paper**.",
        "",
        "| variant | scene splats | " + " | ".join(f"AP n_sigma={k}" for k in ns_keys) + " | best F1 n_sigma=1 | own rule P / R n_sigma=1 | AP above ground n_sigma=1 |",
        "|---|---|" + "---|" * len(ns_keys) + "---|---|---|",
    ]
    for name, v in variants.items():
        one = v["by_n_sigma"].get("1")
        cells = [f"{v['label']} (`{name}`)", f"{v['n_splats']:,}"] + [f"{v['by_n_sigma'][k]['ap']:.4f}" for k in ns_keys]
        cells += [f"{one['best_f1']:.4f}", f"{one['native_precision']:.3f} / {one['native_recall']:.3f}", f"{one['ap_above_ground']:.4f}"] if one else ["—"] * 3
        rows.append("| " + " | ".join(cells) + " |")
    vb = res.get("variant_baseline") or {}
    rows.append("")
    if vb:
        rows.append(
            f"- Reference: {DISPLAY[vb['method']]} ({vb['why']}) on the (b) scene ({vb['n_splats']:,} splats): AP {vb['ap']:.4f}, "
            f"best F1 {vb['best_f1']:.4f} (default scene: AP {vb['ap_default_scene']:.4f})."
        )
    for name, c in (res.get("softmin_check") or {}).items():
        rows.append(
            f"- Log-mean-exp at t = {c['softmin_t']:g} (`{name}`), float32 kernel vs float64 reference on {c['n']} queries near the surface: "
            f"max |difference| {c['max_abs_dev']:.1e}, {c['n_inf_mismatch']} finite/infinite mismatches (no underflow when 0)."
        )
    t = res.get("targets", {})
    if "best_variant_at_n_sigma_1" in t:
        bv = t["best_variant_at_n_sigma_1"]
        rows.append(
            f"- Highest AP at n_sigma = 1: {variants[bv]['label']} (`{bv}`), {variants[bv]['by_n_sigma']['1']['ap']:.4f} "
            f"({t['ap_minus_best_baseline_by_fidelity_variant'][bv]:+.4f} against the best baseline on the default scene)."
        )
    return rows


def report(res: dict) -> str:
    """The markdown of E1: the methods table, then CollisionSplatting's fidelity variants."""
    rows = [
        "# E1 precision-recall (paper Fig. 3)",
        "",
        f"Scene: {res['scene']} ({res['n_splats']:,} splats after filtering {res['floaters_dropped']} floaters); "
        f"sphere r = {res['radius']}; grid spacing {res['grid']['spacing']} over "
        f"[{', '.join(f'{v:.3f}' for v in res['grid']['lo'])}] .. [{', '.join(f'{v:.3f}' for v in res['grid']['hi'])}] "
        f"(splat largest std: median {res['splat_max_std']['median']:.4f}, p99 {res['splat_max_std']['p99']:.4f}).",
        f"Evaluation set: {res['n_queries']:,} grid points with sdf > -r, {res['n_positive']:,} in collision (sdf < r). "
        f"All points: {res['n_queries_all']:,} ({res['n_positive_all']:,} positive). Above ground (z > r): "
        f"{res['n_queries_above_ground']:,} ({res['n_positive_above_ground']:,} positive).",
        "",
    ]
    if res.get("note"):
        rows += [f"**{res['note']}**", ""]
    rows += [
        "| method | score | AP | best F1 | own rule P / R | AP all points | AP above ground | clamped (pos.) | time (s) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for key, m in res["methods"].items():
        name = DISPLAY.get(key, None) or key.replace("collisionsplatting_nsigma", "CollisionSplatting n_sigma=")
        if key == "collisionsplatting":
            name = "CollisionSplatting n_sigma=1"
        rows.append(
            f"| {name} | `{m['score']}` | {m['ap']:.4f} | {m['best_f1']:.4f} | {m['native_precision']:.3f} / {m['native_recall']:.3f} | "
            f"{m['all_points']['ap']:.4f} | {m['above_ground']['ap']:.4f} | {m['n_clamped']:,} ({m['n_clamped_positive']}) | {m['seconds']:.1f} |"
        )
    cs = res["methods"]
    rows += [""]
    for k in ("collisionsplatting", "collisionsplatting_nsigma0", "collisionsplatting_nsigma2"):
        if k in cs:
            m = cs[k]
            tie = (
                f" (min_s2 = 0, one tie group, at {m['n_zero_min_s2']:,} queries, {m['n_zero_min_s2_negative']:,} of them free)"
                if m["n_zero_min_s2"]
                else ""
            )
            rows.append(
                f"- CollisionSplatting n_sigma={m['n_sigma']:g} with `-min(min_s2, cap)` instead of `-softmin`: AP {m['min_s2']['ap']:.4f}, "
                f"best F1 {m['min_s2']['best_f1']:.4f}{tie}."
            )
    for k, v in res.get("diagnostics", {}).items():
        rows.append(
            f"- Diagnostic: CollisionSplatting n_sigma={v['n_sigma']:g} without the {v['n_removed']} semi-transparent floaters "
            f"the default filter keeps: AP {v['ap']:.4f}, best F1 {v['best_f1']:.4f}."
        )
    rows += _variants_markdown(res)
    rows += [
        "",
        "Own rule = each method's native decision (CollisionSplatting: min_s2 < 1; Splat-Nav: max K < 1; SAFER-Splat: h < 0; "
        "ATLASNav: score < 0; SPLANNING: p > 0.01). Baselines other than SPLANNING are evaluated with exact spatial culling "
        "and a clamp far beyond their decision boundary (see `splatplan.eval.pr`); `clamped (pos.)` counts queries tied "
        "at the clamp and, in brackets, how many of them are positives (0 = AP/F1 exactly those of the unculled method).",
        "",
        "Culling check (random queries re-scored over all Gaussians): "
        + "; ".join(
            f"{DISPLAY[k]}: n={v.get('n', 0)}, max rel dev {v.get('max_rel_dev', 0):.1e}, clamp violation {v.get('max_clamp_violation', 0):.1e}"
            for k, v in res["culling_check"].items()
        ),
        "",
        f"Total time {res['seconds_total']:.0f} s on {res['threads']} CPU threads.",
        "",
    ]
    return "\n".join(rows)


def _cs_query(chk: Any, pts: np.ndarray, r: float, desc: str) -> tuple[np.ndarray, np.ndarray]:
    """CollisionSplatting (min_s2, softmin), each (Q,) float64, for sphere centres ``pts`` (Q, 3)."""
    ms, sm = [], []
    for i in progress(range(0, len(pts), 32768), desc=desc, unit="chunk"):
        res = chk.query(pts[i : i + 32768], None, (r, r, r))
        ms.append(np.asarray(res.min_s2))
        sm.append(np.asarray(res.softmin))
    return np.concatenate(ms).astype(np.float64), np.concatenate(sm).astype(np.float64)


class _PRSetup:
    """The scene, grid, labels and evaluation set of E1 (the same in the client and every worker)."""

    def __init__(self, scene: str, gt: str | None, cfg: PRConfig) -> None:
        from ..scenes.filters import filter_floaters

        r = float(cfg.radius)
        if scene == "stonehenge":
            from ..scenes.builtin.stonehenge import build_stonehenge

            raw, geom = build_stonehenge(level=cfg.level, seed=cfg.seed, n_splats=cfg.n_splats)
            self.scene_name = f"built-in Stonehenge level {cfg.level} seed {cfg.seed}"
        else:
            raw, geom, _ = load_scene_with_gt(scene, gt, filtered=False)
            self.scene_name = str(scene)
        self.raw = raw
        self.splats, self.rep = filter_floaters(raw)  # the default rule: o < 0.1 and max std > 5x median
        lo, hi = self.splats.bounds()
        self.grid, self.grid_spec = make_grid(lo - cfg.pad * r, hi + cfg.pad * r, cfg.spacing)  # (Q_all, 3)
        self.sdf = geom.sdf(self.grid)  # (Q_all,) exact signed distance, scene units
        self.label_all = self.sdf < r
        self.reach = self.sdf > -r  # evaluation set
        self.above = self.reach & (self.grid[:, 2] > r)
        self.q = self.grid[self.reach]
        self.y = self.label_all[self.reach]
        self.near = np.abs(self.sdf[self.reach] - r) < 0.5 * r  # near the decision boundary (for the culling check)


class PRContext(_PRSetup):
    """Per-worker state of E1's scoring tasks: the setup, the checkers, the torch scene tensors."""

    def __init__(self, scene: str, gt: str | None, cfg_dict: dict, device: str) -> None:
        from ..metric import CollisionChecker

        cfg = PRConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in cfg_dict.items()})
        super().__init__(scene, gt, cfg)
        self.cfg = cfg
        self.device = device
        self.checker = CollisionChecker(self.splats, n_sigma=1.0, device=device)
        self.scenes_v = {"default": self.splats, "opacity": self.raw.subset(self.raw.opacities >= cfg.eval_opacity_below)}
        self.checkers_v: dict[str, Any] = {"default": self.checker}

    def checker_v(self, kind: str):
        from ..metric import CollisionChecker

        if kind not in self.checkers_v:
            self.checkers_v[kind] = CollisionChecker(self.scenes_v[kind], n_sigma=1.0, device=self.device)
        return self.checkers_v[kind]


def make_pr_context(scene: str, gt: str | None, cfg_dict: dict, device: str) -> PRContext:
    return PRContext(scene, gt, cfg_dict, device)


def pr_task(spec: dict, ctx: PRContext) -> dict:
    """One E1 scoring task (see :func:`run_pr`): CollisionSplatting at one n_sigma, one culled
    baseline (+ its culling check) or one variant at one n_sigma. Deterministic (no RNG but the
    culling check's, seeded by ``check_seed``)."""
    import torch

    cfg, r, t0 = ctx.cfg, float(ctx.cfg.radius), time.perf_counter()
    if spec["kind"] == "cs":
        min_s2, softmin = _cs_query(ctx.checker.with_config(n_sigma=float(spec["n_sigma"])), ctx.grid, r, f"CollisionSplatting n_sigma={spec['n_sigma']:g}")
        return {"min_s2": min_s2, "softmin": softmin, "seconds": time.perf_counter() - t0}
    if spec["kind"] == "variant":
        _, kind, changes = variant_settings(spec["name"], cfg)
        chk = ctx.checker_v(kind).with_config(n_sigma=float(spec["n_sigma"]), **changes)
        min_s2, softmin = _cs_query(chk, ctx.grid, r, f"{spec['name']} n_sigma={spec['n_sigma']:g}")
        return {"min_s2": min_s2, "softmin": softmin, "seconds": time.perf_counter() - t0}
    from ..baselines import BASELINES, as_scene_tensors

    name = spec["name"]
    info = BASELINES[name]
    scene_t = as_scene_tensors(ctx.splats, "cpu", torch.float32)
    full_obj = info.cls(scene_t, "cpu")
    incl, clamp, rule = _cull_rule(name, full_obj, r)
    s_eval, cl_eval, n_pairs = culled_collision_scores(info.cls, scene_t, incl, clamp, ctx.q, r, cfg.tile, cfg.block, desc=DISPLAY[name])
    # deep points (sdf <= -r): far from every splat surface; same culled evaluation
    s_all = np.full(len(ctx.grid), np.nan)
    s_all[ctx.reach] = s_eval
    if (~ctx.reach).any():
        s_deep, _, _ = culled_collision_scores(info.cls, scene_t, incl, clamp, ctx.grid[~ctx.reach], r, cfg.tile, cfg.block, desc=DISPLAY[name] + " (deep)")
        s_all[~ctx.reach] = s_deep
    dt = time.perf_counter() - t0
    t1 = time.perf_counter()
    # batch-1 calls: intra-op threads only add barrier waits on a busy machine
    with set_torch_threads(1), torch.no_grad():
        check = _culling_check(name, full_obj, ctx.q, s_eval, cl_eval, ctx.near, r, cfg)
    check["seconds"] = time.perf_counter() - t1
    return {"s_all": s_all, "cl_eval": cl_eval, "n_pairs": int(n_pairs), "rule": rule, "seconds": dt, "check": check}


def _task_key(ran, kind: str, name: str = "", ns: float | None = None) -> str:
    return ran.key_of[(kind, name, None if ns is None else float(ns))]


def _run_scoring(out_dir: Path, scene: str, gt: str | None, cfg: PRConfig, names: tuple[str, ...], device: str, engine):
    """Every scoring task of E1 on the job engine; the baselines (the heaviest) are submitted first."""
    import functools
    import hashlib

    from .engine import Task, code_version, run_tasks

    cfg_dict = {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(cfg).items()}
    src = {"config": cfg_dict, "scene": str(Path(scene).resolve()) if scene != "stonehenge" else scene, "gt": gt, "device": device, "code": code_version()}
    sig = hashlib.sha1(json.dumps(src, sort_keys=True, default=str).encode()).hexdigest()[:8]
    specs = [("baseline", n, None) for n in names] + [("cs", "", float(ns)) for ns in cfg.n_sigmas]
    specs += [("variant", v, float(ns)) for v in cfg.variants for ns in cfg.n_sigmas]
    tasks, key_of = [], {}
    for kind, name, ns in specs:
        key = f"{sig}/{kind}" + (f"/{name}" if name else "") + ("" if ns is None else f"/ns={ns:g}")
        tasks.append(Task(key, {"kind": kind, "name": name, "n_sigma": ns}))
        key_of[(kind, name, ns)] = key
    # absolute paths: a worker of an existing cluster may run in another folder
    factory = functools.partial(make_pr_context, src["scene"], None if gt is None else str(Path(gt).resolve()), cfg_dict, device)
    ran = run_tasks(tasks, pr_task, factory, engine, Path(out_dir) / "pr.results.jsonl", desc="E1 scoring")
    if ran.errors:
        k, e = next(iter(ran.errors.items()))
        raise SplatplanError(f"E1: {len(ran.errors)} scoring task(s) failed (recorded in {Path(out_dir) / 'pr.results.jsonl'}), e.g. {k}: {e}")
    ran.key_of = key_of
    return ran


def run_pr(
    out_dir: Path, scene: str = "stonehenge", gt: str | None = None, quick: bool = False, config: PRConfig | None = None, device: str = "auto", engine=None
) -> dict:
    """Run E1 and write ``pr.json``, ``pr.png``, ``pr.md`` into ``out_dir``.

    Args:
        out_dir: output folder (created).
        scene: "stonehenge" (built-in) or a splat file path (then ``gt`` is required).
        gt: ground-truth ``.gt.json`` of a scene file (boxes with an exact SDF).
        quick: the < 1 min smoke version (:meth:`PRConfig.quick`).
        config: explicit knobs (overrides ``quick``).
        device: where CollisionSplatting's kernel runs ("auto" = CUDA when present, "cpu",
            "cuda", "cuda:N"). The baselines' culled tile evaluation is a CPU algorithm (many small
            torch calls on a thread pool) and always runs on the CPU.
        engine: where the scoring runs (:class:`~splatplan.eval.engine.EngineConfig` or its dict;
            default serial): each CollisionSplatting n_sigma, each baseline (with its culling
            check) and each variant x n_sigma is one task; the scene is built once per worker;
            finished tasks stream to ``pr.results.jsonl`` (scores in ``pr.results.jsonl.arrays/``)
            and a rerun with the same settings skips them.

    Returns:
        The dict written to ``pr.json``.
    """
    import torch

    from ..baselines import BASELINES, as_scene_tensors
    from ..metric import CollisionChecker

    cfg = (config or (PRConfig.quick() if quick else PRConfig())).validate()
    if not (cfg.spacing > 0 and cfg.radius > 0 and cfg.tile > 0):
        raise SplatplanError("PRConfig: spacing, radius and tile must be > 0")
    for v in cfg.variants:
        variant_settings(v, cfg)  # unknown names fail before any work
    names = tuple(n for n in BASELINE_NAMES if n in cfg.baselines)  # table order
    if set(cfg.baselines) - set(BASELINE_NAMES) or not names:
        raise SplatplanError(f"PRConfig.baselines must be a non-empty subset of {', '.join(BASELINE_NAMES)}, got {', '.join(cfg.baselines) or 'none'}")
    if cfg.variant_baseline not in ("best", "none", *names):
        raise SplatplanError(f"PRConfig.variant_baseline must be 'best', 'none' or one of {', '.join(names)}, got {cfg.variant_baseline!r}")
    if 1.0 not in [float(v) for v in cfg.n_sigmas] or any(not (np.isfinite(v) and v >= 0) for v in cfg.n_sigmas):
        raise SplatplanError(f"PRConfig.n_sigmas must be finite, >= 0 and include 1 (the headline), got {cfg.n_sigmas}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    t_all = time.perf_counter()
    threads = cpu_threads()  # torch threads in the scoring: see culled_collision_scores / pr_task
    r = float(cfg.radius)

    if scene == "stonehenge" and gt is not None:
        raise SplatplanError("--gt is only for a scene file; the built-in stonehenge carries its own ground truth")
    st = _PRSetup(scene, gt, cfg)
    raw, splats, rep, scene_name = st.raw, st.splats, st.rep, st.scene_name
    grid, grid_spec, sdf, label_all, reach, above, q, y, near = st.grid, st.grid_spec, st.sdf, st.label_all, st.reach, st.above, st.q, st.y, st.near
    if not y.any():
        raise SplatplanError("no grid point is in collision: is the ground truth in the scene's frame and units?")

    def summarise(score_all: np.ndarray, native_thr: float | None) -> dict[str, Any]:
        # score_all: (Q_all,) collision score on every grid point
        d = pr_summary(score_all[reach], y, native_thr)
        d["all_points"] = pr_summary(score_all, label_all)
        d["above_ground"] = pr_summary(score_all[above], label_all[above]) if label_all[above].any() else {"ap": float("nan"), "best_f1": float("nan")}
        return d

    methods: dict[str, dict] = {}
    curves: dict[str, tuple] = {}

    # --- CollisionSplatting: the kernel on every grid point
    checker = CollisionChecker(splats, n_sigma=1.0, device=device)
    cap = checker.config.s2_cap
    ran = _run_scoring(out_dir, scene, gt, cfg, names, str(checker.device), engine)
    for ns in cfg.n_sigmas:
        t_cs = ran.rows[_task_key(ran, "cs", ns=ns)]
        min_s2, softmin, dt = t_cs["min_s2"], t_cs["softmin"], t_cs["seconds"]
        score_min = -np.minimum(min_s2, cap)  # (Q_all,) -min(min_s2, cap)
        score_soft = -softmin  # (Q_all,) -softmin (+inf softmin, empty neighbourhood -> -inf)
        d = summarise(score_soft, None)
        # own rule: collision iff n_colliding > 0 iff min_s2 < 1
        d.update({f"native_{k_}": v for k_, v in _decision_prf(min_s2[reach] < 1.0, y).items()})
        dm = summarise(score_min, -1.0)
        key = "collisionsplatting" if float(ns) == 1.0 else f"collisionsplatting_nsigma{ns:g}"
        clamped = min_s2[reach] >= cap
        methods[key] = {
            "score": "-softmin",
            "n_sigma": float(ns),
            **d,
            "min_s2": {"score": "-min(min_s2, s2_cap)", **{k_: v for k_, v in dm.items() if not k_.startswith("native_")}},
            "n_zero_min_s2": int(np.sum(min_s2[reach] == 0.0)),
            "n_zero_min_s2_negative": int(np.sum((min_s2[reach] == 0.0) & ~y)),
            "n_clamped": int(clamped.sum()),
            "n_clamped_positive": int((clamped & y).sum()),
            "seconds": dt,
        }
        p, rc, _ = precision_recall_curve(score_soft[reach], y)
        curves[key] = (*_thin_curve(p, rc, cfg.plot_points), d["ap"])
        if float(ns) == 1.0:
            p, rc, _ = precision_recall_curve(score_min[reach], y)
            curves["collisionsplatting_min_s2"] = (*_thin_curve(p, rc, cfg.plot_points), dm["ap"])

    # --- diagnostic (built-in scene only): the same metric without the floaters the default
    # filter keeps (semi-transparent, 0.1 <= opacity < 0.3). The generator appends its floaters
    # last and the filter keeps order, so they are the last ``n_floaters - n_dropped`` splats.
    diagnostics: dict[str, Any] = {}
    n_kept_floaters = int(splats.info.get("n_floaters", 0)) - int(rep.n_dropped) if scene == "stonehenge" else 0
    if n_kept_floaters > 0:
        clean = CollisionChecker(splats.subset(np.arange(len(splats) - n_kept_floaters)), n_sigma=1.0, device=device)
        for ns in cfg.n_sigmas:
            soft = np.concatenate(
                [clean.with_config(n_sigma=float(ns)).query(q[i : i + 32768], None, (r, r, r)).softmin for i in range(0, len(q), 32768)]
            ).astype(np.float64)
            d = pr_summary(-soft, y)
            diagnostics[f"nsigma{ns:g}_without_kept_floaters"] = {"n_sigma": float(ns), "n_removed": n_kept_floaters, "ap": d["ap"], "best_f1": d["best_f1"]}

    # --- baselines, culled
    checks: dict[str, dict] = {}
    for name in names:
        info = BASELINES[name]
        t_b = ran.rows[_task_key(ran, "baseline", name=name)]
        s_all, cl_eval, n_pairs, rule, dt = t_b["s_all"], np.asarray(t_b["cl_eval"], bool), t_b["n_pairs"], t_b["rule"], t_b["seconds"]
        s_eval = s_all[reach]
        d = summarise(s_all, info.collision_threshold)
        methods[name] = {
            "score": {"splatnav": "-min_i max_t K_i", "safersplat": "-min_i h_i", "atlasnav": "-min_i (dist(p, mu_i) - 3 sigma_i - r)", "splanning": "p = 1 - exp(-I/4pi)"}[name],
            **d,
            "culling": rule,
            "n_clamped": int(cl_eval.sum()),
            "n_clamped_positive": int((cl_eval & y).sum()),
            "n_pairs": int(n_pairs),
            "seconds": dt,
        }
        p, rc, _ = precision_recall_curve(s_eval, y)
        curves[name] = (*_thin_curve(p, rc, cfg.plot_points), d["ap"])
        checks[name] = t_b["check"]

    # --- fidelity variants of CollisionSplatting (issue #7): same grid, labels and evaluation set
    opaque = raw.subset(raw.opacities >= cfg.eval_opacity_below)  # the paper authors' evaluation filter
    scenes_v = {"default": splats, "opacity": opaque}
    checkers_v: dict[str, Any] = {"default": checker}
    variants: dict[str, dict] = {}
    curves_v: dict[str, tuple] = {}
    for name in cfg.variants:
        label, kind, changes = variant_settings(name, cfg)
        if kind not in checkers_v:
            checkers_v[kind] = CollisionChecker(scenes_v[kind], n_sigma=1.0, device=device)
        by_ns = {}
        for ns in cfg.n_sigmas:
            t_v = ran.rows[_task_key(ran, "variant", name=name, ns=ns)]
            min_s2_v, soft_v = t_v["min_s2"], t_v["softmin"]
            d = summarise(-soft_v, None)
            d.update({f"native_{k_}": v for k_, v in _decision_prf(min_s2_v[reach] < 1.0, y).items()})
            by_ns[f"{ns:g}"] = {
                "n_sigma": float(ns),
                "ap": d["ap"],
                "best_f1": d["best_f1"],
                "native_precision": d["native_precision"],
                "native_recall": d["native_recall"],
                "ap_all_points": d["all_points"]["ap"],
                "ap_above_ground": d["above_ground"]["ap"],
                "seconds": t_v["seconds"],
            }
            if float(ns) == 1.0:
                p, rc, _ = precision_recall_curve(-soft_v[reach], y)
                curves_v[name] = (*_thin_curve(p, rc, cfg.plot_points), d["ap"])
        variants[name] = {"label": label, "scene": kind, "n_splats": len(scenes_v[kind]), "metric": changes, "by_n_sigma": by_ns}

    # the best (or a chosen) baseline on the opacity-filtered scene, for a like-for-like comparison with (b)
    variant_baseline: dict[str, Any] = {}
    vb = max(names, key=lambda n: methods[n]["ap"]) if cfg.variant_baseline == "best" else cfg.variant_baseline
    if vb != "none" and any(variant_settings(v, cfg)[1] == "opacity" for v in cfg.variants):
        t0 = time.perf_counter()
        info = BASELINES[vb]
        scene_o = as_scene_tensors(opaque, "cpu", torch.float32)
        incl, clamp, rule = _cull_rule(vb, info.cls(scene_o, "cpu"), r)
        s_eval, cl_eval, _ = culled_collision_scores(info.cls, scene_o, incl, clamp, q, r, cfg.tile, cfg.block, desc=DISPLAY[vb] + " (opacity filter)")
        d = pr_summary(s_eval, y, info.collision_threshold)
        variant_baseline = {
            "method": vb,
            "why": "the best baseline" if cfg.variant_baseline == "best" else "chosen by variant_baseline",
            "scene": "opacity",
            "n_splats": len(opaque),
            "ap": d["ap"],
            "best_f1": d["best_f1"],
            "native_precision": d["native_precision"],
            "native_recall": d["native_recall"],
            "ap_default_scene": methods[vb]["ap"],
            "n_clamped_positive": int((cl_eval & y).sum()),
            "seconds": time.perf_counter() - t0,
        }
        p, rc, _ = precision_recall_curve(s_eval, y)
        curves_v[f"{vb}_opacity"] = (*_thin_curve(p, rc, cfg.plot_points), d["ap"])
    softmin_check = _softmin_check(checkers_v, scenes_v, cfg, q, near, r)

    order = ["collisionsplatting", *names] + [k for k in methods if k.startswith("collisionsplatting_")]
    methods = {k: methods[k] for k in order if k in methods}
    res = {
        "n_queries": int(len(q)),
        "n_positive": int(y.sum()),
        "n_queries_all": int(len(grid)),
        "n_positive_all": int(label_all.sum()),
        "n_queries_above_ground": int(above.sum()),
        "n_positive_above_ground": int(label_all[above].sum()),
        "methods": methods,
        "scene": scene_name,
        "n_splats": len(splats),
        "floaters_dropped": int(rep.n_dropped),
        "splat_max_std": {k: float(np.percentile(splats.scales.max(1), v)) for k, v in (("median", 50), ("p99", 99), ("max", 100))},
        "radius": r,
        "grid": grid_spec,
        "evaluation_set": "grid points with sdf > -r (reachable from free space); 'all_points' and 'above_ground' (z > r) per method",
        "ground_truth": "exact signed distance to the analytic boxes < r",
        "collisionsplatting_score": (
            "-softmin (t = %g) is the headline score; -min(min_s2, s2_cap) (s2_cap = %g) under 'min_s2': it saturates at "
            "min_s2 = 0 for n_sigma > 0 (s2~ = max(0, ...)), which ties every query inside a splat's inflated core"
        ) % (checker.config.softmin_t, cap),
        "culling_check": checks,
        "diagnostics": diagnostics,
        "variants": variants,
        "variant_baseline": variant_baseline,
        "softmin_check": softmin_check,
        "device": str(checker.device),
        "baseline_device": "cpu",
        "quick": bool(quick),
        "note": cfg.note,
        "config": {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(cfg).items()},
        "threads": threads,
        "engine": ran.engine,
        "seconds_total": time.perf_counter() - t_all,
    }
    ours, best_base = methods["collisionsplatting"]["ap"], max(methods[n]["ap"] for n in names)
    res["targets"] = {
        "best_baseline": max(names, key=lambda n: methods[n]["ap"]),
        "ap_minus_best_baseline": ours - best_base,
        "ap_within_0.02_of_best_baseline_or_above": bool(ours >= best_base - 0.02),
        "atlasnav_below_ours": bool(methods["atlasnav"]["ap"] < ours) if "atlasnav" in methods else None,
        "ap_minus_best_baseline_by_variant": {
            f"{k}{'' if sc == 'softmin' else '_min_s2'}": (m["ap"] if sc == "softmin" else m["min_s2"]["ap"]) - best_base
            for k, m in methods.items()
            if k.startswith("collisionsplatting")
            for sc in ("softmin", "min_s2")
        },
    }
    if variants:
        best_v = max(variants, key=lambda k: variants[k]["by_n_sigma"].get("1", {"ap": -1.0})["ap"])
        res["targets"]["best_variant_at_n_sigma_1"] = best_v
        res["targets"]["ap_minus_best_baseline_by_fidelity_variant"] = {
            k: v["by_n_sigma"]["1"]["ap"] - best_base for k, v in variants.items() if "1" in v["by_n_sigma"]
        }
    (out_dir / "pr.json").write_text(json.dumps(res, indent=2) + "\n")
    _plot(curves, out_dir / "pr.png", f"E1: {scene_name}, {len(q):,} queries (sdf > -r), r = {r}", curves_v, variants)
    (out_dir / "pr.md").write_text(report(res))
    return res


def _softmin_check(checkers: dict, scenes: dict, cfg: PRConfig, q: np.ndarray, near: np.ndarray, r: float) -> dict[str, Any]:
    """Float32 kernel vs float64 reference softmin for every log-mean-exp variant at n_sigma = 1 on
    ``n_softmin_check`` queries near the surface: a sharp temperature (t = lme_t on s2~) must not
    underflow the kernel's exponentials (an underflow shows as +inf or a large deviation)."""
    from ..metric.reference import collision_metric_ref

    out: dict[str, Any] = {}
    rng = np.random.default_rng(cfg.check_seed)
    idx = np.nonzero(near)[0]
    if len(idx) == 0 or cfg.n_softmin_check <= 0:
        return out
    idx = rng.choice(idx, min(cfg.n_softmin_check, len(idx)), replace=False)
    pts = q[idx]
    for name in cfg.variants:
        label, kind, changes = variant_settings(name, cfg)
        if changes.get("softmin_mode") != "mean":
            continue
        chk = checkers[kind].with_config(n_sigma=1.0, **changes)
        got = np.asarray(chk.query(pts, None, (r, r, r)).softmin, dtype=np.float64)
        sc = scenes[kind]
        ref = collision_metric_ref(sc.means, sc.quats, sc.scales, pts, None, np.full(3, r), chk.config, chunk=4, opacities=sc.opacities).softmin
        both = np.isfinite(ref) & np.isfinite(got)
        out[name] = {
            "n": int(len(idx)),
            "softmin_t": float(chk.config.softmin_t),
            "max_abs_dev": float(np.max(np.abs(got[both] - ref[both]))) if both.any() else 0.0,
            "n_inf_mismatch": int(np.sum(np.isfinite(ref) != np.isfinite(got))),
        }
    return out
