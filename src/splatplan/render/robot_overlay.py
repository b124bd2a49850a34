"""A picture of a robot moving through a scene: its ellipsoids at several configurations along a path
over the scene's opaque splat means, in a top (x-y) and a side (x-z) view (``splatplan plan --png``).

World frame of the scene (z up after ``scene align``), axes in scene units (metres after align),
equal aspect. The splat means (opacity >= ``opacity_min``, a seeded random subset) are coloured by
height; each ellipsoid is drawn as its exact outline on the view plane (the projection of an
ellipsoid is an ellipse: :func:`ellipsoid_outlines`), from the start (green) to the goal (red), with
the trace of one link (an arm's end effector, a moving robot's base) between them. Returns a matplotlib :class:`~matplotlib.figure.Figure`
(no pyplot, no global backend change).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..scenes.splats import Splats, quat_to_rotmat

if TYPE_CHECKING:
    from ..robots.robot import Robot

__all__ = ["ellipsoid_outlines", "path_figure", "path_frames"]

#: the two views: (axis indices, title)
VIEWS = (((0, 1), "top (x-y)"), ((0, 2), "side (x-z)"))


def ellipsoid_outlines(centers: np.ndarray, quats: np.ndarray, semi_axes: np.ndarray, dims: tuple[int, int], n: int = 64) -> np.ndarray:
    """(E, n, 2) outlines on the plane of axes ``dims`` of the ellipsoids ``centers`` (E, 3) world,
    ``quats`` (E, 4) wxyz world <- ellipsoid, ``semi_axes`` (E, 3): the ellipsoid's shadow along the
    third axis is the ellipse ``x^T M^-1 x = 1`` with ``M = P R diag(a^2) R^T P^T`` (P picks ``dims``)."""
    c = np.asarray(centers, np.float64).reshape(-1, 3)
    r = quat_to_rotmat(np.asarray(quats, np.float64).reshape(-1, 4))  # (E, 3, 3)
    a = np.broadcast_to(np.asarray(semi_axes, np.float64), c.shape)
    p = r[:, list(dims), :] * a[:, None, :]  # (E, 2, 3): P R diag(a)
    m = p @ p.transpose(0, 2, 1) + 1e-18 * np.eye(2)  # (E, 2, 2)
    ell = np.linalg.cholesky(m)  # (E, 2, 2)
    t = np.linspace(0.0, 2 * np.pi, n)
    circle = np.stack([np.cos(t), np.sin(t)])  # (2, n)
    return (c[:, list(dims)][:, :, None] + ell @ circle).transpose(0, 2, 1)


def path_frames(path: np.ndarray, n_frames: int) -> np.ndarray:
    """(n_frames, dof) configurations evenly spaced by arc length (joint space) along ``path`` (V, dof), ends included."""
    path = np.asarray(path, np.float64).reshape(len(path), -1)
    if len(path) == 1:
        return np.repeat(path, n_frames, axis=0)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    if s[-1] <= 0:
        return np.repeat(path[:1], n_frames, axis=0)
    u = np.linspace(0.0, s[-1], n_frames)
    return np.stack([np.interp(u, s, path[:, d]) for d in range(path.shape[1])], axis=1)


def path_figure(
    splats: Splats,
    robot: Robot,
    path: np.ndarray,  # (V, dof) configurations, start first
    *,
    n_frames: int = 6,
    trace_link: str | None = None,
    title: str = "",
    opacity_min: float = 0.5,
    max_points: int = 40000,
    seed: int = 0,
) -> Any:
    """Top and side views of ``robot`` at ``n_frames`` configurations along ``path`` over ``splats``.

    ``trace_link`` is the link whose origin is traced and marks start and goal (default: an arm's
    last link, a moving robot's base link). The view box holds every drawn ellipsoid, padded by a quarter of the robot's extent (at least
    twice its largest semi-axis); the splats inside it are drawn (the higher over the lower in the
    top view). Returns a Figure.
    """
    from matplotlib.figure import Figure

    frames = path_frames(path, max(2, int(n_frames)))
    dense = path_frames(path, 200)
    c, quat, axes = robot.ellipsoids(frames)  # (F, E, 3), (F, E, 4), (E, 3)
    c = np.asarray(c, np.float64)
    reach = np.max(axes, axis=1)  # (E,) a bound on each ellipsoid's half extent
    lo = (c - reach[None, :, None]).reshape(-1, 3).min(axis=0)
    hi = (c + reach[None, :, None]).reshape(-1, 3).max(axis=0)
    pad = max(0.25 * float(np.max(hi - lo)), 2.0 * float(reach.max()))
    lo, hi = lo - pad, hi + pad
    if trace_link is None:
        trace_link = robot.link_names[-1] if robot.base == "fixed" else robot.link_names[0]
    li = list(robot.link_names).index(trace_link)
    tip = robot.link_poses(dense)[:, li, :3, 3]  # (200, 3) world
    m = np.asarray(splats.means, np.float64)
    m = m[(np.asarray(splats.opacities) >= opacity_min) & np.all((m >= lo) & (m <= hi), axis=1)]
    if len(m) > max_points:
        m = m[np.random.default_rng(seed).choice(len(m), max_points, replace=False)]
    fig = Figure(figsize=(12, 5.8), layout="constrained")
    axs = fig.subplots(1, 2)
    zlo, zhi = (float(np.min(m[:, 2])), float(np.max(m[:, 2]))) if len(m) else (float(lo[2]), float(hi[2]))
    sc = None
    for ax, (dims, name) in zip(axs, VIEWS):
        order = np.argsort(m[:, 2]) if dims == (0, 1) else np.argsort(-m[:, 1])  # top: higher over lower; side: nearer (smaller y) over farther
        sc = ax.scatter(m[order, dims[0]], m[order, dims[1]], c=m[order, 2], s=0.5, cmap="viridis", vmin=zlo, vmax=zhi, alpha=0.6, rasterized=True)
        last = len(frames) - 1
        for f in [*range(1, last), 0, last]:  # the ends drawn last, boldest
            col = (0.1 + 0.8 * f / last, 0.6 * (1 - f / last), 0.1)  # green -> red
            end = f in (0, last)
            for poly in ellipsoid_outlines(c[f], quat[f], axes, dims):
                ax.plot(poly[:, 0], poly[:, 1], "-", color=col, lw=1.6 if end else 0.7, alpha=1.0 if end else 0.6, zorder=3)
        ax.plot(tip[:, dims[0]], tip[:, dims[1]], "--", color="k", lw=1.0, zorder=4, label=f"{trace_link} along the path")
        ax.plot(*tip[0, list(dims)], "o", color="tab:green", mec="k", ms=8, zorder=5, label="start")
        ax.plot(*tip[-1, list(dims)], "*", color="tab:red", mec="k", ms=14, zorder=5, label="goal")
        ax.set_xlim(lo[dims[0]], hi[dims[0]])
        ax.set_ylim(lo[dims[1]], hi[dims[1]])
        ax.set_aspect("equal")
        ax.set_xlabel(f"{'xyz'[dims[0]]} (m)")
        ax.set_ylabel(f"{'xyz'[dims[1]]} (m)")
        ax.set_title(name)
        ax.legend(loc="best", fontsize=8)
    if sc is not None:
        fig.colorbar(sc, ax=list(axs), shrink=0.8, label="splat height z (m)")
    fig.suptitle(f"{title or robot.name}: {len(frames)} configurations from start (green) to goal (red); opaque splat means (opacity >= {opacity_min:g})", fontsize=10)
    return fig
