"""Primitive surfaces -> 3DGS-like splats: the surface sampler of the built-in scenes.

:func:`splats_from_scene` samples the exposed surfaces of an
:class:`~.analytic_scene.AnalyticScene` (box faces, cylinder sides and caps, sphere surfaces) on a
jittered grid and gives each sample a splat with the statistics of real captures
(:class:`SurfaceSplatConfig`); :func:`n_splats_for_spacing` turns a target spacing into a splat
count. Coordinates are in scene units, world frame; quaternions wxyz.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..._config import bounded, check_config
from ...errors import SplatplanError
from ..splats import Splats, quat_multiply, quat_to_rotmat, rotmat_to_quat
from .analytic_scene import AnalyticScene, box_aabbs
from .primitive_sdf import curved_sdf

__all__ = [
    "FACE_NAMES", "SurfaceSplatConfig", "copy_splats", "n_splats_for_spacing", "sample_faces", "splats_from_boxes", "splats_from_scene",
]  # fmt: skip


def copy_splats(s: Splats) -> Splats:
    """Fresh arrays of a cached built-in scene's splats (``info`` copied too)."""
    return replace(
        s,
        means=s.means.copy(),
        quats=s.quats.copy(),
        scales=s.scales.copy(),
        opacities=s.opacities.copy(),
        colors=s.colors.copy(),
        info=dict(s.info),
    )


@dataclass(frozen=True)
class SurfaceSplatConfig:
    """How :func:`splats_from_scene` turns primitive surfaces into 3DGS-like splats.

    All lengths are relative to the *local sample spacing* ``h`` (the side of the jittered-grid cell
    a splat was drawn from), so the look is the same at any splat count.
    """

    #: Tangential std = ``tangential_factor * h`` before jitter (0.5-0.7 makes neighbours overlap).
    tangential_factor: float = bounded(0.6, gt=0)
    #: Normal std = ``thickness * smaller tangential std`` (flat splats: 0.1-0.2).
    thickness: float = bounded(0.15, gt=0)
    #: Log-std of the per-splat isotropic size jitter (lognormal).
    size_jitter: float = bounded(0.25, ge=0)
    #: Log-std of the in-plane anisotropy: s_t1 = s exp(+a), s_t2 = s exp(-a), a ~ N(0, this)
    #: clipped at 2 std.
    anisotropy: float = bounded(0.15, ge=0)
    #: Log-std of the jitter of the normal std (the normal std stays below the tangential ones).
    thickness_jitter: float = bounded(0.3, ge=0)
    #: Std (degrees) of the tilt of a splat's normal axis away from the face normal (0 = exact).
    tilt_deg: float = 0.0
    #: Position noise along the face normal, std = this * h.
    normal_noise: float = bounded(0.15, ge=0)
    #: Position noise in the face plane, std = this * h.
    tangential_noise: float = bounded(0.2, ge=0)
    #: Fraction of splats with a lower opacity drawn from U(low_opacity_range).
    low_opacity_fraction: float = bounded(0.15, ge=0, le=1)
    #: Opacity range of the low-opacity splats.
    low_opacity_range: tuple[float, float] = bounded((0.15, 0.6), ge=0, le=1)
    #: The others get 1 - (1 - min_high_opacity) * U^2 (mostly close to 1).
    min_high_opacity: float = bounded(0.6, ge=0, le=1)
    #: Per-splat colour noise std (RGB, added to the box's base colour, then clipped to [0, 1]).
    color_noise: float = bounded(0.04, ge=0)
    #: Fraction of all splats that are floaters (large, transparent, in free space).
    floater_fraction: float = bounded(0.0005, ge=0, le=1)
    #: Floater max std = U(range) * median over surface splats of their max std.
    floater_size_range: tuple[float, float] = bounded((8.0, 25.0), gt=0)
    #: Fraction of floaters with opacity < 0.1 (the rest get U(0.1, 0.3): a filter misses them).
    floater_transparent_fraction: float = bounded(0.85, ge=0, le=1)
    #: Floaters are kept at least this far (scene units) from the geometry.
    floater_clearance: float = bounded(0.02, ge=0)

    def validate(self) -> "SurfaceSplatConfig":
        """Check every field's declared range (:mod:`splatplan._config`); returns self."""
        return check_config(self)


