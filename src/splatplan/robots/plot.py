"""A picture of a robot's collision ellipsoids over its link geometry (matplotlib 3D, returns a Figure)."""

from __future__ import annotations

import numpy as np

from .fit import link_points
from .robot import Robot
from .urdf import UrdfModel


def ellipsoid_surface(center, rot, semi_axes, n: int = 18) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grid (n, n) of surface points of one ellipsoid in the frame of ``center``/``rot``."""
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, n), np.linspace(0, np.pi, n))
    unit = np.stack([np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)], axis=-1)  # (n, n, 3)
    pts = (unit * semi_axes) @ np.asarray(rot).T + center
    return pts[..., 0], pts[..., 1], pts[..., 2]


def plot_robot_ellipsoids(robot: Robot, model: UrdfModel | None = None, q=None, from_visual: bool = False, max_points: int = 12000):
    """Figure: the ellipsoids (wireframes) of ``robot`` at ``q`` (default ``q_default``) over the
    vertices of each link's collision geometry (points; needs ``model``). World frame, metres."""
    from matplotlib.figure import Figure

    q = robot.q_default if q is None else q
    poses = robot.link_poses(q)
    centers, rots = robot.ellipsoid_frames(q)
    fig = Figure(figsize=(7, 7), dpi=110)
    ax = fig.add_subplot(projection="3d")
    rng = np.random.default_rng(0)
    allpts = [centers - robot.semi_axes.max(axis=1, keepdims=True), centers + robot.semi_axes.max(axis=1, keepdims=True)]
    colors = [f"C{i % 10}" for i in range(len(robot.link_names))]
    if model is not None:
        for li, name in enumerate(robot.link_names):
            geoms = model.collisions.get(name) or (model.visuals.get(name, []) if from_visual else [])
            if not geoms:
                continue
            pts = link_points(geoms, name)
            if len(pts) == 0:
                continue
            if len(pts) > max_points // max(1, len(robot.link_names)):
                pts = pts[rng.choice(len(pts), max_points // max(1, len(robot.link_names)), replace=False)]
            w = pts @ poses[li, :3, :3].T + poses[li, :3, 3]
            ax.scatter(w[:, 0], w[:, 1], w[:, 2], s=2.0, color=colors[li], alpha=0.8)
    for e in range(robot.n_ellipsoids):
        x, y, z = ellipsoid_surface(centers[e], rots[e], robot.semi_axes[e])
        ax.plot_wireframe(x, y, z, color=colors[int(robot.ellipsoid_link[e])], linewidth=0.3, alpha=0.6)
    every = np.concatenate(allpts)
    lo, hi = every.min(axis=0), every.max(axis=0)
    mid, half = (lo + hi) / 2, (hi - lo).max() / 2
    ax.set_xlim(mid[0] - half, mid[0] + half)
    ax.set_ylim(mid[1] - half, mid[1] + half)
    ax.set_zlim(mid[2] - half, mid[2] + half)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.set_title(f"{robot.name}: {robot.n_ellipsoids} ellipsoids over the collision geometry (points)")
    return fig
