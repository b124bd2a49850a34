"""A picture of an aligned scene: is up really up? (``splatplan scene align --png``).

Three views of the aligned splat means (output frame: z up, floor at ``floor_z``): front (x-z),
side (y-z) and top (x-y), each point coloured by its height, the floor drawn as a line in the
side views, the up axis as an arrow and, for a wall alignment, the wall at 0 along its axis.
Returns a matplotlib :class:`~matplotlib.figure.Figure` (no pyplot, no global backend change).
"""

from __future__ import annotations

import numpy as np

from .splats import Splats

__all__ = ["alignment_figure"]


def alignment_figure(aligned: Splats, title: str, floor_z: float | None = 0.0, wall_axis: str | None = None, max_points: int = 40000, seed: int = 0):
    """Front, side and top views of ``aligned`` (output frame, z up) coloured by height.

    Args:
        aligned: the aligned scene. title: one line above the views (the up axis, the counts).
        floor_z: the floor's height (drawn), None when the floor was not placed.
        wall_axis: '+x', '-x', '+y' or '-y' for a wall alignment (the wall drawn at 0 along it).
        max_points: a seeded random subset of the opaque means (opacity >= 0.1) is drawn.
    """
    from matplotlib.figure import Figure

    m = aligned.means.astype(np.float64)
    keep = aligned.opacities >= 0.1
    if keep.sum() >= 10:
        m = m[keep]
    if len(m) > max_points:
        m = m[np.random.default_rng(seed).choice(len(m), max_points, replace=False)]
    lo, hi = np.percentile(m, 0.5, axis=0), np.percentile(m, 99.5, axis=0)
    pad = 0.05 * float(np.max(hi - lo) + 1e-9)
    lo, hi = lo - pad, hi + pad
    z = np.clip(m[:, 2], lo[2], hi[2])
    fig = Figure(figsize=(15, 5.2), layout="constrained")
    axes = fig.subplots(1, 3)
    for ax, (i, j), name in zip(axes, ((0, 2), (1, 2), (0, 1)), ("front (x-z)", "side (y-z)", "top (x-y)")):
        order = np.argsort(z) if j != 2 else np.arange(len(m))
        sc = ax.scatter(m[order, i], m[order, j], c=z[order], s=0.6, cmap="viridis", vmin=lo[2], vmax=hi[2], rasterized=True)
        ax.set_xlim(lo[i], hi[i])
        ax.set_ylim(lo[j], hi[j])
        ax.set_aspect("equal")
        ax.set_xlabel("xyz"[i])
        ax.set_ylabel("xyz"[j])
        ax.set_title(name)
        if j == 2:
            if floor_z is not None:
                ax.axhline(floor_z, color="tab:red", lw=1.2, label=f"floor z = {floor_z:g}")
            L = 0.25 * (hi[2] - lo[2])  # noqa: N806 the up arrow's length
            x0 = lo[i] + 0.08 * (hi[i] - lo[i])
            z0 = floor_z if floor_z is not None else lo[2] + pad
            ax.annotate("", xy=(x0, z0 + L), xytext=(x0, z0), arrowprops={"arrowstyle": "-|>", "color": "tab:red", "lw": 2})
            ax.text(x0, z0 + L, " up +z", color="tab:red", va="bottom")
            if floor_z is not None:
                ax.legend(loc="upper right", fontsize=8)
        k = None if wall_axis is None else "xyz".index(wall_axis[1])
        if k in (i, j):  # the wall is the plane {x_k = 0}
            (ax.axvline if k == i else ax.axhline)(0.0, color="tab:orange", lw=1.2, ls="--")
            ax.text(0.0 if k == i else lo[i], hi[j] if k == i else 0.0, f" wall (normal {wall_axis})", color="tab:orange", fontsize=8, va="top")
    fig.colorbar(sc, ax=axes, shrink=0.8, label="height z")
    fig.suptitle(title)
    return fig
