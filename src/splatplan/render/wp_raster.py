"""Warp kernels of the tile rasteriser: project, tile-bin (count, prefix sum, write keys), sort,
tile ranges and alpha blending. Glue (buffers, launches, threads) lives in :mod:`.renderer`;
the numpy reference is :mod:`.reference`; constants and conventions are in :mod:`.config`.

Pipeline for a chunk of C cameras (rows r = c * N + i, splat i seen by camera c):

1. ``project_kernel`` (C*N): view transform, near/far cull, EWA 2D covariance + low-pass,
   conic, SH colour, opacity-aware pixel bounding box, number of 16x16 tiles it touches.
2. prefix sum of the tile counts (``wp.utils.array_scan``) -> offsets, M pairs in all.
3. ``write_keys_kernel`` (C*N): one (key, row) pair per touched tile; key = (c * T + tile) <<
   depth_bits | depth key, the depth key a monotone quantisation of log(z) over [near, the
   farthest a splat mean can be] in depth_bits = 32 - tile bits (>= 20; else 32) bits, so that
   the sort needs two 16-bit passes for up to 4096 tiles.
4. ``wp.utils.radix_sort_pairs`` over the used bits -> pairs grouped by tile, front to back.
5. ``tile_ranges_kernel`` (M): [start, end) of each tile's run of pairs.
6. ``gather_kernel`` (M): copy each pair's projected splat into pair order, so blending streams
   through memory instead of gathering (3x faster blending on CPU).
7. blending: ``blend_tile_kernel`` (one thread per tile, splat-outer loop over the splat's
   pixels inside the tile; the CPU kernel: each splat visits only the ~10 pixels it covers) or
   ``blend_pixel_kernel`` (one thread per pixel; the CUDA kernel). Both give the same result.

EARLY CULL (project_kernel): before the 2D covariance, a splat whose footprint bound stays off the
image is dropped. With lam >= the largest eigenvalue of its 3D covariance (``SceneArgs.spread``
squared), the 2D variance along x, m0^T Sigma m0 + LOW_PASS, is at most (j00^2 + j02^2) lam' +
LOW_PASS with lam' = 1.004 lam: m0 = j00 W[0] + j02 W[2] has |m0|^2 <= (j00^2 + j02^2)(1 + 2e-3) for
rows of W orthonormal to the 1e-3 that the camera check allows (the rest of the pad covers float32
rounding); likewise along y. The bounding box from these bounds contains the exact one, so a splat
dropped here would have been dropped by the exact box: the images are unchanged, and most
off-screen splats skip the covariance.

Exactness of the bounding box: alpha = o exp(-q/2) >= ALPHA_MIN iff q <= k^2 with
k^2 = 2 ln(o / ALPHA_MIN); the ellipse {q <= k^2} lies inside |dx| <= k sqrt(S_xx),
|dy| <= k sqrt(S_yy) (S the 2D covariance). So binning drops only pixels the blending would skip.
"""

from __future__ import annotations

from .._warp import wp as _wp
from .config import ALPHA_MAX, ALPHA_MIN, LOW_PASS, SH_C1, SH_C2, SH_C3, T_MIN, TILE

wp = _wp()
wp.set_module_options({"enable_backward": False})  # forward only: halves the compile time

_TILE = wp.constant(TILE)
_LOW_PASS = wp.constant(LOW_PASS)
_ALPHA_MAX = wp.constant(ALPHA_MAX)
_ALPHA_MIN = wp.constant(ALPHA_MIN)
_T_MIN = wp.constant(T_MIN)
_C1 = wp.constant(SH_C1)
_C20, _C21, _C22, _C23, _C24 = (wp.constant(c) for c in SH_C2)
_C30, _C31, _C32, _C33, _C34, _C35, _C36 = (wp.constant(c) for c in SH_C3)


