"""Clearance of a robot in metres: exact against an analytic scene (boxes, cylinders, spheres),
estimated from the CollisionSplatting metric against splats; per configuration, along a path, and
the path densified by the robot's motion bound.

Used wherever the ground truth is exact: the MotionBenchMaker study (``eval mbm``), the arm
benchmarks, the task studies on the built-in scenes. The scene is a
:class:`~splatplan.scenes.builtin.analytic_scene.AnalyticScene` (``sdf``, ``ellipsoid_clearance``); the
robot a :class:`~splatplan.robots.Robot` (``ellipsoids``, ``motion_bound``, ``min_semi_axis``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .edges import edge_samples

if TYPE_CHECKING:
    from ..metric.checker import CollisionChecker
    from ..robots.robot import Robot

__all__ = ["MetricClearance", "dense_path", "densify_by_motion", "exact_clearance", "metric_clearance", "path_metric_clearance",
           "path_min_clearance", "s2_to_metres"]  # fmt: skip

#: the s2_cap :func:`path_metric_clearance` queries with: min s2~ is exact below it, so a clearance
#: up to (sqrt(16) - 1) = 3 smallest semi-axes is a number, a larger one is reported as "at least"
CLEARANCE_S2_CAP = 16.0


def exact_clearance(scene, robot: Robot, q: np.ndarray) -> np.ndarray:
    """(N,) exact clearance (m) of configurations q (N, dof): min over the robot's ellipsoids of
    :meth:`AnalyticScene.ellipsoid_clearance`. A global broad phase first (the SDF of each centre
    bounds every ellipsoid's clearance within +-a_max), so only ellipsoids that can hold a
    configuration's minimum are solved exactly."""
    q = np.atleast_2d(np.asarray(q, dtype=np.float64))
    c, quat, a = robot.ellipsoids(q)  # (N, E, 3), (N, E, 4), (E, 3)
    n, e = c.shape[:2]
    d_c = scene.sdf(c.reshape(-1, 3)).reshape(n, e)  # (N, E)
    a_max, a_min = a.max(axis=1), a.min(axis=1)
    ub = np.where(d_c < 0, d_c, np.maximum(d_c - a_min, 0.0)).min(axis=1, keepdims=True)  # (N, 1)
    cand = d_c - a_max <= ub + 1e-12  # (N, E)
    out = np.full((n, e), np.inf)
    known = cand & _ball_apart(d_c, a_min, a_max)
    out[known] = (d_c - a_max)[known]
    ci, ei = np.nonzero(cand & ~known)
    out[ci, ei] = scene.ellipsoid_clearance(c[ci, ei], quat[ci, ei], a[ei])
    return out.min(axis=1)


def _ball_apart(d_c: np.ndarray, a_min: np.ndarray, a_max: np.ndarray) -> np.ndarray:
    """(N, E) bool: the ellipsoid is a ball (equal semi-axes, e.g. a sphere model) no closer to the
    primitives than its radius, so its clearance is exactly ``d_c - radius`` (the distance to a
    closed set is 1-Lipschitz and falls at rate 1 towards the nearest point): no solve needed."""
    return (a_max - a_min <= 1e-12 * a_max) & (d_c >= a_max)


def densify_by_motion(robot: Robot, path: np.ndarray, step: float) -> np.ndarray:
    """The path (P, dof) resampled so that no ellipsoid point moves more than ``step`` (scene units)
    between consecutive samples (``Robot.motion_bound``, the bound of the planners' edge checks);
    start included. The one densify of configuration paths: edges, executed trajectories, clearances."""
    p = np.asarray(path, dtype=np.float64)
    if len(p) < 2:
        return p.copy()
    motion = np.abs(np.diff(p, axis=0)) @ np.asarray(robot.motion_bound, dtype=np.float64)  # (P-1,)
    pts, _, _ = edge_samples(p[:-1], p[1:], motion, float(step))
    return np.concatenate([p[:1], pts])


def dense_path(robot: Robot, path: np.ndarray, fraction: float = 0.25) -> np.ndarray:
    """:func:`densify_by_motion` at ``fraction`` x the robot's smallest semi-axis (the planners'
    default edge resolution)."""
    return densify_by_motion(robot, path, fraction * robot.min_semi_axis)


def path_min_clearance(scene, robot: Robot, q: np.ndarray, first: int = 32, stride: int = 8) -> float:
    """min over the configurations q (N, dof) of :func:`exact_clearance` (m), solving only the
    (configuration, ellipsoid) pairs that can hold the minimum. Two bounds prune the pairs:

    * the centre's SDF d_c: ``d_c - a_max <= clearance <= ub`` (ub = d_c inside, max(d_c - a_min,
      0) outside);
    * along the path, an ellipsoid's clearance is 1-Lipschitz in its motion: between samples j and
      k no point moves more than ``M_jk`` = the motion bound of the path between them (``|dq| @
      Robot.motion_bound``, summed), so clearance_j >= clearance_k - M_jk.

    Solved, in three vectorised calls: the ``first`` pairs of smallest ub (where the minimum almost
    always is); then of the pairs whose lower bound reaches the best value, every ``stride``-th
    sample per ellipsoid; then the rest whose bound (from d_c and from the nearest solved samples of
    the same ellipsoid) still reaches it. Equal to ``exact_clearance(...).min()`` (every pair is
    solved by the same :meth:`AnalyticScene.ellipsoid_clearance`; tested)."""
    q = np.atleast_2d(np.asarray(q, dtype=np.float64))
    c, quat, a = robot.ellipsoids(q)  # (N, E, 3), (N, E, 4), (E, 3)
    n, e = c.shape[:2]
    d_c = scene.sdf(c.reshape(-1, 3)).reshape(n, e)  # (N, E)
    a_max, a_min = a.max(axis=1), a.min(axis=1)  # (E,)
    ub = np.where(d_c < 0, d_c, np.maximum(d_c - a_min, 0.0))  # (N, E)
    lb = d_c - a_max  # (N, E)
    cum = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(q, axis=0)) @ np.asarray(robot.motion_bound, dtype=np.float64))])  # (N,)
    val = np.full((n, e), np.nan)  # solved clearances
    ball = _ball_apart(d_c, a_min, a_max)
    val[ball] = lb[ball]  # exact: d_c - radius

    def solve(mask: np.ndarray) -> float:
        ci, ei = np.nonzero(mask & np.isnan(val))
        if len(ci):
            val[ci, ei] = scene.ellipsoid_clearance(c[ci, ei], quat[ci, ei], a[ei])
        return float(np.nanmin(val)) if np.any(~np.isnan(val)) else np.inf

    top = np.zeros(n * e, bool)
    top[np.argsort(ub, axis=None, kind="stable")[:first]] = True
    best = solve(top.reshape(n, e))
    coarse = (lb <= best + 1e-12) & (np.arange(n)[:, None] % stride == 0)
    best = solve(coarse)
    low = lb.copy()
    for k in range(e):  # the bound from the nearest solved samples of the same ellipsoid, on either side
        js = np.nonzero(~np.isnan(val[:, k]))[0]
        if not len(js):
            continue
        pos = np.searchsorted(js, np.arange(n))
        left, right = js[np.clip(pos - 1, 0, len(js) - 1)], js[np.clip(pos, 0, len(js) - 1)]
        for nb in (left, right):
            low[:, k] = np.maximum(low[:, k], val[nb, k] - np.abs(cum - cum[nb]))
    return solve(low <= best + 1e-12)


