"""Exact clearance of a robot against an analytic scene (boxes, cylinders, spheres): per
configuration, along a path, and the path densified by the robot's motion bound.

Used wherever the ground truth is exact: the MotionBenchMaker study (``eval mbm``), the arm
benchmarks, the task studies on the built-in scenes. The scene is a
:class:`~splatplan.scenes.builtin.analytic_scene.AnalyticScene` (``sdf``, ``ellipsoid_clearance``); the
robot a :class:`~splatplan.robots.Robot` (``ellipsoids``, ``motion_bound``, ``min_semi_axis``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .edges import edge_samples

if TYPE_CHECKING:
    from ..robots.robot import Robot

__all__ = ["dense_path", "densify_by_motion", "exact_clearance", "path_min_clearance"]


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
