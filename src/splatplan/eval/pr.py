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

Fidelity variants
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

Code: :func:`run` is the protocol (``run(PRConfig(...)) -> PRResult``, no files written but the
engine's results file when asked); :func:`report` writes ``pr.json``, ``pr.md`` and ``pr.png`` (all
curves; variants on the right). The configuration is in ``_pr_config``, the metrics in
``_pr_metrics``, the culling per baseline in ``_pr_culling``, the engine tasks in ``_pr_scoring``, the figure and tables in ``_pr_report``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import SplatplanError
from .._warp import cpu_threads
from ._common import DISPLAY
from ._pr_config import BASELINE_NAMES, VARIANTS, PRConfig, variant_settings  # noqa: F401 (BASELINE_NAMES: re-exported)
from ._pr_metrics import average_precision, best_f1, decision_prf, pr_summary, precision_recall_curve, thin_curve
from ._pr_report import Curve, pr_figure
from ._pr_report import markdown as _markdown
from ._pr_scoring import PRSetup, cs_query, run_scoring
from ._study import config_dict, write_outputs
from ..metric.config import MetricConfig  # the paper-reproduction studies run the paper's exact settings

__all__ = ["PRConfig", "PRResult", "VARIANTS", "precision_recall_curve", "average_precision", "best_f1", "pr_summary", "markdown", "report", "run"]

#: fields of :class:`PRResult` that feed the figure only (not written to pr.json)
_PLOT_ONLY = ("curves", "variant_curves")


@dataclass
class PRResult:
    """What E1 measured: every field but the curves is a key of ``pr.json`` (same names, same order).

    Sets: the evaluation set (grid points with sdf > -r), all grid points, and the evaluation-set
    points above the ground (z > r); see the module docstring.
    """

    #: evaluation-set queries and how many of them collide
    n_queries: int
    n_positive: int
    #: every grid point and how many collide
    n_queries_all: int
    n_positive_all: int
    #: evaluation-set points with z > r and how many collide
    n_queries_above_ground: int
    n_positive_above_ground: int
    #: method key -> AP, best F1, own-rule P/R/F1, per-set APs, clamp counts, seconds (table order)
    methods: dict[str, dict]
    #: scene description, its splat count after the floater filter and the floaters dropped
    scene: str
    n_splats: int
    floaters_dropped: int
    #: percentiles (median, p99, max) of the splats' largest std (scene units)
    splat_max_std: dict[str, float]
    #: robot sphere radius (scene units)
    radius: float
    #: the query lattice: lo, hi, spacing, shape
    grid: dict
    #: the evaluation set, the ground truth and CollisionSplatting's scores, in words
    evaluation_set: str
    ground_truth: str
    collisionsplatting_score: str
    #: baseline -> the culling check (re-scored sample over all Gaussians: largest deviations)
    culling_check: dict[str, dict]
    #: CollisionSplatting without the semi-transparent floaters the default filter keeps (built-in scene)
    diagnostics: dict[str, dict]
    #: fidelity variant -> label, scene, metric changes and AP etc. per n_sigma
    variants: dict[str, dict]
    #: the baseline re-scored on the opacity-filtered scene (empty when not run)
    variant_baseline: dict[str, Any]
    #: log-mean-exp variant -> float32 kernel vs float64 reference softmin (underflow check)
    softmin_check: dict[str, dict]
    #: where CollisionSplatting ran; the baselines always run on the CPU
    device: str
    baseline_device: str
    #: the smoke-test settings were used
    quick: bool
    note: str
    #: the PRConfig (tuples as lists)
    config: dict[str, Any]
    #: torch threads of the client
    threads: int
    #: the job engine that ran the scoring tasks
    engine: dict
    seconds_total: float
    #: AP differences to the best baseline and the study's pass/fail targets
    targets: dict[str, Any]
    #: figure only: key -> thinned (precision, recall, AP) of the main panel
    curves: dict[str, Curve] = field(default_factory=dict, repr=False)
    #: figure only: fidelity variants (and the baseline on the opacity-filtered scene) at n_sigma = 1
    variant_curves: dict[str, Curve] = field(default_factory=dict, repr=False)

    def to_json(self) -> dict[str, Any]:
        """The content of ``pr.json``."""
        return {f.name: getattr(self, f.name) for f in fields(self) if f.name not in _PLOT_ONLY}


