"""The GROUP BOUND's groups of a robot (:mod:`.wp_metric_kernel`): its ellipsoids by the rigid body
they belong to, for the per-configuration collision kernel."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..errors import SplatplanError

if TYPE_CHECKING:
    from ..robots.robot import Robot

def robot_groups(robot: Robot) -> tuple[bytes, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The GROUP BOUND's groups of a robot (:mod:`.wp_metric_kernel`): its ellipsoids by the link
    (rigid body) they belong to, the most distal link first (it moves most, so it hits first).

    Returns (key, first (G + 1,) int32, members (E,) int32, rel (E,) float64: each member's distance
    from its group's centroid in the link frame (scene units), semi-axes (E, 3) float64); cached on
    the robot object (by its semi-axes, link map and ellipsoid poses).
    """
    ax = np.asarray(robot.semi_axes, dtype=np.float64).reshape(-1, 3)
    local = getattr(robot, "ellipsoid_local", None)
    if local is None or not hasattr(robot, "ellipsoid_link"):  # poses in a link frame unknown: one group per ellipsoid
        link, t = np.arange(len(ax)), np.zeros((len(ax), 3))
    else:
        link = np.asarray(robot.ellipsoid_link, dtype=np.int64).reshape(-1)
        t = np.asarray(local, dtype=np.float64)[:, :3, 3]  # (E, 3) ellipsoid centres in their link's frame
    key = ax.tobytes() + link.tobytes() + t.tobytes()
    hit = robot.__dict__.get("_groups_cache") if hasattr(robot, "__dict__") else None
    if hit is not None and hit[0] == key:
        return hit
    if len(link) != len(ax) or len(t) != len(ax):
        raise SplatplanError(f"robot {getattr(robot, 'name', '?')!r}: its ellipsoid link map or poses do not match its {len(ax)} ellipsoids")
    members, first, rel = [], [0], np.zeros(len(ax))
    for li in sorted(set(link.tolist()), reverse=True):
        idx = np.nonzero(link == li)[0]
        rel[idx] = np.linalg.norm(t[idx] - t[idx].mean(axis=0), axis=1)
        members += idx.tolist()
        first.append(len(members))
    out = (key, np.asarray(first, dtype=np.int32), np.asarray(members, dtype=np.int32), rel, ax)
    if hasattr(robot, "__dict__"):
        robot.__dict__["_groups_cache"] = out
    return out