#: Face ids: 0 +x, 1 -x, 2 +y, 3 -y, 4 +z, 5 -z (in the box frame).
FACE_NAMES = ("+x", "-x", "+y", "-y", "+z", "-z")


def _face_frames(box: np.ndarray, rot: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per face of one box: (centre (3,), frame (3, 3) columns t1 t2 n (right-handed), half (2,))."""
    out = []
    h = box[3:6]
    for k in range(3):
        a, b = (k + 1) % 3, (k + 2) % 3
        for sign in (1.0, -1.0):
            n = sign * rot[:, k]
            if sign > 0:
                t1, t2, ha, hb = rot[:, a], rot[:, b], h[a], h[b]
            else:  # swap the tangents so that (t1, t2, n) stays right-handed
                t1, t2, ha, hb = rot[:, b], rot[:, a], h[b], h[a]
            out.append((box[:3] + n * h[k], np.stack([t1, t2, n], axis=1), np.array([ha, hb])))
    return out


def sample_faces(
    scene: AnalyticScene,
    spacing: np.ndarray,  # (M,) target grid spacing per box
    faces: np.ndarray,  # (M, 6) bool, which faces to sample
    rng: np.random.Generator,
    curved_spacing: float | None = None,
) -> dict[str, np.ndarray]:
    """Jittered-grid samples on the chosen box faces and on every cylinder and sphere surface
    (at ``curved_spacing``, default the median box spacing), with buried samples removed.

    Returns a dict of arrays over the kept samples S: ``p`` (S, 3) points, ``frame`` (S,) face index
    into ``face_rot``/``face_box``, ``h`` (S,) local spacing (sqrt of the cell area), plus the
    per-face ``face_rot`` (F, 3, 3) (columns t1, t2, n; n the outward normal) and ``face_box`` (F,)
    arrays (``face_box`` = primitive index, boxes then cylinders then spheres). A curved surface
    gets one frame per sample.
    """
    rots = scene.rotations()
    pts: list[np.ndarray] = []  # (K, 3) sample points per face / curved primitive
    fids: list[np.ndarray] = []  # (K,) frame index of each sample
    hloc: list[np.ndarray] = []  # (K,) local spacing
    rot_list: list[np.ndarray] = []  # (3, 3) per box face
    owners: list[int] = []  # primitive index per frame
    for i, box in enumerate(scene.boxes):
        for f, (c, fr, half) in enumerate(_face_frames(box, rots[i])):
            if not faces[i, f]:
                continue
            na = max(1, int(np.ceil(2 * half[0] / spacing[i])))
            nb = max(1, int(np.ceil(2 * half[1] / spacing[i])))
            da, db = 2 * half[0] / na, 2 * half[1] / nb
            ia, ib = np.meshgrid(np.arange(na), np.arange(nb), indexing="ij")
            u = -half[0] + (ia.ravel() + rng.random(na * nb)) * da  # (K,) along t1
            v = -half[1] + (ib.ravel() + rng.random(na * nb)) * db  # (K,) along t2
            pts.append(c + u[:, None] * fr[:, 0] + v[:, None] * fr[:, 1])
            fids.append(np.full(na * nb, len(rot_list)))
            hloc.append(np.full(na * nb, np.sqrt(da * db)))
            rot_list.append(fr)
            owners.append(i)
    rot_blocks = [np.asarray(rot_list).reshape(-1, 3, 3)]  # (F, 3, 3) per block: the box faces, then one block per curved primitive
    n_box = len(scene.boxes)
    if len(scene.cylinders) or len(scene.spheres):
        hs = float(np.median(spacing)) if curved_spacing is None else float(curved_spacing)
        for k, (loc, frames, hl, owner) in enumerate(_curved_samples(scene, hs, rng)):
            pts.append(loc)
            fids.append(sum(len(f) for f in rot_blocks) + np.arange(len(loc)))
            hloc.append(hl)
            rot_blocks.append(frames)
            owners.extend([owner] * len(loc))
    p = np.concatenate(pts) if pts else np.zeros((0, 3))
    fid = np.concatenate(fids) if fids else np.zeros(0, int)
    hl = np.concatenate(hloc) if hloc else np.zeros(0)
    face_box = np.asarray(owners, dtype=int)
    face_rot = np.concatenate(rot_blocks) if len(rot_blocks) > 1 else rot_blocks[0]
    # Remove samples buried inside another primitive (contact faces, overlaps, the ground under stones).
    owner = face_box[fid]  # (S,)
    keep = np.ones(len(p), dtype=bool)
    lo, hi = box_aabbs(scene)
    curved = len(scene.cylinders) + len(scene.spheres) > 0
    for i in np.unique(owner):
        sel = np.flatnonzero(owner == i)
        if i < n_box:
            others = np.flatnonzero(np.all(lo <= hi[i] + 1e-9, axis=1) & np.all(hi >= lo[i] - 1e-9, axis=1))
            others = others[others != i]
            if len(others):
                keep[sel] = scene.sdf(p[sel], box_ids=others) >= -1e-9
            if curved:
                keep[sel] &= curved_sdf(p[sel], scene.cylinders, scene.spheres) >= -1e-9
        else:
            j = i - n_box
            nc = len(scene.cylinders)
            cyl = np.delete(scene.cylinders, j, axis=0) if j < nc else scene.cylinders
            sph = np.delete(scene.spheres, j - nc, axis=0) if j >= nc else scene.spheres
            d = np.minimum(scene.sdf(p[sel], box_ids=np.arange(n_box)), curved_sdf(p[sel], cyl, sph))
            keep[sel] = d >= -1e-9
    return {"p": p[keep], "frame": fid[keep], "h": hl[keep], "face_rot": face_rot, "face_box": face_box}


def _curved_areas(scene: AnalyticScene) -> np.ndarray:
    """Surface area per cylinder then per sphere, (C + S,) float64."""
    cyl, sph = scene.cylinders, scene.spheres
    return np.concatenate([2 * np.pi * cyl[:, 3] * (2 * cyl[:, 4] + cyl[:, 3]), 4 * np.pi * sph[:, 3] ** 2])


def _jittered(n_a: int, n_b: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(u, v) in [0, 1)^2: one uniform sample per cell of an n_a x n_b grid (stratified)."""
    ia, ib = np.meshgrid(np.arange(n_a), np.arange(n_b), indexing="ij")
    return (ia.ravel() + rng.random(n_a * n_b)) / n_a, (ib.ravel() + rng.random(n_a * n_b)) / n_b


def _curved_samples(scene: AnalyticScene, h: float, rng: np.random.Generator):
    """Per cylinder, then per sphere: (points (K, 3) world, frames (K, 3, 3) columns t1 t2 n in the
    world frame (n the outward normal, right-handed), local spacing (K,), primitive index).

    Surfaces are parametrised so that equal parameter cells have equal area: a cylinder's side by
    (arc length, height), its caps by a square grid clipped to the disk, a sphere by (longitude,
    height) (Archimedes: area is uniform in height). Every cell gets one jittered sample.
    """
    n_box = len(scene.boxes)
    for ci, cyl in enumerate(scene.cylinders):
        r, hh = cyl[3], cyl[4]
        rot = quat_to_rotmat(cyl[5:9])
        na, nb = max(3, int(np.ceil(2 * np.pi * r / h))), max(1, int(np.ceil(2 * hh / h)))
        u, v = _jittered(na, nb, rng)
        th, z = 2 * np.pi * u, -hh + 2 * hh * v
        ct, st, zero, one = np.cos(th), np.sin(th), np.zeros_like(th), np.ones_like(th)
        side_p = np.stack([r * ct, r * st, z], axis=1)
        side_f = np.stack([np.stack([-st, ct, zero], 1), np.stack([zero, zero, one], 1), np.stack([ct, st, zero], 1)], axis=2)  # (K, 3, 3) columns
        side_h = np.full(len(th), np.sqrt((2 * np.pi * r / na) * (2 * hh / nb)))
        nd = max(1, int(np.ceil(2 * r / h)))
        caps_p, caps_f, caps_h = [], [], []
        for sign in (1.0, -1.0):
            u, v = _jittered(nd, nd, rng)
            x, y = r * (2 * u - 1), r * (2 * v - 1)
            ok = x * x + y * y <= r * r
            x, y = x[ok], y[ok]
            caps_p.append(np.stack([x, y, np.full(len(x), sign * hh)], axis=1))
            fr = np.eye(3) if sign > 0 else np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  # columns (t1, t2, n)
            caps_f.append(np.broadcast_to(fr, (len(x), 3, 3)))
            caps_h.append(np.full(len(x), 2 * r / nd))
        loc = np.concatenate([side_p, *caps_p])
        frames = np.concatenate([side_f, *caps_f])
        yield loc @ rot.T + cyl[:3], np.einsum("ij,kjl->kil", rot, frames), np.concatenate([side_h, *caps_h]), n_box + ci
    for si, sph in enumerate(scene.spheres):
        r = sph[3]
        na, nb = max(3, int(np.ceil(2 * np.pi * r / h))), max(1, int(np.ceil(2 * r / h)))
        u, v = _jittered(na, nb, rng)
        ph, z = 2 * np.pi * u, r * (2 * v - 1)
        rho = np.sqrt(np.maximum(r * r - z * z, 0.0))
        n = np.stack([rho * np.cos(ph), rho * np.sin(ph), z], axis=1) / r
        t1 = np.stack([-np.sin(ph), np.cos(ph), np.zeros_like(ph)], axis=1)
        t2 = np.cross(n, t1)
        frames = np.stack([t1, t2, n], axis=2)
        yield sph[:3] + r * n, frames, np.full(len(ph), np.sqrt((2 * np.pi * r / na) * (2 * r / nb))), n_box + len(scene.cylinders) + si


def _pilot_area(scene: AnalyticScene, n_surf: int, density: np.ndarray, faces: np.ndarray, rng: np.random.Generator) -> float:
    """The exposed surface area (m^2; each box's faces weighted by 1 / density^2, buried parts
    left out), from a pilot sample at 3x the spacing that ``n_surf`` samples of the nominal area would have."""
    curved_area = _curved_areas(scene)  # (C + S,)
    dens_all = np.concatenate([density, np.ones(len(curved_area))]) if len(curved_area) else density  # per primitive
    total = 0.0  # nominal area: every selected face whole, overlaps counted twice
    for i, box in enumerate(scene.boxes):
        h = box[3:6]
        areas = 4 * np.array([h[1] * h[2], h[1] * h[2], h[0] * h[2], h[0] * h[2], h[0] * h[1], h[0] * h[1]])
        total += float((areas * faces[i]).sum()) / density[i] ** 2
    if len(curved_area):
        total += float(curved_area.sum())
    h_pilot = np.sqrt(total / n_surf) * 3.0
    pilot = sample_faces(scene, h_pilot * density, faces, rng, curved_spacing=h_pilot)
    return float(np.sum(pilot["h"] ** 2 / dens_all[pilot["face_box"][pilot["frame"]]] ** 2))


def n_splats_for_spacing(scene: AnalyticScene, spacing: float, config: SurfaceSplatConfig = SurfaceSplatConfig(), seed: int = 0) -> int:
    """The ``n_splats`` for which :func:`splats_from_scene` samples ``scene`` at just under ``spacing``
    (m, its base grid spacing ``info["base_spacing"]``; the median nearest-neighbour distance of
    the splat means comes out ~0.6x that): exposed area / spacing^2 surface splats, plus the
    floaters. A count per area keeps the density, and so everything derived from it, the same on
    large and small scenes."""
    if not (np.isfinite(spacing) and spacing > 0):
        raise SplatplanError(f"splat spacing must be a positive number of metres, got {spacing}")
    m = len(scene.boxes)
    area = _pilot_area(scene, 20_000, np.ones(m), np.ones((m, 6), bool), np.random.default_rng(seed))
    n_surf = area / spacing**2  # the sampler's grid then comes out at 0.95-0.98x spacing
    return max(1, int(np.ceil(n_surf / max(1.0 - config.floater_fraction, 1e-9))))


def _surface_samples(scene: AnalyticScene, n_surf: int, density: np.ndarray, faces: np.ndarray, rng: np.random.Generator):
    """Surface samples (a :func:`sample_faces` dict) at the base spacing that gives at least
    ``n_surf`` of them, and that spacing: a coarse pilot measures the exposed area, then the
    spacing shrinks until there are enough samples."""
    weighted = _pilot_area(scene, n_surf, density, faces, rng)
    h_base = np.sqrt(weighted / n_surf) * 0.98
    for _ in range(5):
        smp = sample_faces(scene, h_base * density, faces, rng, curved_spacing=h_base)
        if len(smp["p"]) >= n_surf:
            break
        h_base *= 0.97 * np.sqrt(len(smp["p"]) / n_surf)
    return smp, h_base


def _floaters(scene: AnalyticScene, cfg: SurfaceSplatConfig, n: int, region, med_size: float, rng: np.random.Generator):
    """``n`` floaters: (means, quats, scales, opacities, colours) rows, in free space at least
    ``cfg.floater_clearance`` from the geometry inside ``region`` (lo, hi) (default the scene
    bounds), sized relative to ``med_size`` (the median largest std of the surface splats)."""
    lo, hi = region if region is not None else scene.bounds()
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    fm = np.zeros((0, 3))
    for _ in range(50):
        cand = rng.uniform(lo, hi, (max(64, 4 * n), 3))
        cand = cand[scene.sdf(cand) > cfg.floater_clearance]
        fm = np.concatenate([fm, cand])[:n]
        if len(fm) == n:
            break
    if len(fm) < n:
        raise SplatplanError("splats_from_scene: no free space for floaters in floater_region")
    big = rng.uniform(*cfg.floater_size_range, n) * med_size
    fs = big[:, None] * np.concatenate([np.ones((n, 1)), rng.uniform(0.3, 1.0, (n, 2))], axis=1)
    fq = rng.standard_normal((n, 4))
    fq /= np.linalg.norm(fq, axis=1, keepdims=True)
    fq *= np.where(fq[:, :1] < 0, -1.0, 1.0)
    transparent = rng.random(n) < cfg.floater_transparent_fraction
    fo = np.where(transparent, rng.uniform(0.01, 0.09, n), rng.uniform(0.1, 0.3, n))
    fc = np.clip(0.8 + 0.1 * rng.standard_normal((n, 3)), 0, 1)
    return fm, fq, fs, fo, fc


def splats_from_scene(
    scene: AnalyticScene,
    n_splats: int,
    *,
    config: SurfaceSplatConfig = SurfaceSplatConfig(),
    colors: np.ndarray | None = None,  # (N, 3) base RGB per primitive (boxes, cylinders, spheres)
    density: np.ndarray | None = None,  # (M,) relative spacing per box (2 = twice the spacing)
    faces: np.ndarray | None = None,  # (M, 6) bool, faces to sample (FACE_NAMES order)
    floater_region: tuple[np.ndarray, np.ndarray] | None = None,
    seed: int | np.random.Generator = 0,
):
    """Sample ~3DGS-like splats on the exposed primitive surfaces (exactly ``n_splats`` of them).

    Box faces, cylinder sides and caps and sphere surfaces are all sampled the same way (a
    stratified grid of equal-area cells, one jittered sample per cell, a local frame whose third
    axis is the outward normal). For a scene of boxes only the output is identical, for the same
    seed, to what this function gave before cylinders and spheres existed (the random draws are the
    same and in the same order); ``splats_from_boxes`` is the same function under its old name.

    Surfaces are sampled on a jittered grid (stratified, so the spacing is even like a trained
    3DGS), buried parts (contact faces, overlaps) are dropped, and each splat gets:

    * local frame = face frame rotated by a random angle about the normal; its **third axis is the
      face normal** (``R[:, 2]``) and carries the smallest std (flat splats);
    * tangential std ``~ tangential_factor * h`` (``h`` = local spacing) with lognormal jitter and
      in-plane anisotropy; normal std ``thickness`` times that;
    * a small position noise along the normal and in the plane;
    * opacity mostly in [0.6, 1], a fraction lower; colour = box colour plus noise.

    The last ``info["n_floaters"]`` splats are floaters: large, mostly transparent (o < 0.1)
    splats in free space, at least ``floater_clearance`` from the geometry.

    Args:
        scene: the primitives.
        n_splats: total number of splats, floaters included.
        config: the look (see :class:`SurfaceSplatConfig`).
        colors: base RGB per primitive in [0, 1] (boxes, cylinders, spheres); default mid grey.
        density: relative spacing per box (1 = the base spacing); default all 1 (cylinders and
            spheres use the base spacing).
        faces: which faces of each box to sample; default all.
        floater_region: (lo, hi) world AABB for floaters; default the scene bounds.
        seed: integer seed or a numpy Generator.

    Returns:
        A :class:`~splatplan.scenes.splats.Splats` (float32, wxyz quats, linear stds).
    """
    if n_splats < 1:
        raise SplatplanError(f"n_splats must be >= 1, got {n_splats}")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    m, n_all = len(scene.boxes), len(scene)
    colors = np.full((n_all, 3), 0.5) if colors is None else np.asarray(colors, np.float64).reshape(n_all, 3)
    density = np.ones(m) if density is None else np.asarray(density, np.float64).reshape(m)
    faces = np.ones((m, 6), bool) if faces is None else np.asarray(faces, bool).reshape(m, 6)
    cfg = config

    n_float = int(round(cfg.floater_fraction * n_splats))
    if cfg.floater_fraction > 0 and n_splats >= 1000:
        n_float = max(1, n_float)
    n_surf = n_splats - n_float

    smp, h_base = _surface_samples(scene, n_surf, density, faces, rng)
    keep = np.sort(rng.choice(len(smp["p"]), size=n_surf, replace=False))
    p, fid, hl = smp["p"][keep], smp["frame"][keep], smp["h"][keep]
    face_rot, face_box = smp["face_rot"], smp["face_box"]
    rot = face_rot[fid]  # (S, 3, 3) columns t1, t2, n
    box_id = face_box[fid]  # (S,)

    # Position noise in the face frame.
    noise = rng.standard_normal((n_surf, 3)) * np.array([cfg.tangential_noise, cfg.tangential_noise, cfg.normal_noise])
    means = p + np.einsum("sij,sj->si", rot, noise * hl[:, None])

    # Scales: (t1, t2, n) in the splat frame.
    def clipped_normal(size: int) -> np.ndarray:  # lognormal factors with the tails cut at 2.5 std
        return np.clip(rng.standard_normal(size), -2.5, 2.5)

    base = cfg.tangential_factor * hl * np.exp(cfg.size_jitter * clipped_normal(n_surf))
    a = cfg.anisotropy * np.clip(rng.standard_normal(n_surf), -2.0, 2.0)
    t_min = base * np.exp(-np.abs(a))
    thick = np.minimum(cfg.thickness * t_min * np.exp(cfg.thickness_jitter * clipped_normal(n_surf)), 0.9 * t_min)
    scales = np.stack([base * np.exp(a), base * np.exp(-a), thick], axis=1)

    # Orientation: face frame, then a random spin about the normal (local z).
    fq = rotmat_to_quat(face_rot)  # (F, 4)
    theta = rng.uniform(0.0, np.pi, n_surf)
    spin = np.stack([np.cos(theta / 2), np.zeros(n_surf), np.zeros(n_surf), np.sin(theta / 2)], axis=1)
    quats = quat_multiply(fq[fid], spin)
    if cfg.tilt_deg > 0:  # tilt the normal about a random in-plane axis (trained splats are not exact)
        phi = np.deg2rad(cfg.tilt_deg) * np.hypot(*rng.standard_normal((2, n_surf)))  # Rayleigh angle
        psi = rng.uniform(0.0, 2 * np.pi, n_surf)
        zero = np.zeros(n_surf)
        tilt = np.stack([np.cos(phi / 2), np.sin(phi / 2) * np.cos(psi), np.sin(phi / 2) * np.sin(psi), zero], axis=1)
        quats = quat_multiply(quats, tilt)
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    quats *= np.where(quats[:, :1] < 0, -1.0, 1.0)

    low = rng.random(n_surf) < cfg.low_opacity_fraction
    opac = np.where(
        low,
        rng.uniform(*cfg.low_opacity_range, n_surf),
        1.0 - (1.0 - cfg.min_high_opacity) * rng.random(n_surf) ** 2,
    )
    cols = np.clip(colors[box_id] + cfg.color_noise * rng.standard_normal((n_surf, 3)), 0.0, 1.0)

    # Floaters.
    if n_float:
        fl = _floaters(scene, cfg, n_float, floater_region, float(np.median(scales.max(axis=1))), rng)
        means, quats, scales, opac, cols = (np.concatenate([a, b]) for a, b in zip((means, quats, scales, opac, cols), fl))

    return Splats(
        means=means,
        quats=quats,
        scales=scales,
        opacities=opac,
        colors=cols,
        source_format="analytic",
        info={
            "n_floaters": int(n_float),  # the last n_floaters splats are the floaters
            "base_spacing": float(h_base),
        },
    )


#: The old name of :func:`splats_from_scene` (box scenes give the same splats as before).
splats_from_boxes = splats_from_scene
