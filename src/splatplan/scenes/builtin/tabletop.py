"""The built-in ``tabletop`` scene: a table with box walls around parts of a 7-DoF arm's workspace.

Sized for the Franka Panda of ``example-robot-data`` mounted at the world origin on the table top
(paper Sec. IV, E5: "a box-walled tabletop scene"). The boxes are the exact ground truth
(:class:`~splatplan.scenes.builtin.analytic_scene.AnalyticScene`); the splats are sampled on their
surfaces with the statistics of real captures (:func:`.levels.level_config` level 1).

Units and frames
----------------
Metres, **z up**, the robot base at the origin looking along +x. The table top is the plane
z = :data:`TABLE_TOP` = -0.09 (the robot stands on a 9 cm mounting plate that belongs to the
robot: its conservative, tilted base ellipsoid reaches 7 cm below its base). Heights below are above the
table top. Quaternions are wxyz.

Layout (before the small per-seed jitter)
-----------------------------------------
* ``table``: top slab x in [-0.30, 1.00], y in [-0.80, 0.80], z in [-0.04, 0]; four legs.
* ``bin``: a box open at the top in front of the robot, x in [0.44, 0.84], y in [-0.30, 0.30]:
  a tall near wall (``wall_front``, 0.24 m) between the robot and the inside of the bin, lower
  side and back walls (0.14 m). :data:`TARGET_REGION` lies inside the bin, *behind the front
  wall*: an arm reaching straight for a target there cuts through the wall.
* ``wall_side``: a 0.34 m wall on the robot's left (y = +0.42), targets behind it are out of the
  studies (too tight) but it blocks wide sweeps of the arm.
* ``shelf``: a low shelf on the right (two posts and a board), objects on and under it.
* coloured objects (``object_*``): a red cube and a yellow block in the bin, a green block and a
  blue box on the table, a purple box on the shelf, an orange block behind the side wall.

Splats: ~150k by default (:data:`N_SPLATS`), the table legs sampled at 3x the spacing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..splats import Splats
from ._layout import BoxList, SceneCache, object_colors
from .analytic_scene import AnalyticScene
from .primitive_sdf import yaw_quat

__all__ = ["N_SPLATS", "TABLE_TOP", "TARGET_REGION", "TabletopLayout", "build_tabletop", "tabletop_layout"]

#: Default total splat count (floaters included).
N_SPLATS = 150_000
#: Height (m) of the table top: the Panda's base sits on a 9 cm mounting plate (part of the robot),
#: so its conservative base ellipsoid clears the table.
TABLE_TOP = -0.09
#: Axis-aligned region (lo, hi) (world, metres) inside the bin behind the front wall where the arm
#: study places end-effector targets.
TARGET_REGION = (np.array([0.60, -0.08, -0.03]), np.array([0.70, 0.08, 0.03]))

#: Base colours per label (RGB in [0, 1]), the objects' distinct colours included.
LABEL_COLORS = {
    "table": (0.55, 0.40, 0.26),
    "table_leg": (0.35, 0.25, 0.16),
    "wall_front": (0.85, 0.85, 0.80),
    "wall_bin": (0.75, 0.78, 0.80),
    "wall_side": (0.70, 0.72, 0.66),
    "shelf": (0.45, 0.45, 0.50),
    # objects: distinct colours
    "object_red": (0.85, 0.12, 0.10),
    "object_yellow": (0.95, 0.82, 0.10),
    "object_green": (0.15, 0.65, 0.20),
    "object_blue": (0.12, 0.30, 0.85),
    "object_purple": (0.55, 0.20, 0.70),
    "object_orange": (0.98, 0.50, 0.05),
}
#: The distinct colours of the objects (labels "object_*").
OBJECT_COLORS = object_colors(LABEL_COLORS)


@dataclass(frozen=True)
class TabletopLayout:
    """The analytic tabletop and its named parts (metres, z up, robot base at the origin).

    Attributes:
        scene: the boxes; labels in {"table", "table_leg", "wall_front", "wall_bin", "wall_side",
            "shelf"} and "object_<colour>".
        colors: float64 (M, 3) base RGB per box.
        target_region: (lo, hi) AABB of end-effector targets behind the front wall.
        front_wall_top: height (m) of the front wall's top face.
    """

    scene: AnalyticScene
    colors: np.ndarray
    target_region: tuple[np.ndarray, np.ndarray]
    front_wall_top: float


def _build_layout(seed: int) -> TabletopLayout:
    rng = np.random.default_rng([int(seed), 4242])
    box_list = BoxList(LABEL_COLORS, offset=(0.0, 0.0, TABLE_TOP))  # heights below: relative to the table top
    add = box_list.add

    j = lambda s: rng.uniform(-s, s)  # noqa: E731  small per-seed jitter (m)
    # table top (its top face is z = 0) and legs
    add("table", (0.35, 0.0, -0.02), (0.65, 0.80, 0.02))
    for x in (-0.26, 0.96):
        for y in (-0.76, 0.76):
            add("table_leg", (x, y, -0.39), (0.03, 0.03, 0.36))
    # the bin: a tall front wall, lower side and back walls (all sink 1 mm into the table)
    t, front_h, low_h = 0.01, 0.24, 0.14
    x0, x1, y1 = 0.44, 0.84, 0.30
    add("wall_front", (x0, 0.0, (front_h - 0.001) / 2), (t, y1 + t, (front_h + 0.001) / 2))
    add("wall_bin", (x1, 0.0, (low_h - 0.001) / 2), (t, y1 + t, (low_h + 0.001) / 2))
    for s in (-1.0, 1.0):
        add("wall_bin", ((x0 + x1) / 2, s * y1, (low_h - 0.001) / 2), ((x1 - x0) / 2 - t, t, (low_h + 0.001) / 2))
    # a side wall on the left
    add("wall_side", (0.30 + j(0.01), 0.42, 0.17 - 0.0005), (0.22, 0.012, 0.17 + 0.0005), yaw_quat(j(0.03)))
    # a low shelf on the right: two posts and a board
    for x in (0.22, 0.52):
        add("shelf", (x, -0.50, 0.10 - 0.0005), (0.015, 0.12, 0.10 + 0.0005))
    add("shelf", (0.37, -0.50, 0.21), (0.17, 0.13, 0.012))
    # coloured objects
    add("object_red", (0.78 + j(0.01), -0.21 + j(0.01), 0.025), (0.025, 0.025, 0.0255), yaw_quat(rng.uniform(0, np.pi)))
    add("object_yellow", (0.78 + j(0.01), 0.21 + j(0.01), 0.035), (0.03, 0.02, 0.0355), yaw_quat(rng.uniform(0, np.pi)))
    add("object_green", (0.20 + j(0.02), 0.25 + j(0.02), 0.04), (0.03, 0.03, 0.0405), yaw_quat(rng.uniform(0, np.pi)))
    add("object_blue", (0.28 + j(0.02), -0.28 + j(0.02), 0.03), (0.05, 0.035, 0.0305), yaw_quat(rng.uniform(0, np.pi)))
    add("object_purple", (0.37 + j(0.02), -0.50, 0.222 + 0.03 - 0.001), (0.03, 0.03, 0.03), yaw_quat(rng.uniform(0, np.pi)))
    add("object_orange", (0.30 + j(0.02), 0.58 + j(0.02), 0.04), (0.035, 0.035, 0.0405), yaw_quat(rng.uniform(0, np.pi)))

    scene, colors = box_list.scene(
        {
            "name": "tabletop",
            "seed": int(seed),
            "units": "metres, z up, table top at z = -0.09, robot base at the origin looking along +x",
            "robot": "panda",
            "target_region": [TARGET_REGION[0].tolist(), TARGET_REGION[1].tolist()],
        }
    )
    return TabletopLayout(scene=scene, colors=colors, target_region=TARGET_REGION, front_wall_top=front_h + TABLE_TOP)


#: the cached layouts and splats; floaters in the region below, splat spacing per label
_CACHE = SceneCache(_build_layout, N_SPLATS, 2718, (np.array([-0.2, -0.7, TABLE_TOP + 0.02]), np.array([0.95, 0.7, 0.8])), density={"table_leg": 3.0, "table": 1.5})


def tabletop_layout(seed: int = 0) -> TabletopLayout:
    """The analytic tabletop for a seed (fresh copies; small object/wall jitter by seed)."""
    return _CACHE.layout(seed)


def build_tabletop(seed: int = 0, n_splats: int | None = None) -> tuple[Splats, AnalyticScene]:
    """The tabletop splats and their boxes, fresh copies (cached in memory): see :func:`._layout.sample_splats`.
    ``seed`` jitters the layout and seeds the sampling; ``n_splats`` counts floaters too (default :data:`N_SPLATS`)."""
    return _CACHE.build(seed, n_splats)

