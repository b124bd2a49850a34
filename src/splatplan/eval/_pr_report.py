"""Figure and markdown of study E1 (:mod:`splatplan.eval.pr`), from its JSON content and curves.

Matplotlib is imported here only (lazily by :func:`splatplan.eval.pr.report`); the figure is a
plain ``matplotlib.figure.Figure``, so no backend or pyplot state is touched.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ._common import DISPLAY
from ._study import note_lines

#: one PR curve for the figure: (precision (P,), recall (P,), AP), thinned to ``plot_points``
Curve = tuple[np.ndarray, np.ndarray, float]


def pr_figure(curves: dict[str, Curve], title: str, curves_v: dict[str, Curve] | None = None, variants: dict | None = None):
    """Left: every method's PR curve. Right (when variants ran): CollisionSplatting's fidelity
    variants at n_sigma = 1, with the best baseline on the same scenes for reference. Returns the Figure."""
    from matplotlib.figure import Figure

    two = bool(curves_v)
    fig = Figure(figsize=(12.8 if two else 6.4, 5.4), dpi=130)
    axs = fig.subplots(1, 2 if two else 1, squeeze=False)
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
    if two and curves_v:  # (two: curves_v is not empty)
        axv = axs[0][1]
        for i, (key, (p, r, ap)) in enumerate(curves_v.items()):
            if key in (variants or {}):  # decreasing widths and varied dashes: identical curves stay visible
                label, st = (variants or {})[key]["label"], dict(color=f"C{i}", lw=max(0.8, 3.2 - 0.4 * i), ls=("-", "--", "-.", ":")[i % 4])
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
    return fig


def _variants_markdown(res: dict) -> list[str]:
    """The fidelity-variants table: AP per n_sigma and the decision at n_sigma = 1."""
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


def markdown(res: dict[str, Any]) -> str:
    """The markdown of E1 from its JSON content: the methods table, then CollisionSplatting's fidelity variants."""
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
        *note_lines(res.get("note")),
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