def s2_to_metres(min_s2, semi_axes) -> np.ndarray:
    """The metric's min s2~ (..., E) -> a clearance estimate in metres (..., E):
    ``(sqrt(min s2~) - 1) * a_min`` with ``a_min`` the smallest semi-axis of each ellipsoid
    ``semi_axes`` (E, 3) (scene units; metres after ``scene align``).

    What it bounds: a point at scaling distance s from an ellipsoid (s2 = s^2, 1 on its surface)
    is at least (s - 1) a_min and at most (s - 1) a_max away from it. At n_sigma = 0 (s2~ = s2 of
    the splat means) the value is therefore a lower bound on the distance from the ellipsoid to
    the nearest splat mean that the metric counts (opacity >= ``opacity_min``). At n_sigma > 0,
    s2~ = max(0, s2 - n_sigma sigma) <= s2, so it is still such a lower bound, smaller by the
    splats' inflation: roughly the distance to the splats grown by n_sigma standard deviations
    along the line to the robot (the metric's linearisation). Negative = the robot overlaps an
    inflated splat (-a_min when a splat mean is at its centre)."""
    s2 = np.maximum(np.asarray(min_s2, dtype=np.float64), 0.0)
    a_min = np.asarray(semi_axes, dtype=np.float64).min(axis=-1)  # (E,)
    return (np.sqrt(s2) - 1.0) * a_min


