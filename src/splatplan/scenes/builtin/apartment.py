"""The built-in ``apartment`` scene: three rooms joined by doorways of different widths.

Sized for the Unitree Go2 (body ~0.31 m wide with the legs, standing height ~0.3 m), for the
quadruped studies (paper Sec. IV, E6). The boxes are the exact ground truth
(:class:`~splatplan.scenes.builtin.analytic_scene.AnalyticScene`); the splats are sampled on their
surfaces with the statistics of real captures (:func:`.levels.level_config` level 1).

Units and frames
----------------
Metres, **z up**, the floor's top face is z = 0, the apartment spans x in [-4, 4], y in [-3, 3]
(inside faces of the outer walls). Quaternions are wxyz.

Layout
------
* ``living`` room: x in [-4, 0], all of y; ``bedroom``: x in [0, 4], y in [0, 3];
  ``kitchen``: x in [0, 4], y in [-3, 0].
* doorways (:data:`DOORS`): living <-> bedroom 0.90 m wide; living <-> kitchen 0.25 m (narrower
  than the Go2: impassable); bedroom <-> kitchen 0.80 m; a second living <-> kitchen doorway of
  0.80 m near the outer wall.
* walls 0.10 m thick and :data:`WALL_HEIGHT` tall; furniture per room (sofa, tables, bed,
  wardrobe, counters, ...) and distinctly coloured objects (``object_*``).

Splats: ~160k by default (:data:`N_SPLATS`); the floor uses twice the spacing and only its top
face, walls 1.5x.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..splats import Splats
from ._layout import BoxList, SceneCache, object_colors
from .analytic_scene import AnalyticScene
from .primitive_sdf import yaw_quat

__all__ = ["DOORS", "HAZE", "add_capture_look", "N_SPLATS", "ROOMS", "WALL_HEIGHT", "ApartmentLayout", "apartment_layout", "build_apartment", "room_of"]

#: Default total splat count (floaters included).
N_SPLATS = 160_000
#: Height of the walls (m).
WALL_HEIGHT = 1.2
_T = 0.05  # wall half thickness

#: Rooms: name -> (lo (2,), hi (2,)) xy rectangle between the wall faces (m).
ROOMS = {
    "living": ((-4.0, -3.0), (0.0 - _T, 3.0)),
    "bedroom": ((0.0 + _T, 0.0 + _T), (4.0, 3.0)),
    "kitchen": ((0.0 + _T, -3.0), (4.0, 0.0 - _T)),
}

#: Doorways: (name, wall axis "x" (wall at x = const) or "y", wall coordinate, start, end along the
#: wall, rooms joined). Width = end - start.
DOORS = (
    ("living-bedroom", "x", 0.0, 1.30, 2.20, ("living", "bedroom")),
    ("living-kitchen-narrow", "x", 0.0, -1.10, -0.85, ("living", "kitchen")),
    ("living-kitchen", "x", 0.0, -2.90, -2.10, ("living", "kitchen")),
    ("bedroom-kitchen", "y", 0.0, 2.55, 3.35, ("bedroom", "kitchen")),
)

#: Base colours per label (RGB in [0, 1]), the objects' distinct colours included.
LABEL_COLORS = {
    "floor": (0.62, 0.50, 0.36),
    "wall": (0.90, 0.89, 0.85),
    "sofa": (0.55, 0.10, 0.12),
    "table": (0.45, 0.30, 0.18),
    "bed": (0.20, 0.30, 0.65),
    "wardrobe": (0.85, 0.80, 0.70),
    "counter": (0.80, 0.80, 0.82),
    "fridge": (0.92, 0.94, 0.96),
    "shelf": (0.40, 0.28, 0.20),
    # objects: distinct colours
    "object_green_plant": (0.10, 0.55, 0.15),
    "object_yellow_box": (0.95, 0.80, 0.10),
    "object_orange_ball": (0.98, 0.45, 0.05),
    "object_cyan_chest": (0.10, 0.75, 0.80),
    "object_magenta_box": (0.80, 0.10, 0.60),
    "object_red_bin": (0.90, 0.10, 0.10),
    "object_blue_crate": (0.10, 0.25, 0.90),
    "object_lime_stool": (0.60, 0.90, 0.10),
}
#: The distinct colours of the objects (labels "object_*").
OBJECT_COLORS = object_colors(LABEL_COLORS)


@dataclass(frozen=True)
class ApartmentLayout:
    """The analytic apartment and its named parts (metres, z up, floor top at z = 0).

    Attributes:
        scene: the boxes (floor first), labels "floor", "wall", furniture names, "object_*".
        colors: float64 (M, 3) base RGB per box.
        rooms: name -> (lo (2,), hi (2,)) xy rectangles.
        doors: name -> dict(center (3,) at z = 0.3, width (m), rooms (a, b), normal (2,) across the wall).
    """

    scene: AnalyticScene
    colors: np.ndarray
    rooms: dict
    doors: dict


def room_of(xy) -> str | None:
    """The room containing the xy point (None: inside a wall or outside)."""
    x, y = float(xy[0]), float(xy[1])
    for name, (lo, hi) in ROOMS.items():
        if lo[0] <= x <= hi[0] and lo[1] <= y <= hi[1]:
            return name
    return None


def _wall_segments(axis: str, coord: float, start: float, end: float, gaps) -> list[tuple[float, float]]:
    """Solid intervals of a wall from ``start`` to ``end`` minus the door gaps on it."""
    cuts = sorted((s, e) for (_, ax, c, s, e, _) in gaps if ax == axis and abs(c - coord) < 1e-9 and start < e and s < end)
    segs, cur = [], start
    for s, e in cuts:
        if s > cur:
            segs.append((cur, s))
        cur = max(cur, e)
    if cur < end:
        segs.append((cur, end))
    return segs


def _build_layout(seed: int) -> ApartmentLayout:
    rng = np.random.default_rng([int(seed), 9191])
    box_list = BoxList(LABEL_COLORS)
    add = box_list.add

    def block(label: str, x: float, y: float, hx: float, hy: float, h: float, yaw: float = 0.0) -> None:
        add(label, (x, y, (h - 0.002) / 2), (hx, hy, (h + 0.002) / 2), yaw_quat(yaw))  # sinks 2 mm

    j = lambda s: rng.uniform(-s, s)  # noqa: E731  small per-seed jitter (m)
    add("floor", (0.0, 0.0, -0.05), (4.2, 3.2, 0.05))
    hz = WALL_HEIGHT / 2
    # outer walls
    for y in (-3.0 - _T, 3.0 + _T):
        add("wall", (0.0, y, hz - 0.001), (4.0 + 2 * _T, _T, hz + 0.001))
    for x in (-4.0 - _T, 4.0 + _T):
        add("wall", (x, 0.0, hz - 0.001), (_T, 3.0, hz + 0.001))
    # interior wall at x = 0 (y in [-3, 3]) and y = 0 (x in [0, 4]), with doorways
    for s, e in _wall_segments("x", 0.0, -3.0, 3.0, DOORS):
        add("wall", (0.0, (s + e) / 2, hz - 0.001), (_T, (e - s) / 2, hz + 0.001))
    for s, e in _wall_segments("y", 0.0, _T, 4.0, DOORS):
        add("wall", ((s + e) / 2, 0.0, hz - 0.001), ((e - s) / 2, _T, hz + 0.001))

    # living room: sofa, coffee table, shelf, objects
    block("sofa", -3.45, 0.4 + j(0.05), 0.35, 0.95, 0.45)
    block("sofa", -3.70, 0.4 + j(0.05), 0.10, 0.95, 0.80)  # backrest
    block("table", -2.3 + j(0.05), 0.3 + j(0.05), 0.45, 0.30, 0.42, j(0.1))
    block("shelf", -2.0, 2.78, 0.80, 0.17, 1.0)
    block("table", -1.6 + j(0.05), -1.5 + j(0.05), 0.50, 0.40, 0.75, j(0.1))  # dining table
    block("object_green_plant", -0.45, 2.55, 0.18, 0.18, 0.70)
    block("object_yellow_box", -2.9 + j(0.05), -1.2 + j(0.05), 0.20, 0.15, 0.30, rng.uniform(0, np.pi))
    block("object_orange_ball", -1.5 + j(0.05), 1.2 + j(0.05), 0.12, 0.12, 0.24, rng.uniform(0, np.pi))
    # bedroom: bed, wardrobe, chest, objects
    block("bed", 3.0, 1.8 + j(0.05), 0.95, 1.0, 0.50)
    block("bed", 3.93, 1.8, 0.05, 1.0, 0.90)  # headboard
    block("wardrobe", 1.0 + j(0.05), 2.7, 0.60, 0.27, 1.15)
    block("object_cyan_chest", 3.7, 0.45 + j(0.05), 0.20, 0.30, 0.45, 0.0)
    block("object_magenta_box", 0.55 + j(0.05), 0.95 + j(0.05), 0.15, 0.15, 0.30, rng.uniform(0, np.pi))
    # kitchen: counters along the walls, fridge, island, objects
    block("counter", 2.35, -2.7, 0.85, 0.30, 0.90)
    block("counter", 3.7, -1.2, 0.30, 0.60, 0.90)
    block("fridge", 3.62, -2.62, 0.33, 0.33, 1.15)
    block("table", 2.0 + j(0.05), -1.4 + j(0.05), 0.50, 0.30, 0.90, j(0.05))  # island
    add("object_blue_crate", (2.0, -1.4, 0.90 + 0.12 - 0.001), (0.15, 0.12, 0.12), yaw_quat(rng.uniform(0, np.pi)))
    block("object_red_bin", 0.4 + j(0.03), -0.4, 0.15, 0.15, 0.40)
    block("object_lime_stool", 1.1 + j(0.03), -1.4 + j(0.03), 0.16, 0.16, 0.45)

    doors: dict[str, dict[str, Any]] = {}
    for name, ax, c, s, e, rooms in DOORS:
        mid = (s + e) / 2
        center = np.array([c, mid, 0.3]) if ax == "x" else np.array([mid, c, 0.3])
        normal = np.array([1.0, 0.0]) if ax == "x" else np.array([0.0, 1.0])
        doors[name] = {"center": center, "width": float(e - s), "rooms": rooms, "normal": normal}
    scene, colors = box_list.scene(
        {
            "name": "apartment",
            "seed": int(seed),
            "units": "metres, z up, floor top at z = 0",
            "robot": "go2",
            "rooms": {k: [list(v[0]), list(v[1])] for k, v in ROOMS.items()},
            "doors": {k: {"center": v["center"].tolist(), "width": v["width"], "rooms": list(v["rooms"])} for k, v in doors.items()},
        }
    )
    return ApartmentLayout(scene=scene, colors=colors, rooms={k: (np.array(v[0]), np.array(v[1])) for k, v in ROOMS.items()}, doors=doors)


#: the cached layouts and splats; floaters in the region below, splat spacing per label
_CACHE = SceneCache(_build_layout, N_SPLATS, 1618, (np.array([-3.9, -2.9, 0.05]), np.array([3.9, 2.9, 1.1])), density={"floor": 2.0, "wall": 1.5}, top_only=("floor",))


def apartment_layout(seed: int = 0) -> ApartmentLayout:
    """The analytic apartment for a seed (fresh copies; furniture jittered by seed)."""
    return _CACHE.layout(seed)


def build_apartment(seed: int = 0, n_splats: int | None = None, haze: bool = False) -> tuple[Splats, AnalyticScene]:
    """The apartment splats and their boxes, fresh copies (cached in memory): see :func:`._layout.sample_splats`.
    ``seed`` jitters the layout and seeds the sampling; ``n_splats`` counts the sampled surface splats
    and floaters (default :data:`N_SPLATS`); ``haze``: add the real-capture look of
    :func:`add_capture_look` (haze, a mirror layer under the kitchen floor, floor-level matter), which
    adds about 13% more splats."""
    splats, scene = _CACHE.build(seed, n_splats)
    if haze:
        splats = add_capture_look(splats, scene, seed=seed)
    return splats, scene


# ---------------------------------------------------------------------------- real-capture look
#: The "real-capture look" of phone captures of apartments, measured on two of them:
#: faint **haze** (6-9% of all splats below opacity 0.1, 12-15% below 0.3; opacity 0.01-0.10,
#: stds 6-15 cm, hanging 10-40 cm above the floor), semi-transparent **fringe** splats (opacity
#: 0.1-0.3) a few centimetres off the surfaces, a **mirror layer** of opaque splats under a
#: shiny floor (the reflection of what stands on it, trained as geometry down to ~0.5 m below the
#: plane, stds up to 15 cm) and **floor-level matter** (rounded splats of opacity 0.3-0.9 and stds
#: of 2-5 cm whose means lie within 3 cm of the floor: not flat, so not the terrain rule's).
HAZE = {
    "haze_fraction": 0.075,  # opacity in [0.01, 0.10): the 6-9%
    "haze_opacity": (0.01, 0.10),
    "haze_std": (0.06, 0.15),
    "haze_height": (0.10, 0.40),
    "fringe_fraction": 0.03,  # opacity in [0.1, 0.3) at the surfaces' fringes: with the level-1 surface's own ~5%, 12-15% below 0.3
    "fringe_opacity": (0.10, 0.30),
    "fringe_offset": 0.03,  # std of their offset from a surface splat (m); stds x U(1, 2)
    "mirror_rooms": ("kitchen",),  # the shiny floor
    "mirror_fraction": 0.25,  # of the splats within mirror_reach above the shiny floor, reflected
    "mirror_reach": 0.50,
    "mirror_std_gain": (1.0, 3.0),  # reflections are blurrier: stds x U(1, 3), capped at mirror_std_max
    "mirror_std_max": 0.15,
    "floor_matter_per_m2": 2.0,
    "floor_matter_std": (0.02, 0.05),
    "floor_matter_opacity": (0.3, 0.9),
}


def _free_floor_points(scene: AnalyticScene, n: int, rng: np.random.Generator, z: np.ndarray | None = None, clearance: float = 0.0) -> np.ndarray:
    """``n`` points inside the rooms (xy uniform), at heights ``z`` (default 0), at least
    ``clearance`` from every box but the floor (rejection sampling)."""
    if n <= 0:
        return np.zeros((0, 3))
    lo, hi = np.array([-4.0, -3.0]), np.array([4.0, 3.0])
    keep = np.array([lab != "floor" for lab in scene.labels])
    sub = AnalyticScene(scene.boxes[keep], [lab for lab, k in zip(scene.labels, keep) if k], scene.meta)
    out = np.empty((0, 3))
    zs = np.zeros(n) if z is None else np.asarray(z, np.float64)
    for _ in range(50):
        m = 4 * n
        p = np.c_[rng.uniform(lo[0], hi[0], m), rng.uniform(lo[1], hi[1], m), np.zeros(m)]
        p[:, 2] = zs[rng.integers(0, n, m)]
        ok = np.array([room_of(q) is not None for q in p], dtype=bool) & (sub.sdf(p) > clearance)
        out = np.vstack([out, p[ok]])
        if len(out) >= n:
            break
    out = out[:n]
    out[:, 2] = zs[: len(out)]
    return out


def _random_quats(n: int, rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return q * np.where(q[:, :1] < 0, -1.0, 1.0)


def _span(v: Any) -> tuple[float, float]:
    """A (low, high) range of the capture-look parameters, as given (typed for the sampler)."""
    return v


def add_capture_look(splats: Splats, scene: AnalyticScene, seed: int = 0, params: dict | None = None) -> Splats:
    """The apartment ``splats`` with the real-capture look of :data:`HAZE` added (haze, fringe splats, a mirror layer under the kitchen's shiny floor, floor-level matter), seeded by ``seed``.

    The added splats come before the floaters (which stay last); ``info["capture_look"]`` counts them per kind (``haze``,
    ``fringe``, ``mirror``, ``floor_matter``). None of them is an obstacle of the ground truth (``scene``):
    haze and faint splats are free space, the mirror layer lies below the floor, the floor-level
    matter within a few centimetres of it.
    """
    p = {**HAZE, **(params or {})}
    rng = np.random.default_rng([int(seed), 3636])
    n0 = len(splats)
    rows = []  # (means, quats, scales, opacities, colors, kind)

    def cloud(n: int, heights: tuple[float, float], std: tuple[float, float], opacity: tuple[float, float], clearance: float):
        z = rng.uniform(*heights, n)
        means = _free_floor_points(scene, n, rng, z=z, clearance=clearance)
        k = len(means)
        scales = rng.uniform(*std, (k, 3)) * rng.uniform(0.6, 1.0, (k, 3)) ** np.array([0.0, 1.0, 1.0])
        cols = np.clip(np.array(LABEL_COLORS["wall"]) * rng.uniform(0.7, 1.0, (k, 1)), 0, 1)
        return means, _random_quats(k, rng), scales, rng.uniform(*opacity, k), cols

    # haze: faint, large, in the air above the floor, anywhere in the rooms' free space
    n_haze = int(round(p["haze_fraction"] * n0))
    rows.append((*cloud(n_haze, p["haze_height"], p["haze_std"], p["haze_opacity"], 0.0), "haze"))
    # fringe: semi-transparent copies of surface splats a few centimetres off the surface (on the
    # shared bathroom the splats of opacity 0.1-0.3 are 9% of all, at every height, median std 3.6 cm)
    n_surf0 = n0 - int(splats.info.get("n_floaters", 0))
    src = rng.integers(0, n_surf0, int(round(p["fringe_fraction"] * n0)))
    k = len(src)
    rows.append((splats.means[src] + rng.normal(0.0, p["fringe_offset"], (k, 3)), splats.quats[src], splats.scales[src] * rng.uniform(1.0, 2.0, (k, 1)),
                 rng.uniform(*_span(p["fringe_opacity"]), k), splats.colors[src], "fringe"))
    # mirror layer: the reflection in z = 0 of what stands on the shiny floor, opaque, blurrier
    z = splats.means[:, 2]
    shiny = np.array([room_of(m) in p["mirror_rooms"] for m in splats.means[:, :2]]) & (z > 0.005) & (z < p["mirror_reach"])
    idx = np.flatnonzero(shiny)
    idx = idx[rng.random(len(idx)) < p["mirror_fraction"]]
    if len(idx):
        means = splats.means[idx].astype(np.float64) * np.array([1.0, 1.0, -1.0])
        q = splats.quats[idx].astype(np.float64) * np.array([1.0, -1.0, -1.0, 1.0])  # reflection of the rotation in z = 0
        scales = np.minimum(splats.scales[idx] * rng.uniform(*_span(p["mirror_std_gain"]), (len(idx), 1)), p["mirror_std_max"])
        opac = np.maximum(splats.opacities[idx], 0.5)
        rows.append((means, q, scales, opac, splats.colors[idx] * 0.8, "mirror"))
    # floor-level matter: rounded splats at the floor (dust, grout, rug fibres)
    area = sum(float(np.prod(np.asarray(hi) - np.asarray(lo))) for lo, hi in ROOMS.values())
    n_fm = int(round(p["floor_matter_per_m2"] * area))
    m = _free_floor_points(scene, n_fm, rng, z=rng.uniform(-0.01, 0.03, n_fm), clearance=0.02)
    k = len(m)
    rows.append((m, _random_quats(k, rng), rng.uniform(*_span(p["floor_matter_std"]), (k, 3)), rng.uniform(*_span(p["floor_matter_opacity"]), k),
                 np.tile(np.array(LABEL_COLORS["floor"]) * 0.7, (k, 1)), "floor_matter"))

    n_surf = n0 - int(splats.info.get("n_floaters", 0))  # the floaters stay last

    def cat(i, base):
        return np.concatenate([base[:n_surf]] + [np.asarray(r[i], np.float32) for r in rows] + [base[n_surf:]])

    out = Splats(
        means=cat(0, splats.means),
        quats=cat(1, splats.quats),
        scales=cat(2, splats.scales),
        opacities=cat(3, splats.opacities),
        colors=cat(4, splats.colors),
        source_format=splats.source_format,
        info={**splats.info, "capture_look": {r[5]: int(len(r[0])) for r in rows}},
    )
    return out