class _Eval:
    """Summaries of a score over E1's three sets (evaluation set, all points, above ground)."""

    def __init__(self, st) -> None:
        self.st = st

    def summarise(self, score_all: np.ndarray, native_thr: float | None) -> dict[str, Any]:
        # score_all: (Q_all,) collision score on every grid point
        st = self.st
        d = pr_summary(score_all[st.reach], st.y, native_thr)
        d["all_points"] = pr_summary(score_all, st.label_all)
        above_pos = st.label_all[st.above]
        d["above_ground"] = pr_summary(score_all[st.above], above_pos) if above_pos.any() else {"ap": float("nan"), "best_f1": float("nan")}
        return d

    def curve(self, score_eval: np.ndarray, ap: float, n: int) -> Curve:
        """The thinned PR curve of ``score_eval`` (Q,) on the evaluation set."""
        p, rc, _ = precision_recall_curve(score_eval, self.st.y)
        return (*thin_curve(p, rc, n), ap)


def _collisionsplatting_rows(ev: _Eval, scored, cfg: PRConfig, cap: float, curves: dict) -> dict[str, dict]:
    """CollisionSplatting at every n_sigma: the ``-softmin`` headline and ``-min(min_s2, cap)`` beside it."""
    st, methods = ev.st, {}
    for ns in cfg.n_sigmas:
        t_cs = scored.row("cs", ns=ns)
        min_s2, softmin = t_cs["min_s2"], t_cs["softmin"]
        score_min = -np.minimum(min_s2, cap)  # (Q_all,) -min(min_s2, cap)
        score_soft = -softmin  # (Q_all,) -softmin (+inf softmin, empty neighbourhood -> -inf)
        d = ev.summarise(score_soft, None)
        # own rule: collision iff n_colliding > 0 iff min_s2 < 1
        d.update({f"native_{k_}": v for k_, v in decision_prf(min_s2[st.reach] < 1.0, st.y).items()})
        dm = ev.summarise(score_min, -1.0)
        key = "collisionsplatting" if float(ns) == 1.0 else f"collisionsplatting_nsigma{ns:g}"
        clamped = min_s2[st.reach] >= cap
        methods[key] = {
            "score": "-softmin",
            "n_sigma": float(ns),
            **d,
            "min_s2": {"score": "-min(min_s2, s2_cap)", **{k_: v for k_, v in dm.items() if not k_.startswith("native_")}},
            "n_zero_min_s2": int(np.sum(min_s2[st.reach] == 0.0)),
            "n_zero_min_s2_negative": int(np.sum((min_s2[st.reach] == 0.0) & ~st.y)),
            "n_clamped": int(clamped.sum()),
            "n_clamped_positive": int((clamped & st.y).sum()),
            "seconds": t_cs["seconds"],
        }
        curves[key] = ev.curve(score_soft[st.reach], d["ap"], cfg.plot_points)
        if float(ns) == 1.0:
            curves["collisionsplatting_min_s2"] = ev.curve(score_min[st.reach], dm["ap"], cfg.plot_points)
    return methods


