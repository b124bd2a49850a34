"""SplatRenderer: scene data kept on one device, batched cameras, multi-core CPU launches.

    renderer = SplatRenderer(scene, device="cpu")
    res = renderer.render(viewmats, Ks, 64, 64)      # RenderResult, (B, H, W, ...) arrays
    renderer.close()                                  # or use it as a context manager

On CPU a Warp launch runs on one thread, so the camera batch is split into chunks that a thread
pool owned by the renderer runs in parallel, each worker with its own workspace (projected
splats, sort buffers); every chunk runs the whole pipeline of :mod:`.wp_raster` and writes its
own images of the shared output arrays. On CUDA chunks run one after another on the device
(chunk size bounded by the workspace memory), blending one thread per pixel.
"""

from __future__ import annotations

import math
import queue
import threading
from typing import Any

import numpy as np

from .._arrays import array_kind
from .._warp import LazyThreadPool, OwnsThreadPool, cpu_threads, resolve_device
from .._warp import wp as _wp
from ..errors import SplatplanError
from ..scenes.splats import Splats
from .._resources import require_bytes
from .config import MAX_BYTES, TILE, RenderResult, camera_arrays, check_render_args, estimate_bytes, resolve_sh_degree
from .reference import scene_arrays

wp = _wp()

#: Bytes of workspace per projected row (camera x splat) plus per sort pair, for memory estimates.
_ROW_BYTES = 64 + 4 + 4  # Splat2D, ntiles, offsets
_PAIR_BYTES = 2 * (8 + 4) + 64  # keys + values (doubled: the radix sort's scratch half) + gathered Splat2D
#: Rows (camera x splat) of one CUDA chunk at most.
_CUDA_MAX_ROWS = 1 << 24


class _Workspace:
    """Buffers of one worker: projected rows, offsets, sort pairs, tile ranges (grown on demand)."""

    def __init__(self, device: str) -> None:
        self.device = device
        self.rows = 0
        self.pairs = 0
        self.tiles = 0
        # Warp structs and arrays on ``device``, None until first grown
        self.proj: Any = None  # rast.ProjArgs (rows,)
        self.offsets: Any = None  # wp.array(int32) (rows,)
        self.keys: Any = None  # wp.array(int64) (2 * pairs,)
        self.vals: Any = None  # wp.array(int32) (2 * pairs,)
        self.sorted: Any = None  # wp.array(Splat2D) (pairs,)
        self.ranges: Any = None  # wp.array(vec2i) (tiles,)

    def ensure_rows(self, rows: int) -> None:
        if rows <= self.rows:
            return
        d = self.device
        rast = _wp_raster()
        p = rast.ProjArgs()
        p.rows = wp.empty(rows, dtype=rast.Splat2D, device=d)
        p.ntiles = wp.empty(rows, dtype=wp.int32, device=d)
        self.proj = p
        self.offsets = wp.empty(rows, dtype=wp.int32, device=d)
        self.rows = rows

    def ensure_pairs(self, pairs: int) -> None:
        if pairs <= self.pairs:
            return
        cap = max(pairs, int(self.pairs * 1.5), 1024)
        self.keys = wp.empty(2 * cap, dtype=wp.int64, device=self.device)
        self.vals = wp.empty(2 * cap, dtype=wp.int32, device=self.device)
        self.sorted = wp.empty(cap, dtype=_wp_raster().Splat2D, device=self.device)
        self.pairs = cap

    def ensure_tiles(self, tiles: int) -> None:
        if tiles <= self.tiles:
            return
        self.ranges = wp.empty(tiles, dtype=wp.vec2i, device=self.device)
        self.tiles = tiles


def _spread(covs: np.ndarray) -> np.ndarray:
    """(N, 3, 3) float32 covariances -> (N,) float32 upper bounds on the square root of each one's largest
    eigenvalue (the smaller of the trace and the largest absolute row sum, both >= it for a symmetric
    positive semi-definite matrix; rounded up), for the project kernel's EARLY CULL; (1,) when N = 0."""
    if len(covs) == 0:
        return np.zeros(1, np.float32)
    c = covs.astype(np.float64)
    lam = np.minimum(np.trace(c, axis1=1, axis2=2), np.abs(c).sum(axis=2).max(axis=1))
    out = np.sqrt(np.maximum(lam, 0.0)) * (1.0 + 1e-6)
    return np.nextafter(out.astype(np.float32), np.float32(np.inf))


def _wp_raster():
    from . import wp_raster

    return wp_raster


