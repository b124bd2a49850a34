"""What makes an ellipsoid collide, summarised for error messages and diagnostics
(:meth:`~.checker.CollisionChecker.blockers` fills a :class:`Blockers`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: splats fainter than this are "faint" in :class:`Blockers` (haze, floaters; the remedy names
#: ``MetricConfig.opacity_min``)
FAINT_OPACITY = 0.3


@dataclass
class Blockers:
    """The splats one ellipsoid counts as colliding (:meth:`CollisionChecker.blockers`).

    Attributes:
        indices: (n,) splat indices (s2~ < 1 at the checker's n_sigma, opacity filter applied).
        n: how many.
        n_inside: how many have their mean inside the ellipsoid (s2 < 1: colliding at n_sigma 0 too).
        n_faint: how many have opacity < :data:`FAINT_OPACITY`.
        opacity: (min, median, max) of their opacities (nan when n = 0).
        max_std: their largest standard deviation (scene units).
        centroid: (3,) mean of their means (world frame, scene units).
        n_sigma: the checker's n_sigma.
    """

    indices: np.ndarray
    n: int
    n_inside: int
    n_faint: int
    opacity: tuple[float, float, float]
    max_std: float
    centroid: np.ndarray
    n_sigma: float

    def remedy(self) -> str:
        """The change that would free the ellipsoid, in words (CLI flag names in parentheses)."""
        if self.n == 0:
            return "nothing blocks it"
        if self.n_faint == self.n:
            return (f"all are faint (opacity < {FAINT_OPACITY:g}, e.g. haze or floaters): count them as free space with "
                    f"opacity_min = {FAINT_OPACITY:g} (--opacity-min {FAINT_OPACITY:g}), or drop floaters when loading (scene align --drop-floaters)")
        if self.n_inside == 0:
            return f"only the n_sigma inflation reaches the robot (no splat mean is inside it): lower n_sigma (--n-sigma, e.g. 0)"
        return "splat means lie inside the robot: move the configuration away from them, or shrink the robot"

    def summary(self) -> str:
        """One clause: how many, how faint and large, where (scene units, world frame)."""
        if self.n == 0:
            return "no splat"
        lo, med, hi = self.opacity
        c = ", ".join(f"{v:.3f}" for v in self.centroid)
        return (f"{self.n} splat(s) ({self.n_inside} with the mean inside, {self.n_faint} faint) of opacity {lo:.3g}-{hi:.3g} "
                f"(median {med:.3g}), std up to {self.max_std:.3g}, around ({c}) (scene units)")
