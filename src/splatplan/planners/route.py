"""Routes of a planar base (x, y, yaw; metres, radians, world frame): a global route by the batched
RRT (:func:`plan_route`), a branch of an exploration tree (:func:`tree_branch`), and the carrot
point a driver follows along a route (:func:`carrot`). Used by :mod:`splatplan.tasks.base` and
:mod:`splatplan.tasks.navigate` (the Go2).
"""

from __future__ import annotations

import numpy as np
from typing import TYPE_CHECKING

from ..errors import SplatplanError

if TYPE_CHECKING:
    from ..metric.checker import CollisionChecker
    from ..robots.robot import Robot

__all__ = ["carrot", "free_yaw", "plan_route", "tree_branch", "wrap_angle"]


def wrap_angle(a):
    """Angles wrapped to (-pi, pi]."""
    return (np.asarray(a, np.float64) + np.pi) % (2 * np.pi) - np.pi


def plan_route(
    robot: Robot, checker: CollisionChecker, start, goal_xy, time_budget_s: float = 60.0, seed: int = 0, edge_resolution: float = 0.05, stride: float = 0.4, goal_bias: float = 0.2,
    box=None,
) -> np.ndarray | None:
    """Global route on the base's SE(2) with the batched RRT: (P, 3) configurations (x, y, yaw),
    or None when none is found within ``time_budget_s``.

    The goal's yaw is free: the RRT goal is the goal position at the collision-free heading nearest
    to the bearing from the start. The route is a guide that MPPI tracks with its own collision
    cost (the executed motion is what the clearance measures), so its edges are checked every
    ``edge_resolution`` = 5 cm (half a wall's thickness) of ellipsoid motion rather than at the
    RRT default of a quarter of the Go2's smallest semi-axis (a 1.9 cm foot: 4.8 mm, ~80 checks
    per edge, which is why the default search did not reach the kitchen in 30 s), with a
    ``stride`` of 0.4 m and a goal bias of 0.2. ``box``: (lo, hi) world x, y (m) the route stays
    in (e.g. :func:`~splatplan.planners.bounds.planning_box` around a captured object); default
    the scene's bounds (a room: its walls)."""
    from ..planners import RRT, RRTConfig

    start = np.asarray(start, np.float64)
    g = np.asarray(goal_xy, np.float64)
    bearing = float(np.arctan2(g[1] - start[1], g[0] - start[0]))
    yaws = bearing + np.linspace(-np.pi, np.pi, 24, endpoint=False)
    yaws = yaws[np.argsort(np.abs(np.angle(np.exp(1j * (yaws - bearing)))))]  # nearest to the bearing first
    q = np.stack([np.full(len(yaws), g[0]), np.full(len(yaws), g[1]), np.angle(np.exp(1j * yaws))], axis=1)
    free = ~np.asarray(checker.collides_robot(robot, q)).any(axis=-1)
    if not free.any():
        raise SplatplanError(f"goal {g.round(3).tolist()}: the base collides there at every heading; pick a free goal")
    yaw = float(q[np.argmax(free), 2])
    if box is None:
        lo, hi = checker.scene.bounds()
    else:
        lo, hi = (np.asarray(b, np.float64).reshape(-1) for b in box)
    cfg = RRTConfig(box_lo=(float(lo[0]), float(lo[1]), -np.pi), box_hi=(float(hi[0]), float(hi[1]), np.pi), time_limit_s=time_budget_s, seed=seed, goal_tolerance=0.1,
                    edge_resolution=edge_resolution, stride=stride, goal_bias=goal_bias)  # fmt: skip
    res = RRT(checker, cfg, robot=robot).plan(start, np.array([g[0], g[1], yaw]))
    if not res.success:
        return None
    return np.asarray(res.path)


def free_yaw(robot: Robot, checker: CollisionChecker, xy) -> float | None:
    """A yaw at which the base at ``xy`` is collision-free (None if every one of 16 collides)."""
    yaws = np.linspace(-np.pi, np.pi, 16, endpoint=False)
    q = np.stack([np.full(16, xy[0]), np.full(16, xy[1]), yaws], axis=1)
    free = ~np.asarray(checker.collides_robot(robot, q)).any(axis=-1)
    return float(yaws[np.argmax(free)]) if free.any() else None


def tree_branch(nodes: np.ndarray, parents: np.ndarray, i: int) -> np.ndarray:
    """(P, 3) tree nodes from the root to node i."""
    idx = []
    while i >= 0:
        idx.append(int(i))
        i = int(parents[i])
    return np.asarray(nodes)[idx[::-1]]


def carrot(path_xy: np.ndarray, p: np.ndarray, lookahead: float, progress: int) -> tuple[np.ndarray, int]:
    """Point ``lookahead`` ahead along the polyline from the closest point at or after segment ``progress``."""
    if len(path_xy) == 1:
        return path_xy[0], 0
    a, b = path_xy[:-1], path_xy[1:]
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0, 1)
    d = np.linalg.norm(a + t[:, None] * ab - p, axis=1)
    d[:progress] = np.inf
    j = int(np.argmin(d))
    rem = lookahead
    pt = a[j] + t[j] * ab[j]
    k = j
    while k < len(ab):
        seg = float(np.linalg.norm(b[k] - pt))
        if seg >= rem:
            return pt + (b[k] - pt) * (rem / max(seg, 1e-12)), j
        rem -= seg
        pt = b[k]
        k += 1
    return path_xy[-1], j