def metric_clearance(checker: CollisionChecker, robot: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-ellipsoid clearance estimates (m) of configurations q (N, dof) from the metric
    (:func:`s2_to_metres` of ``checker.query_robot``): (clearance (N, E), capped (N, E) bool). A
    capped entry is "at least" its value: min s2~ reached the checker's ``s2_cap``, beyond which the
    metric does not look (an empty neighbourhood reads s2_cap here)."""
    q = np.atleast_2d(np.asarray(q, dtype=np.float64))
    cap = float(checker.config.s2_cap)
    s2 = np.asarray(checker.query_robot(robot, q).min_s2, dtype=np.float64)  # (N, E)
    capped = ~(s2 < cap)  # inf and values at the cap
    return s2_to_metres(np.where(capped, cap, s2), robot.semi_axes), capped


@dataclass
class MetricClearance:
    """The smallest metric clearance estimate along a path (:func:`path_metric_clearance`).

    Attributes:
        clearance_m: the smallest estimate (m; see :func:`s2_to_metres` for what it bounds).
        at_least: True when that smallest value was capped (the robot stays farther from every
            splat than the metric looks): the clearance is at least ``clearance_m``.
        link: the link of the ellipsoid where the minimum lies.
        index: the densified sample where it lies (0 = the start).
        n_samples: configurations checked (the path densified by ``step_m`` of motion).
        step_m: no point of the robot moves more than this between two checked configurations;
            between them the clearance can dip below the sampled minimum by at most step_m / 2.
        n_sigma: the metric's n_sigma.
    """

    clearance_m: float
    at_least: bool
    link: str
    index: int
    n_samples: int
    step_m: float
    n_sigma: float

    def to_json(self) -> dict:
        """Plain numbers for a result file."""
        return {"clearance_m": round(float(self.clearance_m), 6), "at_least": bool(self.at_least), "link": self.link, "sample": int(self.index),
                "n_samples": int(self.n_samples), "step_m": round(float(self.step_m), 6), "n_sigma": float(self.n_sigma)}  # fmt: skip

    def summary(self) -> str:
        """One clause: 'clearance 3.21 cm (estimate at n_sigma 1, link panda_hand, ...)'."""
        v = f"{'>= ' if self.at_least else ''}{self.clearance_m * 100:.2f} cm"
        return (f"clearance {v} (metric estimate at n_sigma {self.n_sigma:g}: a lower bound on the distance to the nearest splat mean, "
                f"less the n_sigma inflation; at {self.link}, over {self.n_samples:,} configurations {self.step_m * 100:.2g} cm of motion apart)")  # fmt: skip


def path_metric_clearance(checker: CollisionChecker, robot: Robot, path: np.ndarray, step: float | None = None, s2_cap: float = CLEARANCE_S2_CAP) -> MetricClearance:
    """The smallest metric clearance estimate (m) over the path (P, dof) densified so that no point of
    the robot moves more than ``step`` (scene units; default a quarter of its smallest semi-axis,
    the planners' edge resolution) between checked configurations (:func:`densify_by_motion`).

    The metric is queried with ``s2_cap`` (default :data:`CLEARANCE_S2_CAP`) so that clearances up
    to ``(sqrt(s2_cap) - 1)`` smallest semi-axes are numbers; the checker's other settings (n_sigma,
    opacity) are kept. See :func:`s2_to_metres` for what the number bounds."""
    step = 0.25 * robot.min_semi_axis if step is None else float(step)
    q = densify_by_motion(robot, np.atleast_2d(np.asarray(path, dtype=np.float64)), step)  # (Q, dof)
    chk = checker.with_config(s2_cap=max(float(s2_cap), float(checker.config.s2_cap)))
    per_e, capped = metric_clearance(chk, robot, q)  # (Q, E)
    i, e = np.unravel_index(int(np.argmin(per_e)), per_e.shape)
    link = robot.link_names[int(robot.ellipsoid_link[e])]
    return MetricClearance(float(per_e[i, e]), bool(capped[i, e]), link, int(i), len(q), step, float(checker.config.n_sigma))