def _floater_diagnostics(st, cfg: PRConfig) -> dict[str, dict]:
    """(Built-in scene only) the same metric without the floaters the default filter keeps
    (semi-transparent, 0.1 <= opacity < 0.3). The generator appends its floaters last and the filter
    keeps order, so they are the last ``n_floaters - n_dropped`` splats."""
    from ..metric import CollisionChecker

    out: dict[str, dict] = {}
    n_kept_floaters = int(st.splats.info.get("n_floaters", 0)) - int(st.rep.n_dropped) if cfg.scene == "stonehenge" else 0
    if n_kept_floaters <= 0:
        return out
    r = float(cfg.radius)
    clean = CollisionChecker(st.splats.subset(np.arange(len(st.splats) - n_kept_floaters)), n_sigma=1.0, device=cfg.device, config=MetricConfig.paper())
    for ns in cfg.n_sigmas:
        soft = cs_query(clean.with_config(n_sigma=float(ns)), st.q, r, f"without kept floaters n_sigma={ns:g}")[1]
        d = pr_summary(-soft, st.y)
        out[f"nsigma{ns:g}_without_kept_floaters"] = {"n_sigma": float(ns), "n_removed": n_kept_floaters, "ap": d["ap"], "best_f1": d["best_f1"]}
    return out


#: each baseline's score in words (the JSON's ``methods[name]["score"]``)
_BASELINE_SCORE = {"splatnav": "-min_i max_t K_i", "safersplat": "-min_i h_i", "atlasnav": "-min_i (dist(p, mu_i) - 3 sigma_i - r)", "splanning": "p = 1 - exp(-I/4pi)"}


def _baseline_rows(ev: _Eval, scored, cfg: PRConfig, names: tuple[str, ...], curves: dict) -> tuple[dict[str, dict], dict[str, dict]]:
    """(method rows, culling checks) of the culled baselines."""
    from ..baselines import BASELINES

    st, methods, checks = ev.st, {}, {}
    for name in names:
        t_b = scored.row("baseline", name=name)
        s_all, cl_eval = t_b["s_all"], np.asarray(t_b["cl_eval"], bool)
        d = ev.summarise(s_all, BASELINES[name].collision_threshold)
        methods[name] = {
            "score": _BASELINE_SCORE[name],
            **d,
            "culling": t_b["rule"],
            "n_clamped": int(cl_eval.sum()),
            "n_clamped_positive": int((cl_eval & st.y).sum()),
            "n_pairs": int(t_b["n_pairs"]),
            "seconds": t_b["seconds"],
        }
        curves[name] = ev.curve(s_all[st.reach], d["ap"], cfg.plot_points)
        checks[name] = t_b["check"]
    return methods, checks


def _variant_rows(ev: _Eval, scored, cfg: PRConfig, n_splats: dict[str, int], curves_v: dict) -> dict[str, dict]:
    """CollisionSplatting's fidelity variants: same grid, labels and evaluation set."""
    st, variants = ev.st, {}
    for name in cfg.variants:
        label, kind, changes = variant_settings(name, cfg)
        by_ns = {}
        for ns in cfg.n_sigmas:
            t_v = scored.row("variant", name=name, ns=ns)
            min_s2_v, soft_v = t_v["min_s2"], t_v["softmin"]
            d = ev.summarise(-soft_v, None)
            d.update({f"native_{k_}": v for k_, v in decision_prf(min_s2_v[st.reach] < 1.0, st.y).items()})
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
                curves_v[name] = ev.curve(-soft_v[st.reach], d["ap"], cfg.plot_points)
        variants[name] = {"label": label, "scene": kind, "n_splats": n_splats[kind], "metric": changes, "by_n_sigma": by_ns}
    return variants


