"""The built-in ``stonehenge`` scene: analytic boxes (exact ground truth) + 3DGS-like splats.

Stand-in for Splat-Nav's trained Stonehenge (not available here), used by the studies E1-E4 of
SPEC section 4. The geometry is a union of oriented boxes (:class:`AnalyticScene`), so the exact
signed distance is known; the splats are sampled from the box surfaces by
:func:`~splatplan.scenes.builtin.surface_splats.splats_from_boxes`.

Units and frames
----------------
Normalised scene units, **z up**, the whole scene inside x, y in [-0.5, 0.5]; the ground is a thin
box whose top face is z = 0. Quaternions are wxyz (box/splat frame -> world).

Layout
------
* an outer ring (radius ~0.3) of 16 upright sarsens (~0.11-0.12 tall), lintels over adjacent
  pairs, forming gates of designed widths (:data:`RING_GATES`): some narrower than the robot
  sphere (diameter 0.03), some 0.03-0.05, some 0.06-0.1, and two wide gaps without lintels;
* an inner horseshoe of 5 trilithons (two tall uprights with a narrow slit + a lintel, 0.14-0.16
  tall), open towards the main entrance gap;
* fallen / leaning stones (rotated boxes), a flat altar stone, the heel and station stones
  outside the ring, a few small rocks;
* every stone sinks :data:`SINK` into the ground and lintels sink into their uprights, so contact
  faces are buried (no splats inside the geometry).

A horizontal plane at z = :data:`PLANE_Z` = 0.06 cuts every upright, so planar planning from the
centre to the border must pass a gate wider than the robot or go through a gap.

Splats: ``build_stonehenge(level)`` gives ~200k splats at level 1 and ``200k / 1.8**(L-1)`` at
level L (1..5): fewer, larger, thicker and more anisotropic splats at higher levels, mimicking a
3DGS trained with higher densification thresholds. The ground uses twice the spacing of the
stones. The last ``splats.info["n_floaters"]`` splats are floaters.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ...errors import SplatplanError
from .levels import LEVEL_RATIO, N_SPLATS_LEVEL1, default_n_splats, level_config, splat_count  # noqa: F401 (re-exported)
from .analytic_scene import AnalyticScene
from .primitive_sdf import box_corners, make_box, yaw_quat
from .surface_splats import copy_splats, splats_from_boxes
from ..splats import SH_C0, Splats, quat_multiply

__all__ = [
    "PLANE_Z",
    "RING_GATES",
    "StonehengeLayout",
    "build_stonehenge",
    "default_n_splats",
    "ground_truth_path",
    "level_config",
    "load_ground_truth",
    "plot_top_view",
    "stonehenge_layout",
    "write_stonehenge",
]

#: Height of the horizontal plane used for planar planning (cuts every upright).
PLANE_Z = 0.06
#: Depth every stone is sunk into the ground / a lintel into its uprights (buries contact faces).
SINK = 0.004
#: Radius of the sphere robot the gates are designed around (scene units): the studies' sphere
#: :data:`~splatplan.robots.DEFAULT_POINT_ROBOT` (a test checks they agree).
DESIGN_ROBOT_RADIUS = 0.015

#: Designed ring gates, in order around the ring: (width between the facing inner corners of two
#: adjacent sarsens, lintel on top?). The last one is the main entrance gap. Actual widths (after
#: seed jitter) are in :attr:`StonehengeLayout.gate_widths`.
RING_GATES: tuple[tuple[float, bool], ...] = (
    (0.020, True),
    (0.045, True),
    (0.070, True),
    (0.025, True),
    (0.035, True),
    (0.090, True),
    (0.015, True),
    (0.040, True),
    (0.140, False),  # gap: a missing stone
    (0.060, True),
    (0.022, True),
    (0.080, True),
    (0.050, True),
    (0.018, True),
    (0.100, True),
    (0.160, False),  # main entrance gap
)

_STONE_W = 0.05  # ring sarsen tangential width
_STONE_T = 0.035  # ring sarsen radial thickness
_STONE_H = 0.115  # ring sarsen height (before jitter)
_LINTEL_H = 0.02
_ENTRANCE_ANGLE = np.deg2rad(40.0)  # direction of the main entrance gap (from +x, ccw)

_GREY = np.array([0.60, 0.58, 0.55])
_GROUND = np.array([0.33, 0.47, 0.24])


def _axis_quat(axis, angle: float) -> np.ndarray:
    a = np.asarray(axis, np.float64)
    a = a / np.linalg.norm(a)
    return np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * a])


def _rect_distance(a: np.ndarray, b: np.ndarray) -> tuple[float, np.ndarray]:
    """Distance between two disjoint convex polygons given by corners (4, 2) and its midpoint.

    For disjoint convex polygons the minimum is attained at a vertex of one of them, so checking
    every vertex against the other polygon (as a 2D oriented rectangle) is exact.
    """

    def point_rect(p: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        c = r.mean(0)
        e1, e2 = r[1] - r[0], r[2] - r[0]
        # corners are ordered with index bits (x, y): r[0]=(-,-), r[1]=(+,-), r[2]=(-,+)
        u1, u2 = e1 / np.linalg.norm(e1), e2 / np.linalg.norm(e2)
        h1, h2 = np.linalg.norm(e1) / 2, np.linalg.norm(e2) / 2
        d = p - c
        s1 = np.clip(d @ u1, -h1, h1)
        s2 = np.clip(d @ u2, -h2, h2)
        q = c + s1[:, None] * u1 + s2[:, None] * u2
        return np.linalg.norm(p - q, axis=1), q

    da, qa = point_rect(a, b)
    db, qb = point_rect(b, a)
    if da.min() <= db.min():
        i = int(np.argmin(da))
        return float(da[i]), (a[i] + qa[i]) / 2
    i = int(np.argmin(db))
    return float(db[i]), (b[i] + qb[i]) / 2


def _footprint(box: np.ndarray) -> np.ndarray:
    """(4, 2) xy corners of a yaw-only box (index bits x, y)."""
    return box_corners(box)[:4, :2]


@dataclass(frozen=True)
class StonehengeLayout:
    """The analytic Stonehenge and its named features (scene units, z up).

    Attributes:
        scene: the boxes (ground first), labels in {"ground", "sarsen", "lintel", "trilithon",
            "trilithon_lintel", "fallen", "leaning", "altar", "heel", "station", "rock"}.
        gate_widths: float64 (G,) exact minimum distance between the two ring sarsens of each
            gate (horizontal, the uprights are vertical prisms), in ring order.
        gate_centers: float64 (G, 3) midpoint of the closest points of each gate, at z = plane_z.
        gate_has_lintel: bool (G,); False marks a gap in the ring (no lintel).
        trilithon_gap_widths: float64 (T-1,) minimum distances between adjacent trilithons of the
            horseshoe (the slit inside a trilithon is ~0.01: impassable).
        ring_radius: radius of the sarsen centres.
        robot_radius: the planning sphere's radius (0.015: the sphere
            :data:`~splatplan.robots.DEFAULT_POINT_ROBOT` the gates are sized for).
        plane_z: height of the planar-planning plane (0.06).
    """

    scene: AnalyticScene
    gate_widths: np.ndarray
    gate_centers: np.ndarray
    gate_has_lintel: np.ndarray
    trilithon_gap_widths: np.ndarray
    ring_radius: float
    robot_radius: float = DESIGN_ROBOT_RADIUS
    plane_z: float = PLANE_Z


def _ring_radius(widths: np.ndarray, w: float, t: float) -> float:
    """Ring-centre radius R such that the stones with the given inner-corner gaps close the ring.

    The gap between the inner corners of two stones at angular distance 2a (stones tangent to the
    ring) is ``2 (r_i sin a - (w/2) cos a)`` with r_i = R - t/2; solve for a per gate and bisect R
    so that the angles sum to 2 pi.
    """

    def total(r_c: float) -> float:
        ri = r_c - t / 2
        rho, beta = np.hypot(ri, w / 2), np.arctan2(w / 2, ri)
        return float(np.sum(2 * (beta + np.arcsin(np.clip(widths / (2 * rho), -1, 1)))))

    lo, hi = 0.05, 2.0
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if total(mid) > 2 * np.pi else (lo, mid)
    return 0.5 * (lo + hi)


def _build_layout(seed: int) -> StonehengeLayout:
    rng = np.random.default_rng([int(seed), 7711])
    boxes: list[np.ndarray] = []
    labels: list[str] = []

    def add(label: str, center, half, quat=(1.0, 0.0, 0.0, 0.0)) -> int:
        boxes.append(make_box(center, half, quat))
        labels.append(label)
        return len(boxes) - 1

    # Ground: top face at z = 0, covering x, y in [-0.5, 0.5].
    add("ground", (0.0, 0.0, -0.02), (0.5, 0.5, 0.02))

    # ---------------------------------------------------------------- outer ring of sarsens
    widths = np.array([g for g, _ in RING_GATES])
    has_lintel = np.array([lt for _, lt in RING_GATES])
    n = len(widths)
    r_c = _ring_radius(widths, _STONE_W, _STONE_T)
    ri = r_c - _STONE_T / 2
    rho, beta = np.hypot(ri, _STONE_W / 2), np.arctan2(_STONE_W / 2, ri)
    half_steps = beta + np.arcsin(widths / (2 * rho))  # (n,) half angle of each gate
    # stone k sits between gate k-1 and gate k; put the entrance gap (last gate) at _ENTRANCE_ANGLE
    phi = np.concatenate([[0.0], np.cumsum(2 * half_steps)[:-1]])  # stone k angle, stone 0 first
    phi += _ENTRANCE_ANGLE - (phi[-1] + half_steps[-1])
    heights = _STONE_H + rng.uniform(-0.006, 0.006, n)
    yaw_jit = np.deg2rad(rng.uniform(-1.5, 1.5, n))
    rad_jit = rng.uniform(-0.002, 0.002, n)
    sarsens = []
    for k in range(n):
        c = (r_c + rad_jit[k]) * np.array([np.cos(phi[k]), np.sin(phi[k])])
        h = heights[k]
        sarsens.append(
            add("sarsen", (c[0], c[1], (h - SINK) / 2), (_STONE_T / 2, _STONE_W / 2, (h + SINK) / 2), yaw_quat(phi[k] + yaw_jit[k]))
        )
    gate_w, gate_c = np.zeros(n), np.zeros((n, 3))
    for k in range(n):
        a, b = boxes[sarsens[k]], boxes[sarsens[(k + 1) % n]]
        d, mid = _rect_distance(_footprint(a), _footprint(b))
        gate_w[k], gate_c[k] = d, (mid[0], mid[1], PLANE_Z)
        if has_lintel[k]:
            ca, cb = a[:2], b[:2]
            mid_ab = (ca + cb) / 2
            span = np.linalg.norm(cb - ca)
            yaw = np.arctan2(cb[1] - ca[1], cb[0] - ca[0])
            z0 = min(heights[k], heights[(k + 1) % n]) - SINK
            add(
                "lintel",
                (mid_ab[0], mid_ab[1], z0 + _LINTEL_H / 2),
                (span / 2 + 0.35 * _STONE_W, 0.9 * _STONE_T / 2, _LINTEL_H / 2),
                yaw_quat(yaw),
            )

    # ---------------------------------------------------------------- inner horseshoe of trilithons
    back = _ENTRANCE_ANGLE + np.pi
    tri_angles = back + np.deg2rad(np.array([-100.0, -50.0, 0.0, 48.0, 97.0]))
    tri_heights = np.array([0.14, 0.148, 0.16, 0.146, 0.142]) + rng.uniform(-0.004, 0.004, 5)
    tri_r, tri_w, tri_t, slit = 0.155, 0.034, 0.03, 0.01
    tri_boxes = []
    for ang, h in zip(tri_angles, tri_heights):
        radial = np.array([np.cos(ang), np.sin(ang)])
        tang = np.array([-np.sin(ang), np.cos(ang)])
        pair = []
        for s in (-1.0, 1.0):
            c = tri_r * radial + s * (slit / 2 + tri_w / 2) * tang
            pair.append(add("trilithon", (c[0], c[1], (h - SINK) / 2), (tri_t / 2, tri_w / 2, (h + SINK) / 2), yaw_quat(ang)))
        tri_boxes.append(pair)
        c = tri_r * radial
        add(
            "trilithon_lintel",
            (c[0], c[1], h - SINK + _LINTEL_H / 2),
            (0.9 * tri_t / 2, slit / 2 + tri_w + 0.004, _LINTEL_H / 2),
            yaw_quat(ang),
        )
    tri_gaps = np.array(
        [
            _rect_distance(_footprint(boxes[tri_boxes[i][1]]), _footprint(boxes[tri_boxes[i + 1][0]]))[0]
            for i in range(len(tri_boxes) - 1)
        ]
    )

    # ---------------------------------------------------------------- fallen, leaning, small stones
    def polar(r: float, ang_deg: float) -> np.ndarray:
        a = back + np.deg2rad(ang_deg)
        return r * np.array([np.cos(a), np.sin(a)])

    # a fallen sarsen lying between horseshoe and ring (below the planning plane)
    c = polar(0.235, -140.0)
    add("fallen", (c[0], c[1], 0.012 - SINK), (0.05, 0.02, 0.012 + SINK), yaw_quat(np.deg2rad(35.0) + rng.uniform(-0.1, 0.1)))
    # a fallen lintel tilted against the ground outside the ring (one end up)
    c = polar(0.40, 150.0)
    q = quat_multiply(yaw_quat(np.deg2rad(-20.0)), _axis_quat((0, 1, 0), np.deg2rad(-28.0)))
    add("fallen", (c[0], c[1], 0.018), (0.05, 0.016, 0.01), q)
    # a leaning upright (tilted ~22 degrees sideways, along the ring) between horseshoe and ring,
    # beside two narrow gates: it cuts the planning plane
    c = polar(0.225, 110.0)
    ang = back + np.deg2rad(110.0)
    q = quat_multiply(yaw_quat(ang), _axis_quat((1, 0, 0), np.deg2rad(22.0) + rng.uniform(-0.03, 0.03)))
    add("leaning", (c[0], c[1], 0.045), (0.015, 0.022, 0.06), q)
    # a broken stump + a tilted block outside the ring
    c = polar(0.41, -60.0)
    q = quat_multiply(yaw_quat(np.deg2rad(10.0)), _axis_quat((1, 0, 0), np.deg2rad(12.0)))
    add("fallen", (c[0], c[1], 0.025), (0.025, 0.03, 0.03), q)
    # the altar stone: a flat slab inside the horseshoe, off centre, below the planning plane
    c = polar(0.075, 10.0)
    add("altar", (c[0], c[1], 0.008 - SINK), (0.012, 0.04, 0.008 + SINK), yaw_quat(back + np.deg2rad(10.0)))
    # heel stone (outside the entrance, slightly tilted) and two station stones
    c = 0.43 * np.array([np.cos(_ENTRANCE_ANGLE), np.sin(_ENTRANCE_ANGLE)])
    q = quat_multiply(yaw_quat(_ENTRANCE_ANGLE), _axis_quat((0, 1, 0), np.deg2rad(8.0)))
    add("heel", (c[0], c[1], 0.045 - SINK), (0.02, 0.025, 0.045 + SINK), q)
    for ang_deg in (-95.0, 95.0):
        c = polar(0.40, ang_deg)
        add("station", (c[0], c[1], (0.05 - SINK) / 2), (0.012, 0.015, (0.05 + SINK) / 2), yaw_quat(np.deg2rad(ang_deg)))
    # small rocks scattered inside and outside the ring
    for r, ang_deg, s in ((0.09, -150.0, 0.01), (0.24, 170.0, 0.008), (0.36, -25.0, 0.012), (0.44, 120.0, 0.01), (0.24, -70.0, 0.009)):
        c = polar(r, ang_deg) + rng.uniform(-0.005, 0.005, 2)
        add("rock", (c[0], c[1], s - SINK), (s, 0.8 * s, s), yaw_quat(rng.uniform(0, np.pi)))

    scene = AnalyticScene(
        np.stack(boxes),
        labels,
        {
            "name": "stonehenge",
            "seed": int(seed),
            "units": "normalised scene units, z up, ground top at z = 0",
            "robot_radius": DESIGN_ROBOT_RADIUS,
            "plane_z": PLANE_Z,
            "gate_widths": gate_w.tolist(),
        },
    )
    return StonehengeLayout(
        scene=scene,
        gate_widths=gate_w,
        gate_centers=gate_c,
        gate_has_lintel=has_lintel,
        trilithon_gap_widths=tri_gaps,
        ring_radius=float(r_c),
    )


@functools.lru_cache(maxsize=8)
def _layout_cached(seed: int) -> StonehengeLayout:
    return _build_layout(seed)


def stonehenge_layout(seed: int = 0) -> StonehengeLayout:
    """The analytic Stonehenge for a seed (layout fixed; heights/yaws/rocks jittered by seed).

    Returns a fresh copy each call (arrays may be modified freely).
    """
    lay = _layout_cached(int(seed))
    return replace(
        lay,
        scene=lay.scene.copy(),
        gate_widths=lay.gate_widths.copy(),
        gate_centers=lay.gate_centers.copy(),
        gate_has_lintel=lay.gate_has_lintel.copy(),
        trilithon_gap_widths=lay.trilithon_gap_widths.copy(),
    )


@functools.lru_cache(maxsize=6)
def _build_cached(level: int, seed: int, n_splats: int) -> tuple[Splats, AnalyticScene]:
    lay = _layout_cached(seed)
    scene = lay.scene
    m = len(scene)
    rng = np.random.default_rng([int(seed), int(level), int(n_splats), 3141])
    # base colour per box: grey with a per-stone tint, ground green
    colors = np.clip(_GREY + rng.normal(0.0, 0.04, (m, 1)) + rng.normal(0.0, 0.015, (m, 3)), 0, 1)
    density = np.ones(m)
    faces = np.ones((m, 6), bool)
    for i, lab in enumerate(scene.labels):
        if lab == "ground":
            colors[i] = _GROUND
            density[i] = 2.0  # the ground uses twice the spacing (fewer, larger splats)
            faces[i] = [False, False, False, False, True, False]  # only the top face is seen
    splats = splats_from_boxes(
        scene,
        n_splats,
        config=level_config(level),
        colors=colors,
        density=density,
        faces=faces,
        floater_region=(np.array([-0.45, -0.45, 0.01]), np.array([0.45, 0.45, 0.22])),
        seed=rng,
    )
    splats.info.update({"scene": "stonehenge", "level": int(level), "seed": int(seed), "units": scene.meta["units"]})
    return splats, scene


def build_stonehenge(level: int = 1, seed: int = 0, n_splats: int | None = None) -> tuple[Splats, AnalyticScene]:
    """The Stonehenge splats and their analytic ground truth.

    Args:
        level: Gaussian-size level 1..5 (1: ~200k small splats; L: ~200k / 1.8**(L-1)).
        seed: layout jitter and splat sampling seed (deterministic).
        n_splats: total splat count (floaters included); default :func:`default_n_splats`.

    Returns:
        (splats, scene): float32 splats (wxyz quats, linear stds, the last
        ``splats.info["n_floaters"]`` are floaters) and the boxes they were sampled from.
        Fresh copies each call (an in-memory LRU cache makes repeated calls cheap).
    """
    lv = int(level)
    if lv not in (1, 2, 3, 4, 5):
        raise SplatplanError(f"stonehenge level must be 1..5, got {level}")
    s, sc = _build_cached(lv, int(seed), splat_count(n_splats, default_n_splats(lv)))
    return copy_splats(s), sc.copy()


# ---------------------------------------------------------------------------------------------
# Files
# ---------------------------------------------------------------------------------------------


def ground_truth_path(ply_path) -> Path:
    """``<stem>.gt.json`` beside the ply: where the analytic ground truth of a built scene lives."""
    p = Path(ply_path)
    return p.with_name(p.stem + ".gt.json")


def load_ground_truth(ply_path) -> AnalyticScene:
    """The :class:`AnalyticScene` saved beside ``ply_path`` by :func:`write_stonehenge`."""
    gt = ground_truth_path(ply_path)
    if not gt.is_file():
        raise SplatplanError(f"no ground truth beside {ply_path}: expected {gt} (write it with write_stonehenge)")
    return AnalyticScene.load(gt)


def _write_inria_ply(path: Path, splats: Splats) -> None:
    """INRIA 3DGS .ply: x y z nx ny nz f_dc_0..2 opacity(logit) scale_0..2(log) rot_0..3(wxyz)."""
    from plyfile import PlyData, PlyElement

    names = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2", "opacity"]
    names += ["scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    n = len(splats)
    arr = np.empty(n, dtype=[(k, "<f4") for k in names])
    arr["x"], arr["y"], arr["z"] = splats.means.T
    arr["nx"] = arr["ny"] = arr["nz"] = 0.0
    f_dc = (splats.colors.astype(np.float64) - 0.5) / SH_C0
    for k in range(3):
        arr[f"f_dc_{k}"] = f_dc[:, k]
    o = np.clip(splats.opacities.astype(np.float64), 1e-6, 1 - 1e-6)
    arr["opacity"] = np.log(o / (1 - o))
    ls = np.log(np.maximum(splats.scales.astype(np.float64), 1e-12))
    for k in range(3):
        arr[f"scale_{k}"] = ls[:, k]
        arr[f"rot_{k}"] = splats.quats[:, k]
    arr["rot_3"] = splats.quats[:, 3]
    PlyData([PlyElement.describe(arr, "vertex")], text=False).write(str(path))


def write_stonehenge(out_ply, level: int = 1, seed: int = 0) -> tuple[Path, Path]:
    """Write the level-``level`` Stonehenge as an INRIA 3DGS .ply plus its ground truth JSON.

    Returns:
        (ply path, ground-truth JSON path ``<stem>.gt.json``).
    """
    out_ply = Path(out_ply)
    if out_ply.suffix.lower() != ".ply":
        raise SplatplanError(f"write_stonehenge writes an INRIA .ply; got {out_ply.name!r} (use a .ply name)")
    out_ply.parent.mkdir(parents=True, exist_ok=True)
    splats, scene = build_stonehenge(level=level, seed=seed)
    save_ply(out_ply, splats)
    gt = ground_truth_path(out_ply)
    scene = AnalyticScene(
        scene.boxes,
        scene.labels,
        {**scene.meta, "level": int(level), "n_splats": len(splats), "n_floaters": int(splats.info["n_floaters"]), "ply": out_ply.name},
    )
    scene.save(gt)
    return out_ply, gt


def save_ply(path: Path, splats: Splats) -> None:
    """Write with the project's scene writer (:func:`splatplan.scenes.load.save_scene`), falling
    back to the minimal INRIA writer above if the I/O stage is not importable."""
    try:
        from ..load import save_scene
    except ImportError:  # pragma: no cover - only while the I/O stage is missing
        _write_inria_ply(path, splats)
    else:
        save_scene(splats, path)


# ---------------------------------------------------------------------------------------------
# Plotting
# ---------------------------------------------------------------------------------------------

LABEL_COLORS = {
    "sarsen": "#6b6b6b",
    "lintel": "#8a8a8a",
    "trilithon": "#4d4d4d",
    "trilithon_lintel": "#7a7a7a",
    "fallen": "#9c8b6e",
    "leaning": "#a0522d",
    "altar": "#5f7f9f",
    "heel": "#6f5f8f",
    "station": "#6f5f8f",
    "rock": "#8f8f6f",
}


def box_cross_section(box: np.ndarray, z: float) -> np.ndarray | None:
    """Polygon (K, 2) of the intersection of a box with the plane ``z`` (ccw), or None."""
    corners = box_corners(box)  # (8, 3)
    pts = []
    for i in range(8):
        for b in range(3):
            j = i | (1 << b)
            if j == i:
                continue
            z0, z1 = corners[i, 2] - z, corners[j, 2] - z
            if z0 == 0.0:
                pts.append(corners[i, :2])
            if (z0 < 0) != (z1 < 0) and z0 != 0.0 and z1 != 0.0:
                t = z0 / (z0 - z1)
                pts.append(corners[i, :2] + t * (corners[j, :2] - corners[i, :2]))
    if len(pts) < 3:
        return None
    p = np.unique(np.round(np.asarray(pts), 12), axis=0)
    if len(p) < 3:
        return None
    c = p.mean(0)
    order = np.argsort(np.arctan2(p[:, 1] - c[1], p[:, 0] - c[0]))
    return p[order]


def _footprint_hull(box: np.ndarray) -> np.ndarray:
    pts = box_corners(box)[:, :2]
    from scipy.spatial import ConvexHull

    return pts[ConvexHull(pts).vertices]


def plot_top_view(ax, scene: AnalyticScene, z: float = PLANE_Z, *, footprints: bool = True, inflate: float = 0.0):
    """Draw the cross-section of the boxes at height ``z`` on a matplotlib axes (top view, x-y).

    Filled polygons are the sections (coloured by label); with ``footprints``, the full xy
    projection of every non-ground box is outlined lightly (stones below or above ``z`` show
    too). ``inflate > 0`` additionally draws the section grown by that radius (e.g. the robot
    radius: the configuration-space obstacle), as a dashed outline.

    Args:
        ax: a matplotlib Axes.
        scene: the analytic scene.
        z: section height (scene units).
        footprints: outline every box's projection.
        inflate: radius for the optional configuration-space outline (scene units).

    Returns:
        The axes.
    """
    from matplotlib.patches import Polygon

    lo, hi = scene.bounds()
    for box, lab in zip(scene.boxes, scene.labels):
        if lab == "ground":
            continue
        if footprints:
            ax.add_patch(Polygon(_footprint_hull(box), closed=True, fill=False, ec="0.7", lw=0.5, zorder=1))
        sec = box_cross_section(box, z)
        if sec is not None:
            ax.add_patch(Polygon(sec, closed=True, fc=LABEL_COLORS.get(lab, "0.4"), ec="k", lw=0.5, zorder=2))
            if inflate > 0:
                # Minkowski sum of a convex polygon and a disk, sampled densely.
                t = np.linspace(0, 2 * np.pi, 24, endpoint=False)
                disk = inflate * np.stack([np.cos(t), np.sin(t)], 1)
                pts = (sec[:, None, :] + disk[None]).reshape(-1, 2)
                from scipy.spatial import ConvexHull

                ax.add_patch(Polygon(pts[ConvexHull(pts).vertices], closed=True, fill=False, ec="tab:red", ls="--", lw=0.6, zorder=3))
    ax.set_xlim(min(lo[0], -0.5), max(hi[0], 0.5))
    ax.set_ylim(min(lo[1], -0.5), max(hi[1], 0.5))
    ax.set_aspect("equal")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_title(f"section at z = {z:.3f}")
    return ax
