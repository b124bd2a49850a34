"""Configuration and result types of the CollisionSplatting metric (SPEC section 2)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._config import bounded, check_config


@dataclass
class MetricConfig:
    """Knobs of the CollisionSplatting metric. All distances are squared *scaling* distances
    (dimensionless: 1 on the link's surface), not metres."""

    #: Conservatism: a splat collides when its n_sigma-ellipsoid may reach into the link (s2~ < 1, see linearize). 0 = point cloud of splat means.
    n_sigma: float = bounded(1.0, ge=0)
    #: min_s2 is exact below this value; neighbourhood N(q) = {splats with s2~ < s2_cap}. Must be >= 1.
    s2_cap: float = bounded(4.0, ge=1)
    #: A link is in collision when more than this many splats have s2~ < 1.
    k_collide: int = bounded(0, ge=0)
    #: Softmin temperature t in -(1/t) log sum_{i in N(q)} exp(-t s2~_i). An integer multiple of
    #: cost_gamma (default 2x) lets the kernel reuse the cost's exponential (about 20% faster).
    softmin_t: float = bounded(8.0, ge=1e-3, le=1e4)  # 1/t and exp(-t s2~) stay finite in float32
    #: MPPI cost per splat d_max * exp(-gamma * max(s2~ - s_min, 0)) ...
    cost_d_max: float = bounded(1.0, ge=0)
    #: ... decay factor gamma ...
    cost_gamma: float = bounded(4.0, ge=1e-3, le=1e4)
    #: ... and the minimum allowable scaling distance s_min (1 = the link surface).
    cost_s_min: float = bounded(1.0, ge=0)
    #: How per-splat costs over N(q) are combined: "mean" (the paper) or "sum" or "max".
    cost_reduce: str = bounded("mean", choices=("mean", "sum", "max"))
    #: Softmin aggregation over N(q): "sum" = log-sum-exp -(1/t) log sum exp(-t s2~) (<= min_s2), or
    #: "mean" = log-mean-exp -(1/t) log((1/|N|) sum exp(-t s2~)) (the paper's "recursive softmin", in [min, mean]).
    softmin_mode: str = bounded("sum", choices=("sum", "mean"))
    #: Beyond the paper (our default): splats with opacity below this count as free
    #: space in every output (min_s2, n_colliding, collides, softmin, cost): a splat whose peak
    #: alpha is below 0.1 lets more than 90% of the light through everywhere, so it is haze, not a
    #: surface. 0 = use every splat (the paper, :meth:`paper`).
    opacity_min: float = bounded(0.1, ge=0, le=1)
    #: Beyond the paper (our default): inflate each splat by n_sigma * o_i * sigma_i
    #: instead of n_sigma * sigma_i, so faint splats get less conservatism (opaque ones the paper's).
    #: False = the paper (:meth:`paper`).
    opacity_scaled_inflation: bool = True
    #: Beyond the paper (our default): how the inflation is linearised at the splat mean. With
    #: sigma = |diag(s) R^T grad s2| (the splat's std along the gradient, scaled): "distance" linearises
    #: the scaling distance s = sqrt(s2), s2~ = max(0, s - n_sigma * sigma / (2 s))^2; "squared" (the
    #: paper, MetricConfig.paper()) linearises s2, s2~ = max(0, s2 - n_sigma * sigma). Both are lower bounds of
    #: the exact s2 over the splat's n_sigma-ellipsoid (s and s2 are convex), so neither misses a splat
    #: whose ellipsoid reaches into the link; they agree near the link's surface, and "distance" drops
    #: far less of the quadratic term the paper ignores, which for large splats far from a thin link
    #: (25 cm wall splats a metre from a 2 cm Go2 calf) makes "squared" report a collision.
    linearize: str = bounded("distance", choices=("distance", "squared"))

    def validate(self) -> "MetricConfig":
        """Check every field's declared range (:mod:`splatplan._config`); returns self."""
        return check_config(self)

    @classmethod
    def paper(cls, **changes) -> "MetricConfig":
        """The paper's exact settings (CollisionSplatting, SPEC section 2): every splat counts and
        is inflated by n_sigma * sigma_i whatever its opacity, linearised in s2 (``opacity_min = 0``,
        ``opacity_scaled_inflation = False``, ``linearize = "squared"``); ``changes`` override fields. The CLI's
        ``--paper-metric``; the paper-reproduction studies use it."""
        return cls(**{**PAPER_SETTINGS, **changes})


#: The fields where the default :class:`MetricConfig` departs from the paper, at the paper's values.
PAPER_SETTINGS = {"opacity_min": 0.0, "opacity_scaled_inflation": False, "linearize": "squared"}


COST_REDUCE_CODES = {"mean": 0, "sum": 1, "max": 2}


@dataclass
class QueryResult:
    """Per-query outputs, every array shaped like the query batch (e.g. (K, T, links)).

    The arrays are numpy arrays, torch tensors or ``wp.array``s: the type (and device) of the query
    input. Invalid device queries (NaN, zero quaternion, see ``CollisionChecker.query``) read
    min_s2 = softmin = cost = NaN, n_colliding = -1 and in_collision = True.

    Attributes:
        min_s2: float32, min over splats of s2~; exact when < s2_cap, else >= s2_cap (may be inf).
        n_colliding: int32, number of splats with s2~ < 1 (exact).
        in_collision: bool, n_colliding > k_collide.
        softmin: float32, streaming softmin of s2~ over N(q) (log-sum-exp or log-mean-exp, see
            ``MetricConfig.softmin_mode``); +inf when N(q) is empty.
        cost: float32, aggregated MPPI collision cost over N(q); 0 when N(q) is empty.
    """

    min_s2: np.ndarray
    n_colliding: np.ndarray
    in_collision: np.ndarray
    softmin: np.ndarray
    cost: np.ndarray

    def as_dict(self) -> dict[str, np.ndarray]:
        return {
            "min_s2": self.min_s2,
            "n_colliding": self.n_colliding,
            "in_collision": self.in_collision,
            "softmin": self.softmin,
            "cost": self.cost,
        }

    def reshape(self, shape: tuple[int, ...]) -> "QueryResult":
        return QueryResult(**{k: v.reshape(shape) for k, v in self.as_dict().items()})
