"""Pictures of a task run: the robot's ellipsoids at several frames over the scene, the
end-effector or base trace, the goal. Library plotting returns a matplotlib ``Figure``."""

from __future__ import annotations

import numpy as np
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..robots.robot import Robot


def _ellipse_outlines(centers, quats, axes, dims, n: int = 96) -> list[np.ndarray]:
    """2D outlines (convex hulls of projected surface samples) of ellipsoids on the plane ``dims``."""
    from scipy.spatial import ConvexHull

    from ..scenes.builtin.ellipsoid_clearance import fibonacci_sphere
    from ..scenes.splats import quat_to_rotmat

    u = fibonacci_sphere(n)
    out = []
    rots = quat_to_rotmat(np.asarray(quats)).reshape(-1, 3, 3)
    for c, r, a in zip(np.asarray(centers), rots, np.asarray(axes)):
        p = (c + (u * a) @ r.T)[:, list(dims)]
        out.append(p[ConvexHull(p).vertices])
    return out


def _draw_scene(ax, scene_splats, analytic, dims, z_cut: float | None, bounds) -> None:
    from matplotlib.patches import Polygon

    if analytic is not None:
        from ..scenes.builtin.primitive_sdf import box_corners

        from ..scenes.builtin import apartment, tabletop

        palette = {**tabletop.LABEL_COLORS, **tabletop.OBJECT_COLORS, **apartment.LABEL_COLORS, **apartment.OBJECT_COLORS}
        for i, (box, lab) in enumerate(zip(analytic.boxes, analytic.labels)):
            if lab in ("floor", "ground"):
                continue
            if z_cut is not None and box_corners(box)[:, 2].min() > z_cut + 0.3:
                continue  # far above the robot
            from scipy.spatial import ConvexHull

            pts = box_corners(box)[:, list(dims)]
            poly = pts[ConvexHull(pts).vertices]
            fc = palette.get(lab, "0.6")
            ax.add_patch(Polygon(poly, closed=True, fc=fc, ec="k", lw=0.4, alpha=0.6, zorder=1))
    else:
        m = np.asarray(scene_splats.means)
        sel = np.random.default_rng(0).choice(len(m), size=min(len(m), 30000), replace=False)
        m, col = m[sel], np.clip(np.asarray(scene_splats.colors, np.float64)[sel], 0.0, 1.0)
        if z_cut is not None and dims == (0, 1):
            keep = np.abs(m[:, 2] - z_cut) < 0.3
            m, col = m[keep], col[keep]
        ax.scatter(m[:, dims[0]], m[:, dims[1]], s=0.3, c=col, zorder=1)
    ax.set_xlim(bounds[0][dims[0]], bounds[1][dims[0]])
    ax.set_ylim(bounds[0][dims[1]], bounds[1][dims[1]])
    ax.set_aspect("equal")
    ax.set_xlabel("xyz"[dims[0]] + " (m)")
    ax.set_ylabel("xyz"[dims[1]] + " (m)")


def _draw_memory(ax, maps: dict) -> None:
    """The base's sensed-obstacle memory under the run: sensed free cells light grey, sensed blocked
    cells (the robot collides there at every heading) dark grey; unsensed cells left blank."""
    from matplotlib.colors import ListedColormap

    blocked = np.asarray(maps["memory_blocked"], bool)  # (NX, NY)
    sensed = np.asarray(maps["memory_sensed"], bool)
    img = np.where(sensed, np.where(blocked, 2.0, 1.0), np.nan).T  # (NY, NX) for imshow
    ox, oy = (float(v) for v in maps["memory_origin"])
    c = float(maps["memory_cell"])
    ext = (ox, ox + c * blocked.shape[0], oy, oy + c * blocked.shape[1])
    cmap = ListedColormap([(0.85, 0.85, 0.85, 0.35), (0.3, 0.3, 0.3, 0.45)])
    ax.imshow(img, origin="lower", extent=ext, cmap=cmap, vmin=1.0, vmax=2.0, interpolation="nearest", zorder=1)
    ax.plot([], [], "s", color=(0.85, 0.85, 0.85, 0.8), label="sensed free (memory)")
    ax.plot([], [], "s", color=(0.3, 0.3, 0.3, 0.6), label="sensed blocked (memory)")