def _variant_baseline(ev: _Eval, cfg: PRConfig, names: tuple[str, ...], methods: dict, opaque, curves_v: dict) -> dict[str, Any]:
    """The best (or a chosen) baseline on the opacity-filtered scene, for a like-for-like comparison with (b)."""
    import torch

    from ..baselines import BASELINES, as_scene_tensors
    from ._pr_culling import cull_rule, culled_collision_scores

    vb = max(names, key=lambda n: methods[n]["ap"]) if cfg.variant_baseline == "best" else cfg.variant_baseline
    if vb == "none" or not any(variant_settings(v, cfg)[1] == "opacity" for v in cfg.variants):
        return {}
    t0, r, st = time.perf_counter(), float(cfg.radius), ev.st
    info = BASELINES[vb]
    scene_o = as_scene_tensors(opaque, "cpu", torch.float32)
    incl, clamp, _ = cull_rule(vb, info.cls(scene_o, "cpu"), r)
    s_eval, cl_eval, _ = culled_collision_scores(info.cls, scene_o, incl, clamp, st.q, r, cfg.tile, cfg.block, desc=DISPLAY[vb] + " (opacity filter)")
    d = pr_summary(s_eval, st.y, info.collision_threshold)
    curves_v[f"{vb}_opacity"] = ev.curve(s_eval, d["ap"], cfg.plot_points)
    return {
        "method": vb,
        "why": "the best baseline" if cfg.variant_baseline == "best" else "chosen by variant_baseline",
        "scene": "opacity",
        "n_splats": len(opaque),
        "ap": d["ap"],
        "best_f1": d["best_f1"],
        "native_precision": d["native_precision"],
        "native_recall": d["native_recall"],
        "ap_default_scene": methods[vb]["ap"],
        "n_clamped_positive": int((cl_eval & st.y).sum()),
        "seconds": time.perf_counter() - t0,
    }