@wp.struct
class SceneArgs:
    """Splat data on the device (world frame)."""

    means: wp.array(dtype=wp.vec3)  # (N,) centres
    covs: wp.array(dtype=wp.mat33)  # (N,) covariances R diag(s^2) R^T (disks thickened)
    opacities: wp.array(dtype=wp.float32)  # (N,) in [0, 1]
    extent: wp.array(dtype=wp.float32)  # (N,) k = sqrt(2 ln(o / ALPHA_MIN)): alpha >= ALPHA_MIN only within q <= k^2 (0 below ALPHA_MIN)
    spread: wp.array(dtype=wp.float32)  # (N,) >= sqrt(largest eigenvalue of the covariance) (EARLY CULL)
    colors: wp.array(dtype=wp.vec3)  # (N,) SH band 0 + 0.5
    sh: wp.array(dtype=wp.vec3)  # (N * sh_k,) higher SH coefficients, row-major per splat
    n: int  # N
    sh_k: int  # coefficients stored per splat (0, 3, 8 or 15)
    sh_deg: int  # degree evaluated (0..3)


@wp.struct
class CamArgs:
    """A batch of B cameras (indexed by cam_base + c)."""

    rot: wp.array(dtype=wp.mat33)  # (B,) world -> camera rotation
    trans: wp.array(dtype=wp.vec3)  # (B,) world -> camera translation
    campos: wp.array(dtype=wp.vec3)  # (B,) camera centres, world
    intr: wp.array(dtype=wp.vec4)  # (B,) fx, fy, cx, cy (pixels)
    lims: wp.array(dtype=wp.vec4)  # (B,) guard-band limits of x/z, y/z: neg x, pos x, neg y, pos y


@wp.struct
class FrameArgs:
    width: int
    height: int
    tiles_x: int
    tiles_y: int
    near: float
    far: float
    log_near: wp.float64  # ln(near)
    bg: wp.vec3


@wp.struct
class Splat2D:
    """One projected splat (64 bytes: one cache line per sort pair read by the blending)."""

    xy: wp.vec2  # mean in pixels
    conic: wp.vec3  # inverse 2D covariance (xx, xy, yy), 1/px^2
    opac: float  # opacity
    rgb: wp.vec3  # colour at the viewing direction
    depth: float  # view depth z of the mean
    rect: wp.vec4i  # inclusive pixel box x0, y0, x1, y1
    dkey: wp.int64  # depth sort key (depth_bits wide)


@wp.struct
class ProjArgs:
    """Projected splats, one row per (camera of the chunk, splat)."""

    rows: wp.array(dtype=Splat2D)  # (R,)
    ntiles: wp.array(dtype=wp.int32)  # (R,) tiles touched (0 = culled)


@wp.struct
class OutArgs:
    """Images of the whole batch, flat (B * H * W,) rows (camera, row, column)."""

    rgb: wp.array(dtype=wp.vec3)
    depth: wp.array(dtype=wp.float32)
    alpha: wp.array(dtype=wp.float32)


@wp.func
def sh_color(scene: SceneArgs, i: int, d: wp.vec3) -> wp.vec3:
    """Colour of splat i at unit direction d (INRIA basis), clamped at 0."""
    c = scene.colors[i]
    deg = scene.sh_deg
    if deg >= 1:
        base = i * scene.sh_k
        x = d[0]
        y = d[1]
        z = d[2]
        c = c + _C1 * (-y * scene.sh[base] + z * scene.sh[base + 1] - x * scene.sh[base + 2])
        if deg >= 2:
            xx = x * x
            yy = y * y
            zz = z * z
            xy = x * y
            yz = y * z
            xz = x * z
            c = c + (_C20 * xy) * scene.sh[base + 3] + (_C21 * yz) * scene.sh[base + 4]
            c = c + (_C22 * (2.0 * zz - xx - yy)) * scene.sh[base + 5] + (_C23 * xz) * scene.sh[base + 6]
            c = c + (_C24 * (xx - yy)) * scene.sh[base + 7]
            if deg >= 3:
                c = c + (_C30 * y * (3.0 * xx - yy)) * scene.sh[base + 8] + (_C31 * xy * z) * scene.sh[base + 9]
                c = c + (_C32 * y * (4.0 * zz - xx - yy)) * scene.sh[base + 10]
                c = c + (_C33 * z * (2.0 * zz - 3.0 * xx - 3.0 * yy)) * scene.sh[base + 11]
                c = c + (_C34 * x * (4.0 * zz - xx - yy)) * scene.sh[base + 12] + (_C35 * z * (xx - yy)) * scene.sh[base + 13]
                c = c + (_C36 * x * (xx - 3.0 * yy)) * scene.sh[base + 14]
    return wp.vec3(wp.max(c[0], 0.0), wp.max(c[1], 0.0), wp.max(c[2], 0.0))


