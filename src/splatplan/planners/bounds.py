"""Where a robot can be in a scene: the scene's bounds grown by what the robot needs.

A capture of an object (a chair, a model house) ends at the object, but a robot working on it
stands beside it: a ground robot's base may be anywhere its footprint still reaches the captured
space, an arm's links reach around its base. :func:`planning_box` is that box, the default of
``mpc``'s goal check and route box and of the viewer's "outside the scene" warning.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..robots.footprint import robot_footprint

if TYPE_CHECKING:
    from ..robots.robot import Robot
    from ..scenes.splats import Splats

__all__ = ["box_margin", "planning_box", "reach_radius"]

#: configurations sampled within the joint limits to measure an arm's reach
N_REACH_SAMPLES = 512


def reach_radius(robot: Robot, n_samples: int = N_REACH_SAMPLES, seed: int = 0) -> float:
    """How far the robot's ellipsoids reach from its reference point (scene units):

    * a planar base (a ground robot): its footprint radius (:func:`~splatplan.robots.footprint.robot_footprint`),
      the largest horizontal distance of an ellipsoid point from the base's axis (at any yaw);
    * a fixed base (an arm): its reach, the largest distance of an ellipsoid point from the base
      origin over ``n_samples`` configurations within the joint limits (plus the home one);
    * a point robot: its largest semi-axis (the reference point is its centre).
    """
    if robot.is_point:
        return float(robot.semi_axes.max())
    if robot.base == "planar":  # the footprint disc at its default configuration (yaw turns it about the base origin)
        return robot_footprint(robot)[1]
    lim = np.asarray(robot.joint_limits, dtype=np.float64).reshape(robot.dof, 2)
    lo = np.where(np.isfinite(lim[:, 0]), lim[:, 0], -np.pi)
    hi = np.where(np.isfinite(lim[:, 1]), lim[:, 1], np.pi)
    rng = np.random.default_rng(seed)
    q = np.concatenate([np.asarray(robot.q_default, np.float64).reshape(1, -1), lo + rng.random((n_samples, robot.dof)) * (hi - lo)])
    c, _, ax = robot.ellipsoids(q)  # (Q, E, 3), (E, 3)
    d = np.asarray(c, np.float64) - np.asarray(robot.base_pose, np.float64)[:3, 3]  # (Q, E, 3) from the base origin
    return float((np.linalg.norm(d, axis=-1) + ax.max(axis=1)).max())


def box_margin(robot: Robot) -> float:
    """How far :func:`planning_box` grows the scene's bounds (scene units): a ground robot's
    footprint diameter (room to stand beside the captured space and to drive around it), an arm's
    reach around its base, a point robot's largest semi-axis (:func:`reach_radius`)."""
    r = reach_radius(robot)
    return 2.0 * r if robot.base == "planar" else r


def planning_box(scene: Splats, robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    """(lo (3,), hi (3,)): the scene's bounds (splat means, world frame) grown by
    :func:`box_margin` on every side: where the robot's reference point (a base origin, a point
    robot's centre) can be while the robot still reaches, or drives around, the captured space."""
    lo, hi = (np.asarray(b, dtype=np.float64) for b in scene.bounds())
    m = box_margin(robot)
    return lo - m, hi + m