def _targets(methods: dict, variants: dict, names: tuple[str, ...]) -> dict[str, Any]:
    """AP of ours against the best baseline, per n_sigma, score and fidelity variant."""
    ours, best_base = methods["collisionsplatting"]["ap"], max(methods[n]["ap"] for n in names)
    t = {
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
        t["best_variant_at_n_sigma_1"] = max(variants, key=lambda k: variants[k]["by_n_sigma"].get("1", {"ap": -1.0})["ap"])
        t["ap_minus_best_baseline_by_fidelity_variant"] = {k: v["by_n_sigma"]["1"]["ap"] - best_base for k, v in variants.items() if "1" in v["by_n_sigma"]}
    return t


def run(config: PRConfig, engine=None, *, results: str | Path | None = None) -> PRResult:
    """Run E1 (the protocol of the module docstring); writes no file but the engine's ``results``.

    Args:
        config: the knobs (:meth:`PRConfig.quick_config` for the smoke version); validated here.
        engine: where the scoring runs (:class:`~splatplan.eval.engine.EngineConfig` or its dict;
            default serial): each CollisionSplatting n_sigma, each baseline (with its culling
            check) and each variant x n_sigma is one task; the scene is built once per worker.
        results: JSON-lines file the finished tasks stream to (scores in ``<results>.arrays/``); a
            rerun with the same settings skips them. None: in memory only.

    Returns:
        :class:`PRResult` (``report`` writes it out).
    """
    from ..metric import CollisionChecker

    cfg = config.validate()
    names = cfg.baseline_names()
    t_all = time.perf_counter()
    threads = cpu_threads()  # torch threads in the scoring: see culled_collision_scores / pr_task
    st = PRSetup(cfg)
    if not st.y.any():
        raise SplatplanError("no grid point is in collision: is the ground truth in the scene's frame and units?")
    checker = CollisionChecker(st.splats, n_sigma=1.0, device=cfg.device, config=MetricConfig.paper())
    scored = run_scoring(cfg, names, str(checker.device), engine, results)
    ev = _Eval(st)
    curves: dict[str, Curve] = {}
    methods = _collisionsplatting_rows(ev, scored, cfg, checker.config.s2_cap, curves)
    diagnostics = _floater_diagnostics(st, cfg)
    base_rows, checks = _baseline_rows(ev, scored, cfg, names, curves)
    methods.update(base_rows)
    opaque = st.raw.subset(st.raw.opacities >= cfg.eval_opacity_below)  # the paper authors' evaluation filter
    scenes_v = {"default": st.splats, "opacity": opaque}
    curves_v: dict[str, Curve] = {}
    variants = _variant_rows(ev, scored, cfg, {k: len(v) for k, v in scenes_v.items()}, curves_v)
    variant_baseline = _variant_baseline(ev, cfg, names, methods, opaque, curves_v)
    softmin_check = _softmin_check(checker, scenes_v, cfg, st.q, st.near)
    order = ["collisionsplatting", *names] + [k for k in methods if k.startswith("collisionsplatting_")]
    methods = {k: methods[k] for k in order if k in methods}
    return PRResult(
        n_queries=int(len(st.q)),
        n_positive=int(st.y.sum()),
        n_queries_all=int(len(st.grid)),
        n_positive_all=int(st.label_all.sum()),
        n_queries_above_ground=int(st.above.sum()),
        n_positive_above_ground=int(st.label_all[st.above].sum()),
        methods=methods,
        scene=st.scene_name,
        n_splats=len(st.splats),
        floaters_dropped=int(st.rep.n_dropped),
        splat_max_std={k: float(np.percentile(st.splats.scales.max(1), v)) for k, v in (("median", 50), ("p99", 99), ("max", 100))},
        radius=float(cfg.radius),
        grid=st.grid_spec,
        evaluation_set="grid points with sdf > -r (reachable from free space); 'all_points' and 'above_ground' (z > r) per method",
        ground_truth="exact signed distance to the analytic boxes < r",
        collisionsplatting_score=(
            "-softmin (t = %g) is the headline score; -min(min_s2, s2_cap) (s2_cap = %g) under 'min_s2': it saturates at "
            "min_s2 = 0 for n_sigma > 0 (s2~ = max(0, ...)), which ties every query inside a splat's inflated core"
        ) % (checker.config.softmin_t, checker.config.s2_cap),
        culling_check=checks,
        diagnostics=diagnostics,
        variants=variants,
        variant_baseline=variant_baseline,
        softmin_check=softmin_check,
        device=str(checker.device),
        baseline_device="cpu",
        quick=bool(cfg.quick),
        note=cfg.note,
        config=config_dict(cfg),
        threads=threads,
        engine=scored.engine,
        seconds_total=time.perf_counter() - t_all,
        targets=_targets(methods, variants, names),
        curves=curves,
        variant_curves=curves_v,
    )


def markdown(result: PRResult) -> str:
    """The markdown of E1: the methods table, then CollisionSplatting's fidelity variants."""
    return _markdown(result.to_json())


def report(result: PRResult, out_dir: str | Path) -> list[Path]:
    """Write ``pr.json``, ``pr.md`` and ``pr.png`` into ``out_dir`` (an existing folder); returns their paths."""
    title = f"E1: {result.scene}, {result.n_queries:,} queries (sdf > -r), r = {result.radius}"
    fig = pr_figure(result.curves, title, result.variant_curves, result.variants)
    return write_outputs(out_dir, "pr", result.to_json(), markdown(result), (("pr.png", fig, None),))


def _softmin_check(checker, scenes: dict, cfg: PRConfig, q: np.ndarray, near: np.ndarray) -> dict[str, Any]:
    """Float32 kernel vs float64 reference softmin for every log-mean-exp variant at n_sigma = 1 on
    ``n_softmin_check`` queries near the surface: a sharp temperature (t = lme_t on s2~) must not
    underflow the kernel's exponentials (an underflow shows as +inf or a large deviation).

    ``checker``: the default scene's; ``scenes``: scene kind -> Splats (``q`` (Q, 3), ``near`` (Q,) bool)."""
    from ..metric import CollisionChecker
    from ..metric.reference import collision_metric_ref

    out: dict[str, Any] = {}
    rng = np.random.default_rng(cfg.check_seed)
    idx = np.nonzero(near)[0]
    if len(idx) == 0 or cfg.n_softmin_check <= 0:
        return out
    idx = rng.choice(idx, min(cfg.n_softmin_check, len(idx)), replace=False)
    pts, r = q[idx], float(cfg.radius)
    checkers = {"default": checker}
    for name in cfg.variants:
        label, kind, changes = variant_settings(name, cfg)
        if changes.get("softmin_mode") != "mean":
            continue
        if kind not in checkers:
            checkers[kind] = CollisionChecker(scenes[kind], n_sigma=1.0, device=cfg.device, config=MetricConfig.paper())
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