@wp.kernel
def extent_kernel(opacities: wp.array(dtype=wp.float32), extent: wp.array(dtype=wp.float32)):
    """extent[i] = sqrt(2 ln(o_i / ALPHA_MIN)) (0 below ALPHA_MIN: such splats are never drawn)."""
    i = wp.tid()
    o = opacities[i]
    k = float(0.0)
    if o >= _ALPHA_MIN:
        k = wp.sqrt(2.0 * wp.log(o / _ALPHA_MIN))
    extent[i] = k


@wp.kernel
def project_kernel(
    scene: SceneArgs, cams: CamArgs, cam_base: int, frame: FrameArgs,
    key_scale: wp.float64, key_max: wp.float64, proj: ProjArgs,
):  # fmt: skip
    row = wp.tid()
    c = row // scene.n
    i = row - c * scene.n
    b = cam_base + c
    proj.ntiles[row] = 0
    o = scene.opacities[i]
    if o < _ALPHA_MIN:
        return
    rot = cams.rot[b]
    p = rot * scene.means[i] + cams.trans[b]  # camera frame
    z = p[2]
    if z < frame.near or z > frame.far:
        return
    intr = cams.intr[b]
    lims = cams.lims[b]
    fx = intr[0]
    fy = intr[1]
    inv_z = 1.0 / z
    tx = wp.clamp(p[0] * inv_z, -lims[0], lims[1]) * z
    ty = wp.clamp(p[1] * inv_z, -lims[2], lims[3]) * z
    j00 = fx * inv_z
    j02 = -fx * tx * inv_z * inv_z
    j11 = fy * inv_z
    j12 = -fy * ty * inv_z * inv_z
    u = fx * p[0] * inv_z + intr[2]
    v = fy * p[1] * inv_z + intr[3]
    kk = scene.extent[i]
    # EARLY CULL: the 2D variances below are at most (j00^2 + j02^2) lam_max + LOW_PASS (resp. j11, j12):
    # a footprint that stays off the image with these bounds does so with the exact ones
    lam = scene.spread[i] * scene.spread[i] * 1.004  # (pad: rows of W orthonormal to 1e-3, float32 rounding)
    rxb = kk * wp.sqrt((j00 * j00 + j02 * j02) * lam + _LOW_PASS)
    ryb = kk * wp.sqrt((j11 * j11 + j12 * j12) * lam + _LOW_PASS)
    if wp.ceil(u - rxb - 0.5) > float(frame.width - 1) or wp.floor(u + rxb - 0.5) < 0.0:
        return
    if wp.ceil(v - ryb - 0.5) > float(frame.height - 1) or wp.floor(v + ryb - 0.5) < 0.0:
        return
    # 2D covariance (J W) Sigma (J W)^T + low-pass, J = [[j00, 0, j02], [0, j11, j12]], W = rot:
    # rows of J W are m0 = j00 W[0] + j02 W[2] and m1 = j11 W[1] + j12 W[2] (world frame)
    m0 = j00 * wp.vec3(rot[0, 0], rot[0, 1], rot[0, 2]) + j02 * wp.vec3(rot[2, 0], rot[2, 1], rot[2, 2])
    m1 = j11 * wp.vec3(rot[1, 0], rot[1, 1], rot[1, 2]) + j12 * wp.vec3(rot[2, 0], rot[2, 1], rot[2, 2])
    cov = scene.covs[i]
    s0 = cov * m0
    a = wp.dot(m0, s0) + _LOW_PASS
    bb = wp.dot(m1, s0)
    d = wp.dot(m1, cov * m1) + _LOW_PASS
    det = a * d - bb * bb
    if not (det > 0.0) or not wp.isfinite(det):  # also NaN / overflow from absurd scales
        return
    inv_det = 1.0 / det
    # opacity-aware extent (kk): alpha >= ALPHA_MIN only where q <= kk^2
    rx = kk * wp.sqrt(a)
    ry = kk * wp.sqrt(d)
    # pixel centres px + 0.5 within [u - rx, u + rx]
    fx0 = wp.max(wp.ceil(u - rx - 0.5), 0.0)
    fx1 = wp.min(wp.floor(u + rx - 0.5), float(frame.width - 1))
    fy0 = wp.max(wp.ceil(v - ry - 0.5), 0.0)
    fy1 = wp.min(wp.floor(v + ry - 0.5), float(frame.height - 1))
    if fx0 > fx1 or fy0 > fy1:
        return
    x0 = int(fx0)
    x1 = int(fx1)
    y0 = int(fy0)
    y1 = int(fy1)
    sp = Splat2D()
    sp.xy = wp.vec2(u, v)
    sp.conic = wp.vec3(d * inv_det, -bb * inv_det, a * inv_det)
    sp.opac = o
    sp.depth = z
    lz = (wp.log(wp.float64(z)) - frame.log_near) * key_scale  # monotone in z
    sp.dkey = wp.int64(wp.clamp(lz, wp.float64(0.0), key_max))
    if scene.sh_deg > 0:
        dirv = scene.means[i] - cams.campos[b]
        nd = wp.length(dirv)
        if nd > 0.0:
            dirv = dirv / nd
        sp.rgb = sh_color(scene, i, dirv)
    else:
        c0 = scene.colors[i]
        sp.rgb = wp.vec3(wp.max(c0[0], 0.0), wp.max(c0[1], 0.0), wp.max(c0[2], 0.0))
    sp.rect = wp.vec4i(x0, y0, x1, y1)
    proj.rows[row] = sp
    proj.ntiles[row] = (x1 / _TILE - x0 / _TILE + 1) * (y1 / _TILE - y0 / _TILE + 1)


