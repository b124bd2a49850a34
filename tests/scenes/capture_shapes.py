"""Synthetic object captures for the alignment tests: a chair with no floor, a model house on a
table disc, a tap on a wall inside a far background shell, a standing person-like column.

Every builder returns flat surface splats (normal = the surface's, smallest std along it) in a
**z-up world frame, metres**; :func:`in_capture_frame` re-expresses a scene in a capture frame
(``x_capture = R x_world``), so the true up in the capture frame is ``R @ [0, 0, 1]``.
"""

from __future__ import annotations

import numpy as np

from splatplan.scenes import Splats, rotmat_to_quat


def _frames(normals: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations whose third column is the unit normal (N, 3)."""
    n = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    ref = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    a = np.cross(n, ref)
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    return np.stack([a, np.cross(n, a), n], axis=2)


def surface(points: np.ndarray, normals: np.ndarray, std: float = 0.01, opacity: float = 0.9, seed: int = 0) -> Splats:
    """Flat splats at ``points`` (N, 3) with ``normals`` (N, 3): stds (std, std, std / 20)."""
    rng = np.random.default_rng(seed)
    n = len(points)
    quats = np.stack([rotmat_to_quat(r) for r in _frames(np.asarray(normals, float))])
    scales = np.tile([std, std, std / 20.0], (n, 1))
    return Splats(np.asarray(points, float), quats, scales, np.full(n, opacity), rng.uniform(0, 1, (n, 3)))


def box(rng, lo, hi, density: float = 4000.0, faces: tuple[str, ...] = ("-x", "+x", "-y", "+y", "-z", "+z")):
    """(points, normals) on the faces of the box lo..hi (m), ``density`` points per m^2."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    pts, nrm = [], []
    for f in faces:
        k, sign = "xyz".index(f[1]), (1.0 if f[0] == "+" else -1.0)
        o = [i for i in range(3) if i != k]
        area = (hi[o[0]] - lo[o[0]]) * (hi[o[1]] - lo[o[1]])
        m = max(int(density * area), 4)
        p = rng.uniform(lo, hi, (m, 3))
        p[:, k] = hi[k] if sign > 0 else lo[k]
        nn = np.zeros((m, 3))
        nn[:, k] = sign
        pts.append(p)
        nrm.append(nn)
    return np.concatenate(pts), np.concatenate(nrm)


def cylinder(rng, base, radius: float, height: float, density: float = 4000.0, top: bool = False):
    """(points, normals) on the side (and top disc) of an upright cylinder from ``base`` (m)."""
    m = max(int(density * 2 * np.pi * radius * height), 8)
    t = rng.uniform(0, 2 * np.pi, m)
    nn = np.c_[np.cos(t), np.sin(t), np.zeros(m)]
    p = np.asarray(base, float) + radius * nn + np.c_[np.zeros((m, 2)), rng.uniform(0, height, m)]
    if top:
        k = max(int(density * np.pi * radius**2), 4)
        rr, tt = radius * np.sqrt(rng.uniform(0, 1, k)), rng.uniform(0, 2 * np.pi, k)
        p = np.r_[p, np.asarray(base, float) + np.c_[rr * np.cos(tt), rr * np.sin(tt), np.full(k, height)]]
        nn = np.r_[nn, np.tile([0.0, 0.0, 1.0], (k, 1))]
    return p, nn


def _join(parts, std=0.01, seed=0) -> Splats:
    pts = np.concatenate([p for p, _ in parts])
    nrm = np.concatenate([n for _, n in parts])
    return surface(pts, nrm, std=std, seed=seed)


def chair(seed: int = 0, rear_posts: bool = True) -> Splats:
    """A 0.45 m chair (seat at 0.45 m, back up to 0.95 m), four legs, **no floor**; with
    ``rear_posts`` the rear legs run on up as the back's posts (one plane with the back)."""
    rng = np.random.default_rng(seed)
    parts = [box(rng, (-0.225, -0.225, 0.43), (0.225, 0.225, 0.47))]  # seat
    for x in (-0.2, 0.2):
        parts.append(cylinder(rng, (x, 0.2, 0.0), 0.02, 0.43))  # front legs
        parts.append(cylinder(rng, (x, -0.2, 0.0), 0.02, 0.95 if rear_posts else 0.43))  # rear legs (posts)
    parts.append(box(rng, (-0.2, -0.225, 0.6), (0.2, -0.2, 0.95)))  # the back panel
    return _join(parts, seed=seed)


def house_on_disc(seed: int = 0) -> Splats:
    """A 0.4 x 0.3 x 0.25 m model house with a gable roof on a 0.5 m-radius table disc (its top
    at z = 0; the patch under the house is not captured, as in a real scan)."""
    rng = np.random.default_rng(seed)
    k = 6000
    rr, tt = 0.5 * np.sqrt(rng.uniform(0, 1, k)), rng.uniform(0, 2 * np.pi, k)
    disc = np.c_[rr * np.cos(tt), rr * np.sin(tt), np.zeros(k)]
    disc = disc[~((np.abs(disc[:, 0]) < 0.2) & (np.abs(disc[:, 1]) < 0.15))]
    rim = cylinder(rng, (0.0, 0.0, -0.03), 0.5, 0.03)
    walls = box(rng, (-0.2, -0.15, 0.0), (0.2, 0.15, 0.25), faces=("-x", "+x", "-y", "+y"))
    roof = []
    for sgn in (-1.0, 1.0):  # two slopes from the eaves (y = +-0.15, z = 0.25) to the ridge (y = 0, z = 0.4)
        m = 1500
        a, b = rng.uniform(-0.2, 0.2, m), rng.uniform(0, 1, m)
        p = np.c_[a, sgn * 0.15 * (1 - b), 0.25 + 0.15 * b]
        roof.append((p, np.tile(np.array([0.0, sgn * 0.15, 0.15]) / np.hypot(0.15, 0.15), (m, 1))))
    return _join([(disc, np.tile([0.0, 0.0, 1.0], (len(disc), 1))), rim, walls, *roof], std=0.008, seed=seed)


def tap_on_wall(seed: int = 0, shell: int = 10242, shell_radius: float = 240.0) -> Splats:
    """A shower tap on a 1.2 x 1.2 m wall (the wall in the plane x = 0, its normal +x towards the
    tap; z up, the wall from z = 0.6 to 1.8 m) inside a background shell of ``shell`` opaque splats
    (a quarter of all splats) at ``shell_radius`` m."""
    rng = np.random.default_rng(seed)
    k = 30000
    wall = np.c_[np.zeros(k), rng.uniform(-0.6, 0.6, k), rng.uniform(0.6, 1.8, k)]
    parts = [(wall, np.tile([1.0, 0.0, 0.0], (k, 1)))]
    parts.append(box(rng, (0.0, -0.04, 1.0), (0.08, 0.04, 1.08)))  # mixer body
    parts.append(box(rng, (0.0, -0.015, 1.08), (0.03, 0.015, 1.65)))  # riser pipe
    parts.append(box(rng, (0.03, -0.015, 1.62), (0.25, 0.015, 1.65)))  # arm
    parts.append(cylinder(rng, (0.25, 0.0, 1.58), 0.08, 0.04, top=True))  # shower head
    s = _join(parts, std=0.006, seed=seed)
    if shell:
        d = rng.normal(size=(shell, 3))
        far = surface(np.array([0.0, 0.0, 1.2]) + shell_radius * d / np.linalg.norm(d, axis=1, keepdims=True), -d, std=0.5, seed=seed + 1)
        s = concat(s, far)
    return s


def person(seed: int = 0) -> Splats:
    """A standing person-like stack of cylinders, 1.75 m tall, no floor."""
    rng = np.random.default_rng(seed)
    parts = [cylinder(rng, (x, 0.0, 0.0), 0.07, 0.85) for x in (-0.1, 0.1)]  # legs
    parts.append(cylinder(rng, (0.0, 0.0, 0.85), 0.18, 0.6))  # body
    parts.append(cylinder(rng, (0.0, 0.0, 1.5), 0.1, 0.25, top=True))  # head
    return _join(parts, seed=seed)


def concat(a: Splats, b: Splats) -> Splats:
    return Splats(np.r_[a.means, b.means], np.r_[a.quats, b.quats], np.r_[a.scales, b.scales], np.r_[a.opacities, b.opacities], np.r_[a.colors, b.colors])


def random_rotation(rng) -> np.ndarray:
    """(3, 3) a uniformly random rotation."""
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])  # fmt: skip


def in_capture_frame(s: Splats, r: np.ndarray, offset=(0.0, 0.0, 0.0)) -> Splats:
    """The scene with ``x_capture = r x_world + offset`` (orientations rotated along)."""
    from splatplan.scenes.transforms import apply_rigid

    return apply_rigid(s, np.asarray(r, float), np.asarray(offset, float))


def nearest_axis_name(v) -> str:
    i = int(np.argmax(np.abs(v)))
    return ("+" if v[i] >= 0 else "-") + "xyz"[i]
