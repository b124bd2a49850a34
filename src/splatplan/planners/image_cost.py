"""The terminal image cost of MPPI (paper Sec. II-D): render what a robot-mounted camera would see
at the end of every rollout and compare its embedding with the target image's.

Per MPPI iteration, for the K terminal states x_kT:

1. camera poses: ``world <- camera = link_pose(x_kT) @ offset`` (a
   :class:`~splatplan.render.MountedCamera`: the Panda's wrist camera through ``robot.link_poses``,
   the Go2's head camera on its base link), (K, 4, 4);
2. **one** batched render call (:class:`~splatplan.render.SplatRenderer`: Warp kernels on CPU
   cores or CUDA), (K, H, W, 3) in [0, 1];
3. encoder features and ``cost_k = w_global ||g_t - g_k||^2 + w_patch mean_p ||tok_t,p - tok_k,p||^2``
   (:class:`splatplan.encoders.EmbeddingDistance`; patch tokens only for encoders that have them);
4. times ``weight`` -> (K,) float64.

    cost = ImageCost(renderer, camera, robot, encoder, target_rgb, weight=10.0)
    mppi = MPPI(JointIntegrator(robot), checker, cfg, costs=[CollisionCost(...), cost, ...])

On CUDA the view matrices go to the renderer as a torch tensor on its device, so the images stay
on the GPU between the renderer and the encoder (no host copy of the images).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .._config import ConfigTerms, bounded
from ..errors import SplatplanError
from .cost_base import Cost, CostValue, Rollout

if TYPE_CHECKING:
    import torch

    from ..robots.robot import Robot

__all__ = ["ImageCost", "ImageTerms"]


class ImageCost(Cost):
    """Terminal image cost over a batch of rollouts (see the module docstring).

    Args:
        renderer: a :class:`~splatplan.render.SplatRenderer` of the scene (kept open by the caller).
        camera: a :class:`~splatplan.render.MountedCamera` (link, offset, K, image size).
        robot: the :class:`~splatplan.robots.Robot` whose configuration the states are (the first
            ``robot.dof`` state coordinates).
        encoder: an :class:`~splatplan.encoders.Encoder` (e.g. ``load_encoder("thumbnail")``).
        target: (H, W, 3) RGB target image in [0, 1] (any size: the encoder resizes both images to
            its own input size), or a precomputed :class:`splatplan.encoders.EmbeddingDistance`.
        weight: weight of the term.
        w_global: weight of the global-embedding distance (CLS / pooled / thumbnail).
        w_patch: weight of the mean patch-token distance (0 for encoders without tokens).
        background: RGB background of the renders (the target should use the same).
        keep_images: report the (K, H, W, 3) renders among the values (``values["images"]``).
        w_empty: weight of the empty-view term ``mean_pixels(1 - alpha)`` added to each sample's cost:
            a view of empty space is constant, so a correlation-type embedding (the weight-free
            thumbnail) cannot tell it from a poor match; 0 = the paper's image cost only.
        time_index: which rollout step is rendered when the rollout names no goal step
            (-1 = the terminal state x_T); a shrinking-horizon MPC passes ``goal_step`` = T - 1 - s
            after s executed steps (:meth:`MPPI.step`) so the goal time stays fixed.
        log_eps: > 0 scores ``log(1 + c / log_eps)`` instead of the raw distance c (0 = raw): MPPI's
            weights ``exp(-dC / lambda)`` then see relative progress, so the update stays greedy near
            the goal where absolute cost differences between samples shrink towards 0.
        normalize: compare L2-normalised features (cosine distance in [0, 4]: the same cost scale
            for every encoder; see :class:`splatplan.encoders.EmbeddingDistance`).
    """

    name = "image"

    def __init__(
        self,
        renderer,
        camera,
        robot: Robot,
        encoder,
        target,
        weight: float = 1.0,
        w_global: float = 1.0,
        w_patch: float = 0.0,
        background=(0.0, 0.0, 0.0),
        keep_images: bool = False,
        w_empty: float = 0.0,
        time_index: int = -1,
        log_eps: float = 0.0,
        normalize: bool = False,
    ) -> None:
        from ..encoders.base import EmbeddingDistance

        if not np.isfinite(weight) or weight < 0:
            raise SplatplanError(f"ImageCost weight must be finite and >= 0, got {weight}")
        self.renderer = renderer
        self.camera = camera
        self.robot = robot
        self.encoder = encoder
        self.weight = float(weight)
        self.background = tuple(float(b) for b in background)
        self.keep_images = bool(keep_images)
        self.time_index = int(time_index)
        self.w_empty = float(w_empty)
        if not np.isfinite(log_eps) or log_eps < 0:
            raise SplatplanError(f"ImageCost log_eps must be finite and >= 0, got {log_eps}")
        self.log_eps = float(log_eps)
        camera._link_index(robot)  # fail early on a wrong link name
        if isinstance(target, EmbeddingDistance):
            self.embedding_cost = target
        else:
            img = np.asarray(target, dtype=np.float32)
            if img.ndim != 3 or img.shape[-1] != 3:
                raise SplatplanError(f"ImageCost target must be one (H, W, 3) RGB image, got shape {img.shape}")
            self.embedding_cost = EmbeddingDistance(encoder, img, w_global=w_global, w_patch=w_patch, normalize=normalize)
        #: number of render calls made so far (one per evaluated batch)
        self.n_renders = 0

    # ------------------------------------------------------------------ pieces
    def viewmats(self, states: np.ndarray) -> np.ndarray:
        """(K, 4, 4) world-to-camera matrices of terminal states (K, dx)."""
        q = np.asarray(states, dtype=np.float64)[..., : self.robot.dof]
        return self.camera.viewmats(self.robot, q).reshape(-1, 4, 4)

    def render(self, states: np.ndarray):
        """One batched render of the camera views at states (K, dx) -> (K, H, W, 3) (numpy on CPU,
        a torch tensor on the renderer's CUDA device)."""
        return self._render(states).rgb

    def _render(self, states: np.ndarray):
        v: np.ndarray | torch.Tensor = self.viewmats(states)  # (B, 4, 4); a tensor on the renderer's device when it runs on CUDA
        ks: np.ndarray | torch.Tensor = self.camera.Ks((v.shape[0],))
        if getattr(self.renderer, "is_cuda", False):
            import torch

            dev = torch.device(self.renderer.device)
            v = torch.as_tensor(v, dtype=torch.float32, device=dev)
            ks = torch.as_tensor(ks, dtype=torch.float32, device=dev)
        res = self.renderer.render(v, ks, self.camera.width, self.camera.height, background=self.background)
        self.n_renders += 1
        return res

    def raw_cost_of_images(self, images, alpha=None) -> np.ndarray:
        """(K, H, W, 3) images (and their (K, H, W) alpha for the empty-view term) -> (K,) raw
        float64 costs: unweighted, before the log transform."""
        c = self.embedding_cost(images)
        if hasattr(c, "detach"):
            c = c.detach().cpu().numpy()
        c = np.asarray(c, dtype=np.float64).reshape(-1)
        if self.w_empty > 0 and alpha is not None:
            a = alpha.detach().cpu().numpy() if hasattr(alpha, "detach") else np.asarray(alpha)
            c = c + self.w_empty * (1.0 - a.reshape(len(c), -1).mean(axis=1))
        return c

    def weigh(self, raw: np.ndarray) -> np.ndarray:
        """(K,) raw costs -> (K,) weighted costs (log-transformed when ``log_eps > 0``)."""
        c = raw
        if self.log_eps > 0:
            c = np.log1p(np.maximum(c, 0.0) / self.log_eps)
        return self.weight * c

    def cost_of_images(self, images, alpha=None) -> np.ndarray:
        """(K, H, W, 3) images (and their alpha) -> (K,) weighted float64 costs."""
        return self.weigh(self.raw_cost_of_images(images, alpha))

    def cost_of_states(self, states: np.ndarray) -> np.ndarray:
        """(K, dx) terminal states -> (K,) weighted costs (one render call)."""
        res = self._render(states)
        return self.cost_of_images(res.rgb, res.alpha)

    # ------------------------------------------------------------------ Cost interface
    def evaluate(self, rollout: Rollout) -> CostValue:
        """{"image": (K,) weighted} and the values {"image_raw": (K,) raw costs} (plus "images":
        the (K, H, W, 3) renders with ``keep_images``)."""
        t = self.time_index if rollout.goal_step is None else int(rollout.goal_step)
        res = self._render(rollout.states[:, t])  # (K, H, W, 3): ONE render call per iteration
        raw = self.raw_cost_of_images(res.rgb, res.alpha)
        values = {"image_raw": raw, **({"images": res.rgb} if self.keep_images else {})}
        return CostValue({self.name: self.weigh(raw)}, values)

    def __call__(self, rollout: Rollout) -> np.ndarray:
        return self.evaluate(rollout).terms[self.name]


@dataclass
class ImageTerms(ConfigTerms):
    """The image-cost fields of a task's config (flat in it: ``--task-w-image``) and the
    :class:`ImageCost` they make."""

    #: render background grey level: a mid grey keeps views of empty space from scoring like dark
    #: image regions (with a black background the weight-free thumbnail rewards looking away)
    background: float = bounded(0.5, ge=0, le=1)
    #: weight of the image cost
    w_image: float = bounded(1.0, ge=0)
    #: image cost scored as log(1 + c / image_log_eps) (0 = the raw distance c): MPPI then weighs
    #: relative progress, so it keeps converging near the goal where raw differences shrink
    image_log_eps: float = bounded(0.01, ge=0)
    #: compare L2-normalised features (cosine distance in [0, 4]): one cost scale for every encoder,
    #: so the image cost neither swamps nor vanishes beside the collision cost
    normalize_features: bool = True
    #: weight of the empty-view term mean(1 - alpha) of the rendered view (0 = image cost only)
    w_empty: float = bounded(1.0, ge=0)
    #: weight of the global-embedding distance inside the image cost
    w_global: float = bounded(1.0, ge=0)
    #: weight of the mean patch-token distance inside the image cost (0 = off; needs tokens)
    w_patch: float = bounded(0.0, ge=0)

    def image_cost(self, renderer, camera, robot: Robot, encoder, target) -> ImageCost:
        """The :class:`ImageCost` of ``target`` (H, W, 3) seen by ``camera`` on ``robot``."""
        return ImageCost(renderer, camera, robot, encoder, target, weight=self.w_image, w_global=self.w_global, w_patch=self.w_patch, background=(self.background,) * 3,
                         w_empty=self.w_empty, log_eps=self.image_log_eps, normalize=self.normalize_features)  # fmt: skip