@wp.kernel
def write_keys_kernel(
    proj: ProjArgs, n: int, frame: FrameArgs, depth_bits: int, offsets: wp.array(dtype=wp.int32),
    keys: wp.array(dtype=wp.int64), vals: wp.array(dtype=wp.int32),
):  # fmt: skip
    row = wp.tid()
    nt = proj.ntiles[row]
    if nt == 0:
        return
    k = offsets[row] - nt  # offsets is the inclusive scan
    c = row // n
    sp = proj.rows[row]
    r = sp.rect
    dk = sp.dkey
    tpi = frame.tiles_x * frame.tiles_y
    for ty in range(r[1] / _TILE, r[3] / _TILE + 1):
        for tx in range(r[0] / _TILE, r[2] / _TILE + 1):
            tile = c * tpi + ty * frame.tiles_x + tx
            keys[k] = (wp.int64(tile) << wp.int64(depth_bits)) | dk
            vals[k] = row
            k += 1


@wp.kernel
def tile_ranges_kernel(keys: wp.array(dtype=wp.int64), m: int, depth_bits: int, ranges: wp.array(dtype=wp.vec2i)):
    """ranges[tile] = [start, end) of the tile's pairs; ranges must be zeroed before."""
    k = wp.tid()
    tile = int(keys[k] >> wp.int64(depth_bits))
    if k == 0:
        ranges[tile] = wp.vec2i(k, ranges[tile][1])
    else:
        prev = int(keys[k - 1] >> wp.int64(depth_bits))
        if prev != tile:
            ranges[tile] = wp.vec2i(k, ranges[tile][1])
    if k == m - 1:
        ranges[tile] = wp.vec2i(ranges[tile][0], k + 1)
    else:
        nxt = int(keys[k + 1] >> wp.int64(depth_bits))
        if nxt != tile:
            ranges[tile] = wp.vec2i(ranges[tile][0], k + 1)


@wp.kernel
def gather_kernel(proj: ProjArgs, vals: wp.array(dtype=wp.int32), sorted_rows: wp.array(dtype=Splat2D)):
    """sorted_rows[k] = the projected splat of pair k: the blending then streams through memory."""
    k = wp.tid()
    sorted_rows[k] = proj.rows[vals[k]]


@wp.func
def splat_power(xy: wp.vec2, conic: wp.vec3, px: float, py: float) -> float:
    dx = px - xy[0]
    dy = py - xy[1]
    return -0.5 * (conic[0] * dx * dx + conic[2] * dy * dy) - conic[1] * dx * dy


