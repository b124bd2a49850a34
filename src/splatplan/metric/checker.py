"""CollisionChecker: the public entry point of the metric stage.

    checker = CollisionChecker(scene, n_sigma=1.0, device="cpu")
    res = checker.query(centers, quats=None, semi_axes=(0.015, 0.015, 0.015))
    res.min_s2, res.n_colliding, res.in_collision, res.softmin, res.cost

Query batches may have any leading shape, e.g. (K, T, links) for MPPI rollouts; every output has
that shape. Frames: ``centers`` are link centres in the scene's world frame (scene units),
``quats`` wxyz link orientations (link frame -> world), ``semi_axes`` the link's (a, b, c) along its
own x, y, z axes.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import SplatplanError
from ..scenes.splats import Splats
from .config import MetricConfig, QueryResult


def _as_queries(centers, quats, semi_axes) -> tuple[tuple[int, ...], np.ndarray, np.ndarray | None, np.ndarray]:
    """Validate and flatten a query batch. Returns (batch_shape, centers (B,3), quats (B,4)|None, axes (B,3))."""
    c = np.asarray(centers, dtype=np.float64)
    if c.ndim < 1 or c.shape[-1] != 3:
        raise SplatplanError(f"centers must have shape (..., 3), got {c.shape}")
    shape = c.shape[:-1]
    c = c.reshape(-1, 3)
    if not np.all(np.isfinite(c)):
        raise SplatplanError("centers contain NaN or Inf")
    q = None
    if quats is not None:
        q = np.asarray(quats, dtype=np.float64)
        if q.shape[-1] != 4:
            raise SplatplanError(f"quats must have shape (..., 4) (wxyz), got {q.shape}")
        q = np.broadcast_to(q, shape + (4,)).reshape(-1, 4) if q.shape[:-1] != shape else q.reshape(-1, 4)
        if not np.all(np.isfinite(q)):
            raise SplatplanError("quats contain NaN or Inf")
        n = np.linalg.norm(q, axis=1, keepdims=True)
        if np.any(n < 1e-8):
            raise SplatplanError("quats contain a zero quaternion")
        q = q / n
    a = np.asarray(semi_axes, dtype=np.float64)
    if a.ndim == 0:
        a = np.full(3, float(a))
    if a.shape[-1] != 3:
        raise SplatplanError(f"semi_axes must have shape (3,) or (..., 3), got {a.shape}")
    try:
        a = np.broadcast_to(a, shape + (3,)).reshape(-1, 3)
    except ValueError as exc:
        raise SplatplanError(f"semi_axes shape {np.shape(semi_axes)} does not broadcast to the batch {shape}") from exc
    if not np.all(np.isfinite(a)) or np.any(a <= 0):
        raise SplatplanError("semi_axes must be finite and > 0")
    return shape, c, q, a


class CollisionChecker:
    """Batched CollisionSplatting queries against one scene.

    Args:
        scene: the splats (validated; floaters are *not* filtered here, do that when loading).
        n_sigma: conservatism knob (>= 0), shortcut for ``config.n_sigma``.
        device: "cpu", "cuda", "cuda:N" or None/"auto".
        config: full :class:`MetricConfig`; ``n_sigma`` overrides its field when given.
        backend: "warp" (the streaming kernel) or "reference" (numpy brute force, slow).
    """

    def __init__(
        self,
        scene: Splats,
        n_sigma: float | None = None,
        device: str | None = "cpu",
        config: MetricConfig | None = None,
        backend: str = "warp",
    ) -> None:
        cfg = config or MetricConfig()
        if n_sigma is not None:
            cfg = replace(cfg, n_sigma=float(n_sigma))
        self.config = cfg.validate()
        if len(scene) == 0:
            raise SplatplanError("the scene has no splats to check against")
        self.scene = scene.validate()
        if backend not in ("warp", "reference"):
            raise SplatplanError(f"unknown backend {backend!r}: use 'warp' or 'reference'")
        self.backend = backend
        self._impl = None
        if backend == "warp":
            from .wp_metric import WarpMetric

            self._impl = WarpMetric(scene, device=device)
            self.device = self._impl.device
        else:
            self.device = "cpu"

    @property
    def n_sigma(self) -> float:
        return self.config.n_sigma

    def with_config(self, **changes) -> "CollisionChecker":
        """A checker sharing this one's scene data (and grids) with some config fields changed."""
        other = object.__new__(CollisionChecker)
        other.__dict__.update(self.__dict__)
        other.config = replace(self.config, **changes).validate()
        return other

    def query(self, centers, quats=None, semi_axes=(0.015, 0.015, 0.015)) -> QueryResult:
        """All five outputs for a batch of link poses (see :class:`QueryResult`)."""
        shape, c, q, a = _as_queries(centers, quats, semi_axes)
        if c.shape[0] == 0:
            empty = np.zeros(0)
            return QueryResult(empty.astype(np.float32), empty.astype(np.int32), empty.astype(bool), empty.astype(np.float32), empty.astype(np.float32)).reshape(shape)
        if self.backend == "reference":
            from .reference import collision_metric_ref

            s = self.scene
            res = collision_metric_ref(s.means, s.quats, s.scales, c, q, a, self.config)
            res = QueryResult(
                res.min_s2.astype(np.float32),
                res.n_colliding.astype(np.int32),
                res.in_collision,
                res.softmin.astype(np.float32),
                res.cost.astype(np.float32),
            )
        else:
            res = self._impl.query(c, q, a, self.config)
        return res.reshape(shape)

    def collides(self, centers, quats=None, semi_axes=(0.015, 0.015, 0.015)) -> np.ndarray:
        """Boolean collision state only (n_colliding > k_collide); stops at the (k+1)-th hit.

        Much cheaper than :meth:`query` for RRT edge checks. Shape: the batch shape.
        """
        shape, c, q, a = _as_queries(centers, quats, semi_axes)
        if c.shape[0] == 0:
            return np.zeros(shape, dtype=bool)
        if self.backend == "reference":
            return self.query(centers, quats, semi_axes).in_collision
        return self._impl.collides(c, q, a, self.config).reshape(shape)