def plot_run(robot: Robot, task_scene, result, *, kind: str, n_frames: int = 6, title: str = ""):
    """A Figure of the run: ``kind`` "arm" (top and side views) or "base" (top view at body height)."""
    import matplotlib
    from matplotlib.figure import Figure
    from matplotlib.patches import Polygon

    traj = np.asarray(result.trajectory)
    frames = np.unique(np.linspace(0, len(traj) - 1, n_frames).round().astype(int))
    an = task_scene.analytic
    if kind == "arm":
        views = [((0, 1), "top view"), ((0, 2), "side view")]
        trace = np.asarray(result.extra.get("ee_trace", np.zeros((0, 3))))
        lo = np.array([-0.35, -0.8, -0.15])
        hi = np.array([1.0, 0.8, 1.0])
        z_cut = None
    else:
        views = [((0, 1), "top view")]
        trace = np.concatenate([traj[:, :2], np.zeros((len(traj), 1))], axis=1)
        lo, hi = task_scene.splats.bounds()
        lo, hi = lo - 0.1, hi + 0.1
        z_cut = float(robot.info.get("standing_height_m", 0.35))
    # the axes fit the data: the box above grown to hold every drawn robot pose (ellipsoid centres
    # +- the largest semi-axis, world frame) and the trace, with a 5 cm margin
    c, _, sa = robot.ellipsoids(traj[frames])  # (F, E, 3), (E, 3)
    pts = np.concatenate([np.asarray(c, np.float64).reshape(-1, 3), trace.reshape(-1, 3)])
    pad = float(np.max(sa)) + 0.05
    lo, hi = np.minimum(lo, pts.min(axis=0) - pad), np.maximum(hi, pts.max(axis=0) + pad)
    fig = Figure(figsize=(6.5 * len(views), 6.0), constrained_layout=True)  # no pyplot state: any backend, nothing to close
    axes = fig.subplots(1, len(views), squeeze=False)
    cmap = matplotlib.colormaps["viridis"]
    for ax, (dims, name) in zip(axes[0], views):
        _draw_scene(ax, task_scene.splats, an, dims, z_cut, (lo, hi))
        maps = getattr(result, "maps", None) or {}
        if kind == "base" and "memory_blocked" in maps:
            _draw_memory(ax, maps)
        for j, f in enumerate(frames):
            c, q, a = robot.ellipsoids(traj[f])
            for poly in _ellipse_outlines(c, q, a, dims):
                ax.add_patch(Polygon(poly, closed=True, fill=False, ec=cmap(j / max(1, len(frames) - 1)), lw=0.8, zorder=3))
        if len(trace):
            ax.plot(trace[:, dims[0]], trace[:, dims[1]], "-", color="tab:red", lw=1.5, zorder=4, label="end effector" if kind == "arm" else "base")
        goal = np.asarray(result.goal["position"], np.float64)
        if len(goal) > max(dims):
            ax.plot(goal[dims[0]], goal[dims[1]], "*", color="gold", mec="k", ms=16, zorder=5, label="goal")
        ax.set_title(name)
        ax.legend(loc="upper right", fontsize=8)
    col = "with collision cost" if result.collision_cost else "WITHOUT collision cost (--no-collision)"
    fig.suptitle(
        f"{title or robot.name} {col}: {'reached' if result.success else 'not reached'}, final error {result.final_position_error_m * 100:.1f} cm,\n"
        f"min clearance {result.min_clearance_m * 100:.1f} cm ({result.clearance_source}); robot ellipsoids from start (purple) to end (yellow)",
        fontsize=9,
    )
    return fig