@wp.kernel
def blend_tile_kernel(
    pairs: wp.array(dtype=Splat2D), ranges: wp.array(dtype=wp.vec2i),
    frame: FrameArgs, cam_base: int, out: OutArgs,
):  # fmt: skip
    """One thread per tile; splats in front-to-back order, each visiting only its pixels in the tile.

    During blending out.alpha holds the transmittance T of each pixel, negated once the pixel
    is done (T < T_MIN would be reached); the last loop turns it into alpha = 1 - T.
    """
    t = wp.tid()
    tpi = frame.tiles_x * frame.tiles_y
    c = t / tpi
    tl = t - c * tpi
    ty = tl / frame.tiles_x
    tx = tl - ty * frame.tiles_x
    x0 = tx * _TILE
    y0 = ty * _TILE
    x1 = wp.min(x0 + _TILE, frame.width) - 1
    y1 = wp.min(y0 + _TILE, frame.height) - 1
    img = (cam_base + c) * frame.height * frame.width
    npix = (x1 - x0 + 1) * (y1 - y0 + 1)
    for py in range(y0, y1 + 1):
        for px in range(x0, x1 + 1):
            pix = img + py * frame.width + px
            out.alpha[pix] = 1.0
            out.rgb[pix] = wp.vec3(0.0)
            out.depth[pix] = 0.0
    r = ranges[t]
    ndone = int(0)
    for k in range(r[0], r[1]):
        if ndone == npix:
            break
        sp = pairs[k]
        rect = sp.rect
        xy = sp.xy
        conic = sp.conic
        o = sp.opac
        col = sp.rgb
        z = sp.depth
        for py in range(wp.max(rect[1], y0), wp.min(rect[3], y1) + 1):
            for px in range(wp.max(rect[0], x0), wp.min(rect[2], x1) + 1):
                pix = img + py * frame.width + px
                tr = out.alpha[pix]
                if tr < 0.0:
                    continue
                power = splat_power(xy, conic, float(px) + 0.5, float(py) + 0.5)
                if power > 0.0:
                    continue
                alpha = wp.min(_ALPHA_MAX, o * wp.exp(power))
                if alpha < _ALPHA_MIN:
                    continue
                nt = tr * (1.0 - alpha)
                if nt < _T_MIN:
                    out.alpha[pix] = -tr
                    ndone += 1
                    continue
                w = alpha * tr
                out.rgb[pix] = out.rgb[pix] + w * col
                out.depth[pix] = out.depth[pix] + w * z
                out.alpha[pix] = nt
    for py in range(y0, y1 + 1):
        for px in range(x0, x1 + 1):
            pix = img + py * frame.width + px
            tr = wp.abs(out.alpha[pix])
            acc = 1.0 - tr
            out.alpha[pix] = acc
            out.rgb[pix] = out.rgb[pix] + tr * frame.bg
            if acc > 0.0:
                out.depth[pix] = out.depth[pix] / acc
            else:
                out.depth[pix] = 0.0


@wp.kernel
def blend_pixel_kernel(
    pairs: wp.array(dtype=Splat2D), ranges: wp.array(dtype=wp.vec2i),
    frame: FrameArgs, cam_base: int, out: OutArgs,
):  # fmt: skip
    """One thread per pixel (threads ordered tile by tile); same maths as blend_tile_kernel."""
    tid = wp.tid()
    tpi = frame.tiles_x * frame.tiles_y
    t = tid / (_TILE * _TILE)
    local = tid - t * (_TILE * _TILE)
    c = t / tpi
    tl = t - c * tpi
    ty = tl / frame.tiles_x
    tx = tl - ty * frame.tiles_x
    px = tx * _TILE + local % _TILE
    py = ty * _TILE + local / _TILE
    if px >= frame.width or py >= frame.height:
        return
    pxf = float(px) + 0.5
    pyf = float(py) + 0.5
    r = ranges[t]
    tr = float(1.0)
    rgb = wp.vec3(0.0)
    dacc = float(0.0)
    for k in range(r[0], r[1]):
        sp = pairs[k]
        power = splat_power(sp.xy, sp.conic, pxf, pyf)
        if power > 0.0:
            continue
        alpha = wp.min(_ALPHA_MAX, sp.opac * wp.exp(power))
        if alpha < _ALPHA_MIN:
            continue
        nt = tr * (1.0 - alpha)
        if nt < _T_MIN:
            break
        w = alpha * tr
        rgb = rgb + w * sp.rgb
        dacc = dacc + w * sp.depth
        tr = nt
    pix = ((cam_base + c) * frame.height + py) * frame.width + px
    acc = 1.0 - tr
    out.alpha[pix] = acc
    out.rgb[pix] = rgb + tr * frame.bg
    if acc > 0.0:
        out.depth[pix] = dacc / acc
    else:
        out.depth[pix] = 0.0
