"""The configuration of study E1 (:mod:`splatplan.eval.pr`): :class:`PRConfig`, the baselines it
scores (:data:`BASELINE_NAMES`) and the CollisionSplatting fidelity variants (:data:`VARIANTS`,
:func:`variant_settings`). A module of its own because both the protocol (:mod:`~splatplan.eval.pr`)
and its engine tasks (:mod:`~splatplan.eval._pr_scoring`) read it; ``splatplan.eval.pr`` re-exports
every name.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .._config import bounded
from ..errors import SplatplanError
from ..robots import point_radius
from ._study import StudyConfig

__all__ = ["BASELINE_NAMES", "PRConfig", "VARIANTS", "variant_settings"]

#: Order of the baselines in tables and plots.
BASELINE_NAMES = ("splatnav", "safersplat", "atlasnav", "splanning")

#: CollisionSplatting fidelity variants: name -> (label, scene, MetricConfig changes).
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
    "library_default": ("(e) the library's default MetricConfig ($library_default)", "default", {"$library_default": None}),
}


def variant_settings(name: str, cfg: "PRConfig") -> tuple[str, str, dict[str, Any]]:
    """(label, scene kind, MetricConfig changes) of variant ``name`` with ``cfg``'s values filled in."""
    if name not in VARIANTS:
        raise SplatplanError(f"unknown E1 variant {name!r}: choose from {', '.join(VARIANTS)}")
    from ..metric.config import MetricConfig

    label, kind, changes = VARIANTS[name]
    if "$library_default" in changes:  # the study runs the paper's settings; this variant the library's default
        from ..metric.config import PAPER_SETTINGS

        default = MetricConfig()
        changes = {k: getattr(default, k) for k in PAPER_SETTINGS}
        label = label.replace("$library_default", ", ".join(f"{k} = {v}" for k, v in changes.items()))
    subst = {"$lme_t": cfg.lme_t, "$opacity_min": cfg.opacity_min, "$default_t": MetricConfig().softmin_t}
    changes = {k: subst.get(v, v) if isinstance(v, str) else v for k, v in changes.items()}
    for key, val in subst.items():
        label = label.replace(key, f"{val:g}")
    label = label.replace("opacity < 0.1", f"opacity < {cfg.eval_opacity_below:g}")
    return label, kind, changes


@dataclass
class PRConfig(StudyConfig):
    """Knobs of the precision-recall study (defaults = the full run). ``device`` is where
    CollisionSplatting's kernel runs; the baselines' culled tile evaluation is a CPU algorithm (many
    small torch calls on a thread pool) and always runs on the CPU."""

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
    #: opacity_min (d1), opacity_scaled_inflation (d2), library_default (e: the library's default
    #: MetricConfig, the rest run the paper's); see VARIANTS.
    variants: tuple[str, ...] = (
        "default",
        "opacity_filter",
        "log_mean_exp",
        "log_mean_exp_default_t",
        "opacity_filter+log_mean_exp",
        "opacity_min",
        "opacity_scaled_inflation",
        "library_default",
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
    #: 'stonehenge' (built-in) or a splat file with --gt
    scene: str = "stonehenge"
    #: ground-truth .gt.json of a scene file (written by 'splatplan scene'); only with a scene file
    gt: str | None = None

    def check(self) -> None:
        """Cross-field rules: known variants and baselines, n_sigma 1 present, --gt only with a scene file."""
        for v in self.variants:
            variant_settings(v, self)  # unknown names fail before any work
        names = self.baseline_names()
        if set(self.baselines) - set(BASELINE_NAMES) or not names:
            raise SplatplanError(f"PRConfig.baselines must be a non-empty subset of {', '.join(BASELINE_NAMES)}, got {', '.join(self.baselines) or 'none'}")
        if self.variant_baseline not in ("best", "none", *names):
            raise SplatplanError(f"PRConfig.variant_baseline must be 'best', 'none' or one of {', '.join(names)}, got {self.variant_baseline!r}")
        if 1.0 not in [float(v) for v in self.n_sigmas] or any(not (np.isfinite(v) and v >= 0) for v in self.n_sigmas):
            raise SplatplanError(f"PRConfig.n_sigmas must be finite, >= 0 and include 1 (the headline), got {self.n_sigmas}")
        if self.scene == "stonehenge" and self.gt is not None:
            raise SplatplanError("--gt is only for a scene file; the built-in stonehenge carries its own ground truth")

    def baseline_names(self) -> tuple[str, ...]:
        """The chosen baselines in table order."""
        return tuple(n for n in BASELINE_NAMES if n in self.baselines)

    @classmethod
    def quick_config(cls) -> "PRConfig":
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
            quick=True,
        )
