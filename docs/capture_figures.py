"""Pictures of the README's "Your own capture" section, from a capture-like file we may publish.

    python docs/capture_figures.py [WORKDIR]      # default WORKDIR: build/capture_figures

Makes docs/capture_before_align.png, docs/capture_after_align.png and docs/capture_plan.png.
No shared data: the input is the built-in ``apartment`` scene (metres, z up) turned into what a
phone scan looks like: re-expressed in the y-down capture frame, scaled to non-metric units
(1 unit = 2.5 m), offset from the origin, and wrapped in a far "sky shell" of large faint splats.
Then the real commands run on it (``splatplan info``, ``scene align`` with ``--scale 2.5``: align
cannot know a capture's scale, ``render`` before and after with the same camera, ``plan --robot
go2`` between two floor points of the aligned scene), and the plan is drawn in a top view: splats
between 5 cm and 1.5 m above the floor coloured by height, and the Go2's ellipsoids (their
footprints) along the path.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

DOCS = Path(__file__).resolve().parent
#: capture units per metre (the scan's unknown scale) and the offset of its origin (capture units).
UNITS_PER_METRE = 0.4
OFFSET = np.array([1.3, 0.7, -2.1])
#: sky shell: count, radius and typical std of its splats (capture units; stds x 0.5..1.5, opacity 0.02..0.08).
SHELL = (3000, 60.0, 4.0)
#: start and goal of the Go2 in the apartment's own frame (x, y, yaw; metres, radians): living room -> bedroom.
START, GOAL = (-2.5, 1.8, 0.0), (1.3, 1.6, 0.0)
#: the camera (eye, look-at) in the apartment's own frame (metres); both pictures put it at the same
#: place relative to the room (in the scan's frame, then in the aligned one) with the same z-up convention.
EYE, LOOK_AT = (-9.5, 0.0, 5.5), (0.0, 0.0, 0.3)
IMAGE = ("--up", "0,0,1", "--fov", "70", "--width", "320", "--height", "240", "--background", "1,1,1")


def capture_like(seed: int = 0):
    """The apartment as a phone scan would store it: y-down, 1 unit = 2.5 m, offset, sky shell."""
    from splatplan.scenes import Splats
    from splatplan.scenes.builtin import build_builtin
    from splatplan.scenes.transforms import Y_DOWN_TO_Z_UP, rotate, scale, translate

    room, _ = build_builtin("apartment", seed=seed)
    scan = translate(scale(rotate(room, Y_DOWN_TO_Z_UP.T), UNITS_PER_METRE), OFFSET)  # z up -> y down
    rng = np.random.default_rng(seed)
    n, radius, std = SHELL
    d = rng.normal(size=(n, 3))
    centre = scan.means.mean(axis=0)
    shell = Splats(
        means=centre + radius * d / np.linalg.norm(d, axis=1, keepdims=True),  # (n, 3)
        quats=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)),
        scales=np.full((n, 3), std) * rng.uniform(0.5, 1.5, (n, 1)),
        opacities=rng.uniform(0.02, 0.08, n),
        colors=np.array([0.55, 0.7, 0.9]) + rng.normal(0, 0.05, (n, 3)),
    )
    cat = lambda a, b: np.concatenate([a, b])  # noqa: E731
    return Splats(cat(scan.means, shell.means), cat(scan.quats, shell.quats), cat(scan.scales, shell.scales), cat(scan.opacities, shell.opacities), cat(scan.colors, shell.colors))


def cli(*args: str) -> str:
    """Run ``splatplan ARGS`` (this interpreter), echo and return its stdout."""
    print("$ splatplan " + " ".join(args), flush=True)
    done = subprocess.run([sys.executable, "-m", "splatplan.cli", *args], capture_output=True, text=True)
    print(done.stdout + done.stderr, end="", flush=True)
    if done.returncode != 0:
        raise SystemExit(f"splatplan {args[0]} failed (exit {done.returncode})")
    return done.stdout


def draw_plan(scene_path: Path, plan_path: Path, out: Path) -> None:
    """Top view of an aligned scene (z up, floor at z = 0) and the Go2's plan."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Ellipse

    from splatplan.robots import load_robot
    from splatplan.scenes import load_scene

    s = load_scene(scene_path)
    m = s.means
    sel = (m[:, 2] > 0.05) & (m[:, 2] < 1.5)
    path = np.asarray(json.loads(plan_path.read_text())["path"], np.float64)  # (P, 3) x, y, yaw
    robot = load_robot("go2")
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    sc = ax.scatter(m[sel, 0], m[sel, 1], c=m[sel, 2], s=0.15, cmap="viridis", vmin=0.05, vmax=1.5, rasterized=True)
    fig.colorbar(sc, ax=ax, label="height above the floor (m)")
    t = np.linspace(0, 1, 4)[:, None]
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
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title("aligned capture, top view: the Go2's plan between floor points", fontsize=10)
    fig.tight_layout()
    fig.savefig(out, dpi=80)


def main(work: str = "build/capture_figures") -> None:
    from splatplan.scenes import save_scene

    w = Path(work)
    w.mkdir(parents=True, exist_ok=True)
    scan, room = w / "scan.ply", w / "room.ply"
    save_scene(capture_like(), scan)
    cli("info", str(scan))
    cli("scene", "align", str(scan), "--out", str(room), "--scale", str(1.0 / UNITS_PER_METRE), "--drop-floaters")
    cli("info", str(room))
    # the apartment's own points (metres, z up) through the scan's and then the align's transform
    from splatplan.scenes.transforms import Y_DOWN_TO_Z_UP

    t = np.asarray(json.loads(room.with_suffix(".align.json").read_text())["transform"], np.float64)  # (4, 4)
    in_scan = lambda p: UNITS_PER_METRE * Y_DOWN_TO_Z_UP.T @ np.asarray(p, np.float64) + OFFSET  # noqa: E731
    in_room = lambda p: t[:3, :3] @ in_scan(p) + t[:3, 3]  # noqa: E731
    txt = lambda x: ",".join(f"{v:.2f}" for v in x)  # noqa: E731
    floor_point = lambda s: txt([*in_room([s[0], s[1], 0.0])[:2], s[2]])  # noqa: E731  x, y, yaw
    plan = w / "go2.json"
    cli("plan", str(room), "--robot", "go2", "--start", floor_point(START), "--goal", floor_point(GOAL), "--out", str(plan))
    cli("render", str(scan), "--eye", txt(in_scan(EYE)), "--look-at", txt(in_scan(LOOK_AT)), *IMAGE, "--out", str(DOCS / "capture_before_align.png"))
    cli("render", str(room), "--eye", txt(in_room(EYE)), "--look-at", txt(in_room(LOOK_AT)), *IMAGE, "--out", str(DOCS / "capture_after_align.png"))
    draw_plan(room, plan, DOCS / "capture_plan.png")


if __name__ == "__main__":
    main(*sys.argv[1:2])
