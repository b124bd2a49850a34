"""A robot's footprint on the floor: its height and the radius of the disc that holds it at any
heading (what free floor must leave clear: :func:`splatplan.scenes.pick.pick_points`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..errors import SplatplanError

if TYPE_CHECKING:
    from .robot import Robot

__all__ = ["robot_footprint"]


def robot_footprint(robot: Robot) -> tuple[float, float]:
    """``(height, radius)`` of ``robot`` standing at its default configuration and base pose: the z
    extent of its ellipsoids (a ground robot's from its floor frame, z = 0 under its feet) and the
    largest x, y distance of an ellipsoid point from the base's axis (bounded by centre distance +
    largest semi-axis: a disc that holds the robot at any heading)."""
    if robot.base == "fixed" and not robot.is_point:
        raise SplatplanError(f"{robot.name} is a fixed-base arm: it has no footprint on the floor; give a ground robot (go2) or a point robot")
    q = np.asarray(robot.q_default, dtype=np.float64)
    c, rot = robot.ellipsoid_frames(q)  # (E, 3), (E, 3, 3) world <- ellipsoid
    a = np.asarray(robot.semi_axes, dtype=np.float64)  # (E, 3)
    ext_z = np.sqrt(np.sum((rot[:, 2, :] * a) ** 2, axis=1))  # (E,) half extent along world z
    bottom = 0.0 if robot.walks_on_terrain else float(np.min(c[:, 2] - ext_z))
    height = float(np.max(c[:, 2] + ext_z)) - bottom
    axis = robot.base_pose[:2, 3]
    radius = float(np.max(np.linalg.norm(c[:, :2] - axis, axis=1) + a.max(axis=1)))
    return height, radius
