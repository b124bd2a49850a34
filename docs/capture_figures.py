"""Pictures of the README's "Your own capture" section, from a real capture.

    python docs/capture_figures.py ALIGNED.ply PLAN.json docs/capture_plan.png

Top view of an aligned (z-up, floor at z = 0) scene: splats between 5 cm and 1.5 m above the
floor coloured by height, and the Go2's ellipsoids (their footprints) along the planned path.
The before/after renders come from `splatplan render` (see the README).
"""

from __future__ import annotations

import json
import sys

import numpy as np


def main(scene_path: str, plan_path: str, out: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Ellipse

    from splatplan.robots import load_robot
    from splatplan.scenes import load_scene

    s = load_scene(scene_path)
    m = s.means
    sel = (m[:, 2] > 0.05) & (m[:, 2] < 1.5)
    path = np.asarray(json.loads(open(plan_path).read())["path"], np.float64)  # (P, 3) x, y, yaw
    robot = load_robot("go2")
    fig, ax = plt.subplots(figsize=(6, 5))
    sc = ax.scatter(m[sel, 0], m[sel, 1], c=m[sel, 2], s=0.5, cmap="viridis", vmin=0.05, vmax=1.5)
    fig.colorbar(sc, ax=ax, label="height above the floor (m)")
    t = np.linspace(0, 1, 6)[:, None]
    states = np.concatenate([a + t * (b - a) for a, b in zip(path[:-1], path[1:])])
    c, q, ax3 = robot.ellipsoids(states)
    for k, st in enumerate(states):
        for e in range(c.shape[1]):
            yaw = np.degrees(st[2])
            ax.add_patch(Ellipse(c[k, e, :2], 2 * ax3[e, 0], 2 * ax3[e, 1], angle=yaw, fill=False, lw=0.4, color="crimson" if k in (0, len(states) - 1) else "orange"))
    ax.plot(path[:, 0], path[:, 1], "r.-", lw=1.5, label="Go2 plan (base x, y)")
    lo, hi = np.quantile(m[sel, :2], 0.01, axis=0), np.quantile(m[sel, :2], 0.99, axis=0)
    ax.set_xlim(lo[0] - 0.1, hi[0] + 0.1)
    ax.set_ylim(lo[1] - 0.1, hi[1] + 0.1)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title("aligned capture, top view: the Go2's plan between floor points")
    fig.tight_layout()
    fig.savefig(out, dpi=90)


if __name__ == "__main__":
    main(*sys.argv[1:4])