class SplatRenderer(OwnsThreadPool):
    """Render one scene from batches of cameras, repeatedly (scene data stays on the device).

    Args:
        scene: the splats (validated once here).
        device: "auto" (CUDA when Warp sees one, else the CPU; None means the same), "cpu", "cuda" or "cuda:N".
        threads: CPU worker threads (default: every core the process may use).
        blend: "tile" (one thread per tile; the CPU default) or "pixel" (one thread per pixel;
            the CUDA default). Both give the same images.
        max_bytes: cap on the memory one call may take (outputs + workspace); a larger request
            raises :class:`SplatplanError` (default 2 GiB).
    """

    def __init__(
        self,
        scene: Splats,
        device: str | None = "auto",
        *,
        threads: int | None = None,
        blend: str | None = None,
        max_bytes: int = MAX_BYTES,
    ) -> None:
        if not isinstance(scene, Splats):
            raise SplatplanError(f"scene must be a Splats object, got {type(scene).__name__}")
        self.device = resolve_device(device)
        self.is_cuda = self.device.startswith("cuda")
        if blend is None:
            blend = "pixel" if self.is_cuda else "tile"
        if blend not in ("tile", "pixel"):
            raise SplatplanError(f"unknown blend mode {blend!r}: use 'tile' or 'pixel'")
        self.blend = blend
        self.max_bytes = int(max_bytes)
        self.n = len(scene)
        if self.n:
            scene.validate()
        arrs = scene_arrays(scene)
        self.sh_degree = int(arrs["degree"])
        self.sh_k = int(arrs["sh"].shape[1])
        d = self.device
        rast = _wp_raster()
        s = rast.SceneArgs()
        s.means = wp.array(arrs["means"].astype(np.float32), dtype=wp.vec3, device=d)
        covs = arrs["covs"].astype(np.float32)  # (N, 3, 3) as the kernels hold them
        s.covs = wp.array(covs, dtype=wp.mat33, device=d)
        s.opacities = wp.array(arrs["opacities"].astype(np.float32), dtype=wp.float32, device=d)
        s.extent = wp.empty(max(self.n, 1), dtype=wp.float32, device=d)
        if self.n:
            wp.launch(rast.extent_kernel, dim=self.n, inputs=[s.opacities, s.extent], device=d)
        s.spread = wp.array(_spread(covs), dtype=wp.float32, device=d)
        s.colors = wp.array(arrs["colors"].astype(np.float32), dtype=wp.vec3, device=d)
        sh = arrs["sh"].reshape(-1, 3).astype(np.float32) if self.sh_k else np.zeros((1, 3), np.float32)
        s.sh = wp.array(sh, dtype=wp.vec3, device=d)
        s.n = self.n
        s.sh_k = self.sh_k
        s.sh_deg = 0
        self._scene = s
        self._scene_bytes = self.n * (12 + 36 + 4 + 4 + 4 + 12 + 12 * self.sh_k)
        if self.n:
            lo, hi = arrs["means"].min(axis=0), arrs["means"].max(axis=0)
            self._centre, self._radius = 0.5 * (lo + hi), 0.5 * float(np.linalg.norm(hi - lo)) * 1.001 + 1e-6
        else:
            self._centre, self._radius = np.zeros(3), 1.0
        self.threads = 1 if self.is_cuda else max(1, int(threads or cpu_threads()))
        self._pool = LazyThreadPool(self.threads, "splatplan-render")
        self._workspaces: queue.SimpleQueue = queue.SimpleQueue()
        for _ in range(self.threads):
            self._workspaces.put(_Workspace(d))
        self._lock = threading.Lock()
        self._call_out_bytes = 0
        wp.load_module(rast, device=d)  # compile before any worker thread launches

    # ------------------------------------------------------------------ rendering
    def render(
        self, viewmats, Ks, width: int, height: int, *, near: float = 0.01, far: float = 1e10, background=(0.0, 0.0, 0.0), sh_degree: int | None = None
    ) -> RenderResult:
        """Render B cameras; see :func:`splatplan.render` for the conventions and outputs."""
        v, k, width, height, near, far, bg = check_render_args(viewmats, Ks, width, height, near, far, background)
        deg = resolve_sh_degree(sh_degree, self.sh_degree)
        b = v.shape[0]
        out_bytes = estimate_bytes(b, width, height)
        require_bytes(out_bytes, f"the output of {b} image(s) of {width}x{height} (one render call)", "the image size or the cameras per call", limit=self.max_bytes)
        kind = array_kind(viewmats)
        if b == 0:
            return _wrap(np.zeros((0, height, width, 3), np.float32), np.zeros((0, height, width), np.float32),
                         np.zeros((0, height, width), np.float32), kind, self.device)  # fmt: skip
        rast = _wp_raster()
        dev = self.device
        cam = camera_arrays(v, k, width, height)
        ca = rast.CamArgs()
        ca.rot = wp.array(cam["rot"].astype(np.float32), dtype=wp.mat33, device=dev)
        ca.trans = wp.array(cam["trans"].astype(np.float32), dtype=wp.vec3, device=dev)
        ca.campos = wp.array(cam["campos"].astype(np.float32), dtype=wp.vec3, device=dev)
        ca.intr = wp.array(cam["intr"].astype(np.float32), dtype=wp.vec4, device=dev)
        ca.lims = wp.array(cam["lims"].astype(np.float32), dtype=wp.vec4, device=dev)
        fr = rast.FrameArgs()
        fr.width, fr.height = width, height
        fr.tiles_x, fr.tiles_y = math.ceil(width / TILE), math.ceil(height / TILE)
        fr.near, fr.far = near, far  # far already capped at 3e38 by check_planes
        fr.log_near = math.log(near)
        # farthest view depth a splat mean can have, per camera (bounding sphere of the means)
        zmax = np.minimum(np.linalg.norm(cam["campos"] - self._centre, axis=1) + self._radius, fr.far)  # (B,)
        fr.bg = wp.vec3(*bg.astype(np.float32))

        npix = b * height * width
        if self.is_cuda:
            out = rast.OutArgs()
            out.rgb = wp.empty(npix, dtype=wp.vec3, device=dev)
            out.depth = wp.empty(npix, dtype=wp.float32, device=dev)
            out.alpha = wp.empty(npix, dtype=wp.float32, device=dev)
            host = None
        else:
            host = (np.empty((b, height, width, 3), np.float32), np.empty((b, height, width), np.float32),
                    np.empty((b, height, width), np.float32))  # fmt: skip
            out = rast.OutArgs()
            out.rgb = wp.array(host[0].reshape(-1, 3), dtype=wp.vec3, device="cpu", copy=False)
            out.depth = wp.array(host[1].reshape(-1), dtype=wp.float32, device="cpu", copy=False)
            out.alpha = wp.array(host[2].reshape(-1), dtype=wp.float32, device="cpu", copy=False)

        with self._lock:  # one call at a time per renderer (shared workspaces and scene struct)
            scene = self._scene
            scene.sh_deg = deg  # the struct's fields are copied at every launch
            self._call_out_bytes = out_bytes
            chunk = self._chunk_size(b, width, height, out_bytes)
            starts = list(range(0, b, chunk))
            if self.is_cuda or self.threads == 1 or len(starts) == 1:
                for s0 in starts:
                    self._run_chunk(scene, ca, fr, zmax, out, s0, min(chunk, b - s0))
            else:
                pool = self._pool.get()
                from .._warp import wait_all

                wait_all(pool.submit(self._run_chunk, scene, ca, fr, zmax, out, s0, min(chunk, b - s0)) for s0 in starts)
        if host is not None:
            return _wrap(*host, kind, dev)
        return _wrap_device(out, b, height, width, kind)

    def _chunk_size(self, b: int, width: int, height: int, out_bytes: int) -> int:
        """Cameras per chunk: CPU spreads the batch over the workers (one camera per chunk for big
        scenes); CUDA takes as many as the workspace budget allows."""
        n = max(self.n, 1)
        budget = self._workspace_budget()
        per_cam = n * (_ROW_BYTES + 2 * _PAIR_BYTES) + math.ceil(width / TILE) * math.ceil(height / TILE) * 8  # ~2 tiles per splat
        by_mem = max(1, budget // max(per_cam, 1))
        if self.is_cuda:
            return int(max(1, min(b, by_mem, _CUDA_MAX_ROWS // n)))
        # small scenes: a few cameras per chunk to amortise launch overhead; big ones: one each
        per_thread = math.ceil(b / self.threads)
        return int(max(1, min(per_thread, by_mem, max(1, (1 << 16) // n))))

    def _run_chunk(self, scene, cams, frame, zmax, out, cam_base: int, nc: int) -> None:
        ws: _Workspace = self._workspaces.get()
        try:
            self._run_range(ws, scene, cams, frame, zmax, out, cam_base, nc)
        finally:
            self._workspaces.put(ws)

    def _run_range(self, ws: "_Workspace", scene, cams, frame, zmax, out, cam_base: int, nc: int) -> None:
        """The whole pipeline for cameras cam_base .. cam_base + nc - 1 in one workspace.

        zmax (B,): per camera, the farthest view depth a splat mean can have (sets the depth-key range).
        """
        rast = _wp_raster()
        dev = self.device
        n = self.n
        rows = nc * n
        tiles = nc * frame.tiles_x * frame.tiles_y
        m = 0
        tile_bits = max(1, int(tiles - 1).bit_length())
        depth_bits = 32 - tile_bits if tile_bits <= 12 else 32  # keys of <= 32 bits: two 16-bit sort passes
        key_max = float(2**depth_bits - 1)
        zfar = float(zmax[cam_base : cam_base + nc].max())
        key_scale = key_max / max(math.log(max(zfar, frame.near * 1.0001)) - frame.log_near, 1e-12)
        if rows:
            ws.ensure_rows(rows)
            proj = ws.proj
            wp.launch(rast.project_kernel, dim=rows, inputs=[scene, cams, cam_base, frame, key_scale, key_max, proj], device=dev)
            wp.utils.array_scan(proj.ntiles[:rows], ws.offsets[:rows], inclusive=True)
            m = int(ws.offsets[rows - 1 : rows].numpy()[0])
        if m:
            budget = self._workspace_budget()
            need = m * _PAIR_BYTES + rows * _ROW_BYTES
            if need > budget:
                if nc > 1:  # more tile slots than estimated: split the chunk (re-projects; rare)
                    half = nc // 2
                    self._run_range(ws, scene, cams, frame, zmax, out, cam_base, half)
                    self._run_range(ws, scene, cams, frame, zmax, out, cam_base + half, nc - half)
                    return
                require_bytes(need, f"the workspace of one {frame.width}x{frame.height} image ({m:,} splat-tile pairs)", "the image size", limit=budget)
            ws.ensure_pairs(m)
            ws.ensure_tiles(tiles)
            ws.ranges.zero_()  # empty tiles must read [0, 0)
            wp.launch(rast.write_keys_kernel, dim=rows, inputs=[proj, n, frame, depth_bits, ws.offsets, ws.keys, ws.vals], device=dev)
            wp.utils.radix_sort_pairs(ws.keys, ws.vals, m, 0, depth_bits + tile_bits)
            wp.launch(rast.tile_ranges_kernel, dim=m, inputs=[ws.keys, m, depth_bits, ws.ranges], device=dev)
            wp.launch(rast.gather_kernel, dim=m, inputs=[ws.proj, ws.vals, ws.sorted], device=dev)
        else:
            ws.ensure_pairs(1)
            ws.ensure_tiles(tiles)
            ws.ranges.zero_()
        if self.blend == "tile":
            wp.launch(rast.blend_tile_kernel, dim=tiles, inputs=[ws.sorted, ws.ranges, frame, cam_base, out], device=dev)
        else:
            wp.launch(rast.blend_pixel_kernel, dim=tiles * TILE * TILE, inputs=[ws.sorted, ws.ranges, frame, cam_base, out], device=dev)

    def _workspace_budget(self) -> int:
        """Bytes one worker's workspace may take in the current call (set by render())."""
        return max(self.max_bytes - self._call_out_bytes - self._scene_bytes, 0) // self.threads


def _wrap(rgb: np.ndarray, depth: np.ndarray, alpha: np.ndarray, kind: str, device: str) -> RenderResult:
    if kind == "torch":
        import torch

        return RenderResult(torch.from_numpy(rgb), torch.from_numpy(depth), torch.from_numpy(alpha))
    if kind == "warp":
        return RenderResult(
            wp.array(rgb, dtype=wp.vec3, device="cpu"),
            wp.array(depth, dtype=wp.float32, device="cpu"),
            wp.array(alpha, dtype=wp.float32, device="cpu"),
        )
    return RenderResult(rgb, depth, alpha)


def _wrap_device(out, b: int, h: int, w: int, kind: str) -> RenderResult:
    rgb = out.rgb.reshape((b, h, w))
    if kind == "torch":
        return RenderResult(
            wp.to_torch(out.rgb).reshape(b, h, w, 3), wp.to_torch(out.depth).reshape(b, h, w), wp.to_torch(out.alpha).reshape(b, h, w)
        )
    if kind == "warp":
        return RenderResult(rgb, out.depth.reshape((b, h, w)), out.alpha.reshape((b, h, w)))
    return RenderResult(out.rgb.numpy().reshape(b, h, w, 3), out.depth.numpy().reshape(b, h, w), out.alpha.numpy().reshape(b, h, w))
