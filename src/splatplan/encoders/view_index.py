"""A view index for place recognition (paper Sec. IV-B, E6; :mod:`splatplan.tasks.navigate`): the
views of a planar base's camera at the nodes of a map (e.g. an exploration tree), rendered and
encoded in batches (:func:`index_views`), and the view closest to a target image
(:func:`retrieve`: squared embedding distance, the image cost of the paper).

Units: metres, radians; yaw about +z, 0 = looking along +x.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .._config import ConfigTerms, bounded
from ..errors import SplatplanError
from ..planners.route import wrap_angle

if TYPE_CHECKING:
    from ..robots.robot import Robot
    from .base import Encoder

__all__ = ["Match", "ViewIndex", "ViewIndexTerms", "index_views", "retrieve", "thin_nodes"]


def thin_nodes(nodes: np.ndarray, spacing: float) -> np.ndarray:
    """Indices of nodes kept by greedy thinning in order: a node is kept when it is at least
    ``spacing`` (m, in x, y) from every node kept before it."""
    nodes = np.asarray(nodes, np.float64)
    if spacing <= 0 or len(nodes) == 0:
        return np.arange(len(nodes))
    kept = [0]
    for i in range(1, len(nodes)):
        if np.min(np.linalg.norm(nodes[kept, :2] - nodes[i, :2], axis=1)) >= spacing:
            kept.append(i)
    return np.asarray(kept)


@dataclass
class ViewIndex:
    """Encoded views of the tree: row i = node ``node[i]`` at heading ``yaw[i]``."""

    poses: np.ndarray  # (M, 3) x, y, yaw of each view
    node: np.ndarray  # (M,) tree node index
    embeddings: object  # (M, D) encoder output (numpy or torch)
    encoder: Encoder  # what encoded them (and encodes a target image)
    render_s: float = 0.0
    encode_s: float = 0.0


def index_views(robot: Robot, camera, nodes: np.ndarray, encoder, renderer, *, n_headings: int = 24, spacing: float = 0.15, batch: int = 256, background: float = 0.5) -> ViewIndex:
    """Render with ``camera`` (a :class:`~splatplan.render.MountedCamera` on the planar base
    ``robot``) and encode the views of ``nodes`` (N, 3) x, y, yaw (thinned to ``spacing`` m by
    :func:`thin_nodes`) at ``n_headings`` evenly spaced headings, ``batch`` renders at a time on a
    grey ``background``. ``ViewIndex.node`` indexes ``nodes``."""
    nodes = np.asarray(nodes, np.float64).reshape(-1, 3)
    keep = thin_nodes(nodes, spacing)
    cam = camera
    yaws = 2 * np.pi * np.arange(n_headings) / n_headings
    poses = np.concatenate([np.repeat(nodes[keep, :2], len(yaws), axis=0), np.tile(yaws, len(keep))[:, None]], axis=1)  # (M, 3)
    poses[:, 2] = wrap_angle(poses[:, 2])
    node = np.repeat(keep, len(yaws))
    embs, t_r, t_e = [], 0.0, 0.0
    for i in range(0, len(poses), batch):
        t0 = time.perf_counter()
        rgb = cam.render(renderer, robot, poses[i : i + batch], background=(background,) * 3).rgb
        t1 = time.perf_counter()
        embs.append(np.asarray(encoder.encode(rgb)))
        t_r, t_e = t_r + t1 - t0, t_e + time.perf_counter() - t1
    emb = np.concatenate(embs) if embs else np.zeros((0, encoder.dim), np.float32)
    return ViewIndex(poses, node, emb, encoder, t_r, t_e)


@dataclass
class Match:
    """The retrieved view: pose (x, y, yaw), its node, the cost (squared embedding distance),
    the median cost over all views, and whether the match is weak."""

    index: int
    node: int
    pose: np.ndarray
    cost: float
    median_cost: float
    ratio: float
    weak: bool
    costs: np.ndarray | None = field(repr=False, default=None)

    def to_json(self) -> dict:
        return {"node": int(self.node), "pose": self.pose.round(4).tolist(), "cost": round(self.cost, 6), "median_cost": round(self.median_cost, 6),
                "ratio": round(self.ratio, 4), "weak": bool(self.weak)}  # fmt: skip


def retrieve(index: ViewIndex, target_image, weak_ratio: float = 0.5) -> Match:
    """The view whose embedding is closest to the target image's (any image size: the encoder
    resizes it; RGB in [0, 1])."""
    img = np.asarray(target_image, np.float32)
    if img.ndim != 3 or img.shape[-1] != 3:
        raise SplatplanError(f"target image must be (H, W, 3) RGB, got shape {img.shape}")
    if len(index.poses) == 0:
        raise SplatplanError("the view index is empty: the exploration tree has no nodes")
    e_t = np.asarray(index.encoder.encode(img[None]))  # (1, D)
    costs = np.sum((np.asarray(index.embeddings, np.float64) - e_t.astype(np.float64)) ** 2, axis=1)  # (M,)
    i = int(np.argmin(costs))
    med = float(np.median(costs))
    ratio = float(costs[i] / med) if med > 0 else 1.0
    return Match(i, int(index.node[i]), index.poses[i].copy(), float(costs[i]), med, ratio, bool(ratio > weak_ratio), costs)


@dataclass
class ViewIndexTerms(ConfigTerms):
    """The head camera's and the view index's fields of a navigation config (flat in it:
    ``--n-headings``), and the camera and index they make."""

    #: rendered image side (pixels, square)
    image_size: int = bounded(64, ge=1)
    #: horizontal field of view of the head camera (degrees)
    fov_deg: float = bounded(90.0, ge=0.01, le=179)
    #: head camera position in the base frame (x forward, y left, z up), metres
    camera_offset: tuple[float, float, float] = (0.30, 0.0, 0.05)
    #: render background grey level
    background: float = bounded(0.5, ge=0, le=1)
    #: index only nodes at least this far (m) from every node indexed before them (greedy thinning
    #: in tree order); 0 = every node
    index_spacing_m: float = bounded(0.15, gt=0)
    #: headings rendered per node (evenly spaced over 360 degrees)
    n_headings: int = bounded(24, ge=1)
    #: renders per batch when indexing
    render_batch: int = bounded(256, ge=1)

    def head_camera(self, robot: Robot):
        """The head camera on the base link of ``robot`` (:func:`splatplan.render.cameras.head_camera`)."""
        from ..render.cameras import head_camera

        return head_camera(robot, self.image_size, self.fov_deg, self.camera_offset)

    def index_views(self, robot: Robot, nodes: np.ndarray, encoder, renderer) -> ViewIndex:
        """:func:`index_views` of ``nodes`` (N, 3) with these settings and :meth:`head_camera`."""
        return index_views(robot, self.head_camera(robot), nodes, encoder, renderer, n_headings=self.n_headings, spacing=self.index_spacing_m, batch=self.render_batch,
                           background=self.background)  # fmt: skip
