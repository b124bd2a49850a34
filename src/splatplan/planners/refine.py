"""Zeroth-order path refinement: one MPPI update with the horizon set to the whole path (paper III-C).

1. Fit a clamped cubic B-spline to the (RRT) polyline, endpoints pinned (``fit_bspline``); the
   number of control points follows the path length (``knot_spacing``).
2. Sample K perturbations of the *interior* control points (sample 0 = the fit itself);
   coordinates along which the whole path is constant (e.g. z of a planar plan) are not perturbed.
3. Cost of each sampled curve, evaluated on ``T`` dense samples:
   ``C = w_length * length + w_collision * sum_t cost_t * ds + w_hit * (#samples in collision)``
   with ``cost_t`` the checker's collision cost of the robot at sample t (one ``checker.query`` on
   a (K, T, L) batch) and ``ds = length / (T - 1)``, so the collision term is a line integral in
   scene units, comparable to the length.
4. MPPI weights ``exp(-(C - C_min) / lambda)``, control points <- weighted mean (``n_iters`` times;
   the paper uses one).
5. Accept the refined curve only if its dense polyline is collision-free at ``check_resolution``
   (default: half the robot's smallest semi-axis) via ``checker.collides``; otherwise fall back to
   the lowest-cost collision-free sample, then retry with twice the control points (up to
   ``max_attempts`` fits); if nothing passes, the original path is returned unchanged.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .._config import bounded, check_config, check_order
from .._resources import require_bytes
from ..errors import SplatplanError
from .bspline import bspline_basis, fit_bspline, resample_polyline
from .robot_links import LinkGeometry, as_robot
from .edges import EdgeChecker
from .rrt_types import path_length

if TYPE_CHECKING:
    from ..metric.checker import CollisionChecker
    from ..robots.robot import Robot


@dataclass
class RefineConfig:
    """Knobs of :func:`refine_path` (distances in scene units of robot motion). Every None is
    derived from the robot's smallest semi-axis a (the values for the default sphere a = 0.015
    in brackets), so the refinement scales with the robot like the RRT's defaults."""

    #: sampled perturbations K
    n_samples: int = bounded(256, ge=2)
    #: target arc length between B-spline control points (sets n_knots from the path length);
    #: None = 20/3 a (0.1)
    knot_spacing: float | None = bounded(None, gt=0)
    #: fixed number of control points instead of knot_spacing (None = from knot_spacing)
    n_knots: int | None = bounded(None, ge=4)
    #: bounds of the number of control points
    min_knots: int = bounded(5, ge=4)
    max_knots: int = bounded(64, ge=4)
    #: standard deviation of the interior control point perturbations (scene units of motion;
    #: divided by motion_bound per joint for an arm or base); None = 0.8 a (0.012)
    noise_sigma: float | None = bounded(None, ge=0)
    #: MPPI temperature lambda (same units as the cost, i.e. scene units); None = a / 3 (0.005)
    temperature: float | None = bounded(None, gt=0)
    #: MPPI updates (the paper: 1)
    n_iters: int = bounded(1, ge=1)
    #: spacing of the dense samples on which the cost is evaluated; None = the robot's smallest semi-axis
    cost_spacing: float | None = bounded(None, gt=0)
    #: weight of the path length
    w_length: float = bounded(1.0, ge=0)
    #: weight of the collision line integral (pushes the curve away from splats within ~2 radii)
    w_collision: float = bounded(30.0, ge=0)
    #: cost per dense sample in collision
    w_hit: float = bounded(1.0, ge=0)
    #: spacing of the acceptance check; None = half the robot's smallest semi-axis
    check_resolution: float | None = bounded(None, gt=0)
    #: fits tried (n_knots doubled after a rejected one)
    max_attempts: int = bounded(3, ge=1)
    #: seed of the perturbations
    seed: int = bounded(0, ge=0)

    def validate(self) -> "RefineConfig":
        """Check every field's declared range (:mod:`splatplan._config`) and the cross-field rules; returns self."""
        check_config(self)
        check_order(self, "min_knots", "max_knots")
        return self



@dataclass
class RefineResult:
    """Outcome of :func:`refine_path`.

    Attributes:
        path: (M, D) the refined dense curve (spacing <= check_resolution), or the input path
            when rejected.
        accepted: whether ``path`` is the refined curve.
        knots: (n_knots, D) control points of the accepted curve (None when rejected).
        cost_before: refinement cost of the input polyline.
        cost_after: refinement cost of the returned path.
        n_attempts: fits tried.
        message: what happened.
    """

    path: np.ndarray
    accepted: bool
    knots: np.ndarray | None
    cost_before: float
    cost_after: float
    n_attempts: int
    message: str = ""
    info: dict = field(default_factory=dict)


