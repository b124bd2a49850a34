"""What makes an ellipsoid collide, summarised for error messages and diagnostics
(:meth:`~.checker.CollisionChecker.blockers` fills a :class:`Blockers`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from ..scenes.splats import Splats
    from .config import MetricConfig

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
        linearize: the checker's :attr:`~.config.MetricConfig.linearize`.
        floor: ``(floor_z, step_height)`` of the terrain removed from the scene for a ground robot
            (``Splats.info["terrain"]``, :func:`~splatplan.scenes.terrain.remove_terrain`), else None.
        height: (lowest, highest) height of their means above ``floor_z`` (nan without a floor).
        n_floor_level: how many reach into the terrain's step band within their inflation (mean z
            minus n_sigma_i times their std along z below ``floor_z + step_height``): matter standing
            on the floor, 0 without a floor.
        n_inside_faint: how many of the ``n_inside`` are faint.
    """

    indices: np.ndarray
    n: int
    n_inside: int
    n_faint: int
    opacity: tuple[float, float, float]
    max_std: float
    centroid: np.ndarray
    n_sigma: float
    linearize: str = "distance"
    floor: tuple[float, float] | None = None
    height: tuple[float, float] = (float("nan"), float("nan"))
    n_floor_level: int = 0
    n_inside_faint: int = 0

    def remedy(self) -> str:
        """The change that would free the ellipsoid, in words (CLI flag names in parentheses)."""
        if self.n == 0:
            return "nothing blocks it"
        if self.n_faint == self.n:
            return (f"all are faint (opacity < {FAINT_OPACITY:g}, e.g. haze or floaters): count them as free space with "
                    f"opacity_min = {FAINT_OPACITY:g} (--opacity-min {FAINT_OPACITY:g}), or drop floaters when loading (scene align --drop-floaters)")
        if self.floor is not None and self.n_floor_level == self.n:
            step = self.height[1] + 0.01  # scene units: just above the highest of them
            return (f"all stand on the floor ({self.height[0]:.3g}-{self.height[1]:.3g} above it, the terrain's step height is {self.floor[1]:g}): "
                    f"if this is floor-level matter (a rug, dust, a threshold) the robot may step over, raise the step height to {step:.2g} "
                    f"(TerrainConfig.step_height, --terrain-step-height {step:.2g}); else it is an obstacle: move the configuration")
        faint = ""
        if self.n_inside and self.n_inside_faint == self.n_inside:  # only faint means inside: they go with opacity_min
            faint = (f"the {self.n_inside} splat(s) with the mean inside are faint: count them as free space with opacity_min = "
                     f"{FAINT_OPACITY:g} (--opacity-min {FAINT_OPACITY:g}); of the rest, ")
        if self.n_inside == self.n_inside_faint:
            if self.linearize == "squared":
                return faint + ("only the n_sigma inflation reaches the robot (no splat mean is inside it), linearised in s2 (the paper's rule, "
                                "which overshoots for large splats far from thin links): linearise the distance (linearize = 'distance', "
                                "--linearize distance, the default) or lower n_sigma (--n-sigma, e.g. 0)")
            return faint + "only the n_sigma inflation reaches the robot (no splat mean is inside it): lower n_sigma (--n-sigma, e.g. 0)"
        return "splat means lie inside the robot: move the configuration away from them, or shrink the robot"

    def summary(self) -> str:
        """One clause: how many, how faint and large, where (scene units, world frame)."""
        if self.n == 0:
            return "no splat"
        lo, med, hi = self.opacity
        c = ", ".join(f"{v:.3f}" for v in self.centroid)
        where = ""
        if self.floor is not None:
            where = f", {self.height[0]:.3g}-{self.height[1]:.3g} above the floor ({self.n_floor_level} standing on it)"
        return (f"{self.n} splat(s) ({self.n_inside} with the mean inside, {self.n_faint} faint) of opacity {lo:.3g}-{hi:.3g} "
                f"(median {med:.3g}), std up to {self.max_std:.3g}, around ({c}){where} (scene units)")


def find_blockers(scene: Splats, config: MetricConfig, center, quat, semi_axes) -> Blockers:
    """:meth:`CollisionChecker.blockers` of ``scene`` at ``config``: the splats one ellipsoid counts
    (s2~ < 1), summarised (host numpy, the reference formulas)."""
    from ..scenes.splats import quat_to_rotmat
    from .reference import conservative_s2_ref, link_matrices, splat_inflation_ref
    from .wp_metric_kernel import search_radius

    sc = scene
    c = np.asarray(center, dtype=np.float64).reshape(3)
    ax = np.broadcast_to(np.asarray(semi_axes, dtype=np.float64), (3,))
    sig = np.asarray(sc.scales, dtype=np.float64).max(axis=1)  # (N,)
    rho = float(search_radius(float(config.n_sigma), float(sig.max()), float(ax.min()), float(ax.max()), 1.0))
    near = np.nonzero(np.sum((np.asarray(sc.means, dtype=np.float64) - c) ** 2, axis=1) <= rho * rho)[0]  # (M,) candidates
    keep, ns = splat_inflation_ref(sc.opacities, len(sc), config)
    near = near[keep[near]]
    a = link_matrices(None if quat is None else np.asarray(quat, dtype=np.float64).reshape(1, 4), ax, 1)
    s2, s2c = conservative_s2_ref(np.asarray(sc.means)[near], np.asarray(sc.quats)[near], np.asarray(sc.scales)[near], c[None], a, ns[near], config.linearize)
    hit = s2c[0] < 1.0
    idx = near[hit]
    op = np.asarray(sc.opacities, dtype=np.float64)[idx]
    terrain = (sc.info or {}).get("terrain")  # a ground robot's scene (scenes.terrain.remove_terrain)
    floor, height, n_floor = None, (np.nan, np.nan), 0
    if terrain is not None and idx.size:
        fz, step = float(terrain["floor_z"]), float(terrain["step_height"])
        z = np.asarray(sc.means, dtype=np.float64)[idx, 2]
        rz = quat_to_rotmat(np.asarray(sc.quats, dtype=np.float64)[idx])[:, 2, :]  # (n, 3): row z of R
        sz = np.sqrt(np.sum((rz * np.asarray(sc.scales, dtype=np.float64)[idx]) ** 2, axis=1))  # std along z
        floor, height = (fz, step), (float(z.min() - fz), float(z.max() - fz))
        n_floor = int(np.sum(z - ns[idx] * sz < fz + step))
    return Blockers(
        indices=idx, n=int(idx.size), n_inside=int(np.sum(s2[0][hit] < 1.0)), n_faint=int(np.sum(op < FAINT_OPACITY)),
        opacity=(float(op.min()), float(np.median(op)), float(op.max())) if idx.size else (np.nan,) * 3,
        max_std=float(sig[idx].max()) if idx.size else np.nan,
        centroid=np.asarray(sc.means, dtype=np.float64)[idx].mean(axis=0) if idx.size else np.full(3, np.nan),
        n_sigma=float(config.n_sigma), linearize=config.linearize, floor=floor, height=height, n_floor_level=n_floor,
        n_inside_faint=int(np.sum((s2[0][hit] < 1.0) & (op < FAINT_OPACITY))),
    )  # fmt: skip
