"""Query inputs and outputs of the metric on any array type: numpy, torch (CPU or CUDA) or ``wp.array``.

The *kind* of a call is the type of its ``centers`` (or ``q`` for robot queries):

- numpy (or anything ``np.asarray`` takes): the thin host adapter. Validated on the host as it
  always was (shapes, NaN/Inf, zero quaternions, semi-axes > 0: one-line ``SplatplanError``s),
  converted to float32 and copied to the checker's device; results come back as numpy arrays.
- torch tensors and ``wp.array``s: device inputs. Zero-copy (``wp.from_torch``) when float32 and
  contiguous (float64 torch tensors are converted on their device). Host work is O(1): shapes,
  dtypes and devices only; non-finite values are caught *on the device* (the query reads
  in_collision = True with NaN distances) and raise only with ``validate=True`` (one sync).
  Results are tensors / ``wp.array``s of the input's type on its device.

Rotations and semi-axes whose leading shape is a suffix of the batch shape (e.g. per-link
(E, 3) semi-axes for a (K, T, E) batch) are not expanded: the kernel reads row ``q % period``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .._arrays import array_kind, host_array
from .._warp import wp as _wp
from ..errors import SplatplanError

if TYPE_CHECKING:
    import warp as wp

# Warp is loaded on first use, not on import (``import splatplan.metric`` stays light).


def _wdt(tail: tuple[int, ...]):
    """Warp dtype of one row with trailing shape ``tail``: (3,) vec3, (4,) vec4, (3, 3) mat33."""
    wp = _wp()
    return {(3,): wp.vec3, (4,): wp.vec4, (3, 3): wp.mat33}[tuple(tail)]


def torch_device_name(t) -> str:
    d = t.device
    return "cpu" if d.type == "cpu" else f"cuda:{d.index if d.index is not None else 0}"


def warp_device_name(a) -> str:
    return "cpu" if a.device.is_cpu else str(a.device)


def check_device(name: str, dev: str, want: str) -> None:
    if dev != want:
        raise SplatplanError(
            f"{name} is on {dev} but the checker runs on {want}: move them there or create the checker with device={dev!r}"
        )


def _period(lead: tuple[int, ...], shape: tuple[int, ...]) -> int | None:
    """Rows of an array with leading shape ``lead`` when it broadcasts to ``shape`` by tiling, else None."""
    lead = tuple(lead)
    while lead and lead[0] == 1:
        lead = lead[1:]
    if len(lead) > len(shape) or (lead and tuple(shape[len(shape) - len(lead) :]) != lead):
        return None
    return int(np.prod(lead, dtype=np.int64)) if lead else 1


# ---------------------------------------------------------------------------------------- host inputs


@dataclass
class HostArrays:
    """A validated host batch: centres (B, 3) and compact rotations / semi-axes with their periods."""

    shape: tuple[int, ...]
    centers: np.ndarray  # (B, 3) float64
    quats: np.ndarray | None  # (P, 4) unit wxyz, or None
    rots: np.ndarray | None  # (P, 3, 3) world <- link, or None
    rot_period: int
    axes: np.ndarray  # (P_a, 3) float64 > 0
    axes_period: int


def as_host_queries(centers, quats, semi_axes, rots=None) -> HostArrays:
    """Validate and flatten a host query batch (today's checks and messages)."""
    c = _to_numpy(centers)
    if c.ndim < 1 or c.shape[-1] != 3:
        raise SplatplanError(f"centers must have shape (..., 3), got {c.shape}")
    shape = c.shape[:-1]
    c = c.reshape(-1, 3)
    if not np.all(np.isfinite(c)):
        raise SplatplanError("centers contain NaN or Inf")
    if quats is not None and rots is not None:
        raise SplatplanError("give link orientations as quats or as rots, not both")
    q = r = None
    rp = 1
    if quats is not None:
        q = _to_numpy(quats)
        if q.shape[-1] != 4:
            raise SplatplanError(f"quats must have shape (..., 4) (wxyz), got {q.shape}")
        q, rp = _compact(q, shape, 1, "quats")
        if not np.all(np.isfinite(q)):
            raise SplatplanError("quats contain NaN or Inf")
        n = np.linalg.norm(q, axis=1, keepdims=True)
        if np.any(n < 1e-8):
            raise SplatplanError("quats contain a zero quaternion")
        q = q / n
    if rots is not None:
        r = _to_numpy(rots)
        if r.ndim < 2 or r.shape[-2:] != (3, 3):
            raise SplatplanError(f"rots must have shape (..., 3, 3) (world <- link rotation matrices), got {r.shape}")
        r, rp = _compact(r, shape, 2, "rots")
        if not np.all(np.isfinite(r)):
            raise SplatplanError("rots contain NaN or Inf")
    a = _to_numpy(semi_axes)
    if a.ndim == 0:
        a = np.full(3, float(a))
    if a.shape[-1] != 3:
        raise SplatplanError(f"semi_axes must have shape (3,) or (..., 3), got {a.shape}")
    a, ap = _compact(a, shape, 1, "semi_axes")
    if not np.all(np.isfinite(a)) or np.any(a <= 0):
        raise SplatplanError("semi_axes must be finite and > 0")
    return HostArrays(shape, c, q, r, rp, a, ap)


def _compact(x: np.ndarray, shape: tuple[int, ...], tail: int, name: str) -> tuple[np.ndarray, int]:
    """(rows, period): x reshaped to (P, *tail) when it tiles the batch, else broadcast to (B, *tail)."""
    lead, tl = x.shape[: x.ndim - tail], x.shape[x.ndim - tail :]
    p = _period(lead, shape)
    if p is not None:
        return x.reshape((p,) + tl), p
    try:
        full = np.broadcast_to(x, tuple(shape) + tl)
    except ValueError as exc:
        raise SplatplanError(f"{name} shape {x.shape} does not broadcast to the batch {tuple(shape)}") from exc
    b = int(np.prod(shape, dtype=np.int64))
    return full.reshape((b,) + tl), max(b, 1)


def _to_numpy(x) -> np.ndarray:
    return np.asarray(host_array(x), dtype=np.float64)


def axes_medians(axes: np.ndarray) -> tuple[float, float]:
    """(median smallest, median largest) semi-axis over rows (B, 3): sizes the hash grids."""
    return float(np.median(axes.min(1))), float(np.median(axes.max(1)))


def host_link_batch(h: HostArrays, device: str, axes_dev=None) -> tuple:
    """A :class:`LinkBatch` on ``device`` from validated host arrays; returns (batch, arrays to keep alive)."""
    from .wp_metric_kernel import LinkBatch

    wp = _wp()
    lb = LinkBatch()
    lb.centers = wp.array(np.ascontiguousarray(h.centers, dtype=np.float32), dtype=wp.vec3, device=device)
    lb.axes = axes_dev if axes_dev is not None else wp.array(np.ascontiguousarray(h.axes, dtype=np.float32), dtype=wp.vec3, device=device)
    lb.axes_period = int(h.axes_period)
    lb.use_order = 0
    lb.rot_period = int(h.rot_period)
    lb.rot_mode = 0
    if h.quats is not None:
        lb.quats = wp.array(np.ascontiguousarray(h.quats, dtype=np.float32), dtype=wp.vec4, device=device)
        lb.rot_mode = 1
    elif h.rots is not None:
        lb.rots = wp.array(np.ascontiguousarray(h.rots, dtype=np.float32), dtype=wp.mat33, device=device)
        lb.rot_mode = 2
    return lb, [lb.centers, lb.axes, lb.quats, lb.rots]


# ---------------------------------------------------------------------------------------- device inputs


def device_rows(x, kind: str, name: str, tail: tuple[int, ...], device: str):
    """(wp.array of P rows of dtype vec3/vec4/mat33, leading shape) from a torch tensor or wp.array: O(1) host work."""
    wp = _wp()
    wdt = _wdt(tail)
    if kind == "torch":
        import torch

        check_device(name, torch_device_name(x), device)
        if x.dtype not in (torch.float32, torch.float64, torch.float16, torch.bfloat16):
            raise SplatplanError(f"{name} must be a floating-point tensor, got {x.dtype}")
        if tuple(x.shape[x.ndim - len(tail) :]) != tail or x.ndim < len(tail):
            raise SplatplanError(f"{name} must have shape (..., {', '.join(map(str, tail))}), got {tuple(x.shape)}")
        lead = tuple(x.shape[: x.ndim - len(tail)])
        t = x.detach().to(torch.float32).contiguous().reshape((-1,) + tail)
        return wp.from_torch(t, dtype=wdt), lead, t
    if kind == "warp":
        check_device(name, warp_device_name(x), device)
        if x.dtype == wdt:
            lead = tuple(x.shape)
            arr = x
        elif x.dtype == wp.float32 and tuple(x.shape[x.ndim - len(tail) :]) == tail and x.ndim >= len(tail):
            lead = tuple(x.shape[: x.ndim - len(tail)])
            arr = x
        else:
            want = {wp.vec3: "vec3", wp.vec4: "vec4", wp.mat33: "mat33"}[wdt]
            raise SplatplanError(
                f"{name} as a wp.array must be dtype wp.{want} or float32 shaped (..., {', '.join(map(str, tail))}), "
                f"got dtype {getattr(x.dtype, '__name__', x.dtype)} shape {tuple(x.shape)}"
            )
        if not x.is_contiguous:
            raise SplatplanError(f"{name} must be a contiguous wp.array")
        n = int(np.prod(lead, dtype=np.int64)) if lead else 1
        flat = arr.reshape((n,) + (tail if arr.dtype == wp.float32 else ()))
        if flat.dtype == wp.float32:
            flat = flat.view(wdt)
        return flat, lead, arr
    raise AssertionError(kind)


def device_side_rows(x, name: str, tail: tuple[int, ...], shape: tuple[int, ...], device: str):
    """Rotations / semi-axes of a device call: (wp rows, period, keep-alive).

    Host arrays (numpy, tuples, scalars) are uploaded (O(their size)); device arrays must tile the
    batch (leading shape a suffix of it) or are expanded on their device (torch only).
    """
    k = array_kind(x)
    if k == "numpy":
        a = np.asarray(x, dtype=np.float64)
        if name == "semi_axes" and a.ndim == 0:
            a = np.full(3, float(a))
        if a.ndim < len(tail) or a.shape[a.ndim - len(tail) :] != tail:
            raise SplatplanError(f"{name} must have shape (..., {', '.join(map(str, tail))}), got {a.shape}")
        a, p = _compact(a, shape, len(tail), name)
        arr = _wp().array(np.ascontiguousarray(a, dtype=np.float32), dtype=_wdt(tail), device=device)
        return arr, p, arr, a
    arr, lead, keep = device_rows(x, k, name, tail, device)
    per = _period(lead, shape)
    if per is None:
        if k != "torch":
            raise SplatplanError(
                f"{name} shape {lead + tail} does not tile the batch {tuple(shape)}: its leading shape must be a suffix of the batch shape"
            )
        try:
            t = keep.reshape(lead + tail).expand(tuple(shape) + tail).contiguous().reshape((-1,) + tail)
        except RuntimeError as exc:
            raise SplatplanError(f"{name} shape {lead + tail} does not broadcast to the batch {tuple(shape)}") from exc
        arr, keep, per = _wp().from_torch(t, dtype=_wdt(tail)), t, max(1, int(np.prod(shape, dtype=np.int64)))
    return arr, per, keep, None


def device_axes_medians(axes: "wp.array", device: str) -> tuple[float, float]:
    """Medians of the smallest / largest semi-axis from at most 1024 evenly spaced device rows (O(1) transfer)."""
    from .wp_metric_kernel import gather_rows_kernel

    wp = _wp()
    n = axes.shape[0]
    if n <= 1024:
        host = axes.numpy()
    else:
        step = n // 1024
        dst = wp.empty(1024, dtype=wp.vec3, device=device)
        wp.launch(gather_rows_kernel, dim=1024, inputs=[axes, step, dst], device=device)
        host = dst.numpy()
    host = np.asarray(host, dtype=np.float64).reshape(-1, 3)
    ok = np.all(np.isfinite(host), axis=1) & np.all(host > 0, axis=1)
    if not ok.any():
        return 1.0, 1.0  # every query invalid: the kernel flags them, any grid will do
    return axes_medians(host[ok])


# ---------------------------------------------------------------------------------------- outputs


@dataclass
class MetricWorkspace:
    """Preallocated device buffers reused across calls: pass ``out=workspace`` to the checker.

    Results returned for a call that used a workspace are views of its buffers (numpy views on
    CPU, torch tensors or wp.arrays on the device): they are overwritten by the next call with the
    same workspace, so copy what must be kept. Buffers grow on demand and never shrink; one
    workspace must not be used by two threads at once.
    """

    device: str
    capacity: int = 0
    min_s2: Any = None  # wp.array(float32) (capacity,)
    n_colliding: Any = None  # wp.array(int32)
    in_collision: Any = None  # wp.array(bool)
    softmin: Any = None  # wp.array(float32)
    cost: Any = None  # wp.array(float32)
    bad: Any = None  # wp.array(int32) (1,)
    sort_keys: Any = None  # wp.array(int32) (2 * capacity,) scratch of the query sort
    sort_values: Any = None  # wp.array(int32) (2 * capacity,)
    fk_capacity: int = 0
    fk_centers: Any = None  # wp.array(vec3) (fk_capacity,) ellipsoid centres from robot FK
    fk_rots: Any = None  # wp.array(mat33) (fk_capacity,)
    q_capacity: int = 0
    q: Any = None  # wp.array(float32) (q_capacity, dof) host configurations copied to the device (numpy inputs)
    slack: Any = None  # wp.array(float32) (fk_capacity,) per-ellipsoid FREE SLACK of collides_robot / collides_configs
    reallocations: int = 0  # how often buffers were (re)allocated (tests and benchmarks read it)
    _cache: dict = field(default_factory=dict)

    def reserve(self, n: int) -> "MetricWorkspace":
        """Make sure the output buffers hold at least n rows."""
        wp = _wp()
        if self.bad is None:
            self.bad = wp.empty(1, dtype=wp.int32, device=self.device)
        if n > self.capacity:
            cap = max(n, 2 * self.capacity)
            d = self.device
            self.min_s2 = wp.empty(cap, dtype=wp.float32, device=d)
            self.n_colliding = wp.empty(cap, dtype=wp.int32, device=d)
            self.in_collision = wp.empty(cap, dtype=wp.bool, device=d)
            self.softmin = wp.empty(cap, dtype=wp.float32, device=d)
            self.cost = wp.empty(cap, dtype=wp.float32, device=d)
            self.sort_keys = wp.empty(2 * cap, dtype=wp.int32, device=d)
            self.sort_values = wp.empty(2 * cap, dtype=wp.int32, device=d)
            self.capacity = cap
            self.reallocations += 1
        return self

    def reserve_fk(self, n: int) -> "MetricWorkspace":
        """Make sure the FK buffers hold at least n ellipsoids."""
        wp = _wp()
        if n > self.fk_capacity:
            cap = max(n, 2 * self.fk_capacity)
            self.fk_centers = wp.empty(cap, dtype=wp.vec3, device=self.device)
            self.fk_rots = wp.empty(cap, dtype=wp.mat33, device=self.device)
            self.fk_capacity = cap
            self.reallocations += 1
        return self

    def reserve_q(self, b: int, dof: int):
        """A (b, dof) float32 view of the configuration buffer (grown on demand)."""
        wp = _wp()
        if b > self.q_capacity or self.q is None or self.q.shape[1] != dof:
            cap = max(b, 2 * self.q_capacity if self.q is not None and self.q.shape[1] == dof else b)
            self.q = wp.empty((cap, dof), dtype=wp.float32, device=self.device)
            self.q_capacity = cap
            self.reallocations += 1
        return self.q if b == self.q_capacity else self.q[:b]

    def reserve_slack(self, n: int):
        """The slack buffer with at least n rows."""
        wp = _wp()
        if self.slack is None or self.slack.shape[0] < n:
            self.slack = wp.empty(max(n, self.fk_capacity), dtype=wp.float32, device=self.device)
            self.reallocations += 1
        return self.slack

    def scratch(self) -> tuple:
        """(keys, values) int32 scratch of the query sort."""
        return self.sort_keys, self.sort_values

    def outputs(self):
        """The kernels' :class:`~.wp_metric_kernel.MetricOutputs` over these buffers."""
        from .wp_metric_kernel import MetricOutputs

        o = MetricOutputs()
        o.min_s2, o.n_colliding, o.in_collision = self.min_s2, self.n_colliding, self.in_collision
        o.softmin, o.cost, o.bad = self.softmin, self.cost, self.bad
        return o

    def reset_bad(self) -> None:
        from .wp_metric_kernel import NO_BAD

        self.bad.fill_(NO_BAD)

    def first_bad(self) -> int | None:
        """Smallest invalid query index of the last call (one device sync), or None."""
        from .wp_metric_kernel import NO_BAD

        v = int(self.bad.numpy()[0])
        return None if v == NO_BAD else v


def convert_out(x, b: int, shape: tuple[int, ...], kind: str, copy: bool):
    """Rows [0, b) of a device buffer as the caller's type, shaped ``shape``."""
    if kind == "numpy":
        if x.device.is_cpu:
            a = x.numpy()[:b]  # (a numpy slice of the host buffer: cheaper than a device view)
            return (a.copy() if copy else a).reshape(shape)
        return (x[:b] if x.shape[0] != b else x).numpy().reshape(shape)  # (copies only the b rows)
    v = x[:b] if x.shape[0] != b else x
    if kind == "torch":
        return _wp().to_torch(v).reshape(shape)
    return v.reshape(shape) if len(shape) else v