#: configurations per cost query of the sampled curves: the deadline is checked between chunks
COST_CHUNK = 16384


class _OutOfTime(Exception):
    """The deadline passed while the sampled curves were being costed."""


def _chunked_costs(checker, geom: LinkGeometry, curves: np.ndarray, cfg: RefineConfig, deadline: float | None) -> np.ndarray:
    """:func:`_curve_costs` over (K, T, D) in chunks of about COST_CHUNK configurations, checking
    ``deadline`` (a ``time.perf_counter()`` value) between chunks; raises _OutOfTime past it."""
    k, t_len = curves.shape[:2]
    step = max(1, COST_CHUNK // t_len)
    out = np.empty(k)
    for i in range(0, k, step):
        if deadline is not None and time.perf_counter() > deadline:
            raise _OutOfTime
        out[i : i + step] = _curve_costs(checker, geom, curves[i : i + step], cfg)
    return out


def _curve_costs(checker, geom: LinkGeometry, curves: np.ndarray, cfg: RefineConfig) -> np.ndarray:
    """Refinement cost of K dense curves (K, T, D) -> (K,) (lengths in the planner metric)."""
    seg = np.linalg.norm(np.diff(curves, axis=1) * geom.distance_scale(), axis=-1)  # (K, T-1)
    length = seg.sum(axis=1)  # (K,)
    res = geom.query(checker, curves)  # (K, T, L)
    k, t_len = curves.shape[:2]
    col = res.cost.reshape(k, t_len, -1).astype(np.float64).sum(axis=2)  # (K, T)
    hit = res.in_collision.reshape(k, t_len, -1).any(axis=2).sum(axis=1)  # (K,)
    ds = length / (t_len - 1)
    return cfg.w_length * length + cfg.w_collision * col.sum(axis=1) * ds + cfg.w_hit * hit


def refine_path(
    checker: CollisionChecker,
    path: np.ndarray,
    config: RefineConfig | None = None,
    *,
    robot: Robot | str,
    deadline: float | None = None,
) -> RefineResult:
    """Refine a collision-free polyline into a shorter, smoother, collision-free B-spline curve.

    Args:
        checker: a :class:`~splatplan.metric.CollisionChecker`.
        path: (P, D) polyline from start to goal (e.g. an RRT path), assumed collision-free.
        config: :class:`RefineConfig`.
        deadline: a ``time.perf_counter()`` value: past it the refinement stops (checked between
            chunks of cost queries and before each acceptance check) and returns the input path.
        robot: (required) a :class:`~splatplan.robots.Robot` or name; the path is in its configuration space
            and lengths / spacings are in the RRT's metric (|motion_bound * dq|, scene units).

    Returns:
        :class:`RefineResult`; ``path`` is never in collision at ``check_resolution`` unless the
        input was.
    """
    cfg = (config or RefineConfig()).validate()
    p = np.asarray(path, dtype=np.float64)
    if p.ndim != 2 or len(p) < 2:
        raise SplatplanError(f"refine_path needs a path of shape (P >= 2, D), got {p.shape}")
    if deadline is not None and time.perf_counter() > deadline:
        return RefineResult(p.copy(), False, None, math.nan, math.nan, 0, "time limit reached before the refinement; kept the original path",
                            {"time_limit_hit": True})  # fmt: skip
    geom = LinkGeometry(as_robot(robot))
    geom.bind(p[0])
    wq = geom.distance_scale()  # (D,) configuration -> metric
    a_min = geom.min_semi_axis
    check_res = float(cfg.check_resolution or 0.5 * a_min)
    cost_sp = float(cfg.cost_spacing or a_min)
    edges = EdgeChecker(checker, geom, check_res, inflate=geom.sphere)
    rng = np.random.default_rng(cfg.seed)
    length0 = path_length(p, wq)
    # the input polyline's own cost, on the same kind of dense samples
    t_cost = int(np.clip(math.ceil(length0 / cost_sp) + 1, 16, 4096))
    try:
        cost_before = float(_chunked_costs(checker, geom, resample_polyline(p, t_cost)[0][None], cfg, deadline)[0])
    except _OutOfTime:
        return RefineResult(p.copy(), False, None, math.nan, math.nan, 0, "time limit reached before the refinement; kept the original path",
                            {"time_limit_hit": True})  # fmt: skip
    if length0 <= 0:
        return RefineResult(p.copy(), False, None, cost_before, cost_before, 0, "zero-length path")
    knot_spacing = float(cfg.knot_spacing) if cfg.knot_spacing is not None else a_min * 20.0 / 3.0
    noise_sigma = float(cfg.noise_sigma) if cfg.noise_sigma is not None else 0.8 * a_min
    temperature = float(cfg.temperature) if cfg.temperature is not None else a_min / 3.0
    sigma_q = noise_sigma / np.where(wq > 0, wq, 1.0)  # (D,) noise in configuration units
    scales = {"knot_spacing": knot_spacing, "noise_sigma": noise_sigma, "temperature": temperature}
    free_dims = np.ptp(p, axis=0) > 0  # perturb only coordinates the path actually uses
    u_cost = np.linspace(0.0, 1.0, t_cost)
    t_out = int(max(2, math.ceil(length0 * 1.5 / check_res) + 1))  # output density (refined curves are shorter)
    n_knots = cfg.n_knots or int(np.clip(math.ceil(length0 / knot_spacing) + 3, cfg.min_knots, cfg.max_knots))
    d = p.shape[1]  # the resource guard, before any array: sampled knots and curves, the two bases, the dense output
    need = 8.0 * (4.0 * cfg.n_samples * (n_knots + t_cost) * d + float(t_cost + t_out) * 2 * n_knots + 4.0 * t_out * d)
    require_bytes(need, f"the refinement ({cfg.n_samples:,} samples x {n_knots:,} knots, {t_out:,} checked points)",
                  "RefineConfig.n_samples, n_knots or max_knots, or raise check_resolution (--refine-n-samples, --refine-n-knots, "
                  "--refine-max-knots, --refine-check-resolution)")
    try:
        return _attempts(checker, geom, p, cfg, edges, rng, deadline, cost_before, length0, sigma_q, temperature, scales, free_dims, u_cost, t_out, n_knots, wq)
    except _OutOfTime:
        return RefineResult(p.copy(), False, None, cost_before, cost_before, 0, "time limit reached during refinement; kept the original path",
                            {"length_before": length0, "time_limit_hit": True, **scales})  # fmt: skip


def _attempts(checker, geom, p, cfg, edges, rng, deadline, cost_before, length0, sigma_q, temperature, scales, free_dims, u_cost, t_out, n_knots, wq) -> RefineResult:
    """The fits of :func:`refine_path` (raises _OutOfTime past ``deadline``)."""
    message = ""
    for attempt in range(1, cfg.max_attempts + 1):
        basis = bspline_basis(n_knots, u_cost)  # (T, n)
        knots = fit_bspline(p, n_knots, fix_endpoints=True)  # (n, D)
        for _ in range(cfg.n_iters):
            eps = rng.standard_normal((cfg.n_samples, n_knots, p.shape[1])) * sigma_q  # (K, n, D)
            eps[0] = 0.0
            eps[:, [0, -1]] = 0.0  # endpoints pinned
            eps[:, :, ~free_dims] = 0.0
            samples = knots[None] + eps  # (K, n, D)
            curves = np.einsum("tn,knd->ktd", basis, samples)  # (K, T, D)
            c = _chunked_costs(checker, geom, curves, cfg, deadline)
            w = np.exp(-(c - c.min()) / temperature)
            w /= w.sum()
            knots = np.einsum("k,knd->nd", w, samples)
        candidates = [knots, samples[int(np.argmin(c))]]
        basis_out = bspline_basis(n_knots, t_out)
        for name, kn in zip(("weighted mean", "best sample"), candidates):
            dense = basis_out @ kn  # (T_out, D)
            if deadline is not None and time.perf_counter() > deadline:
                raise _OutOfTime
            if edges.path_free(dense):
                cost_after = float(_curve_costs(checker, geom, (basis @ kn)[None], cfg)[0])
                return RefineResult(
                    dense,
                    True,
                    kn,
                    cost_before,
                    cost_after,
                    attempt,
                    f"accepted the {name} (n_knots={n_knots}, attempt {attempt})",
                    {"n_knots": n_knots, "length_before": length0, "length_after": path_length(dense, wq), **scales},
                )
        message = f"refined curves collide (n_knots={n_knots}); kept the original path"
        n_knots = min(2 * n_knots, max(cfg.max_knots, n_knots))
    return RefineResult(p.copy(), False, None, cost_before, cost_before, cfg.max_attempts, message, {"length_before": length0, **scales})
