"""What the box-built scenes (apartment, tabletop) share: a box list with a colour per label, their
splat sampling (level-1 look, floaters the default filter drops, per-label density) and the
in-memory cache of their layouts and splats (:class:`SceneCache`).

Units and frames are the caller's (metres, z up for both scenes).
"""

from __future__ import annotations

import copy
import functools
from dataclasses import replace
from typing import Callable, Protocol

import numpy as np

from ..splats import Splats
from .levels import level_config, splat_count
from .analytic_scene import AnalyticScene
from .primitive_sdf import make_box
from .surface_splats import copy_splats, splats_from_scene


def object_colors(label_colors: dict) -> dict:
    """The distinct colours of the objects: the entries of ``label_colors`` labelled "object_*"."""
    return {k: v for k, v in label_colors.items() if k.startswith("object_")}


class BoxList:
    """Boxes, labels and base colours of a layout, in the order they are added.

    Args:
        label_colors: label -> RGB in [0, 1] (every label a box gets).
        offset: (3,) added to every centre (e.g. a table height the layout is written relative to).
    """

    def __init__(self, label_colors: dict, offset=(0.0, 0.0, 0.0)) -> None:
        self.label_colors = label_colors
        self.offset = np.asarray(offset, np.float64)
        self.boxes: list[np.ndarray] = []
        self.labels: list[str] = []
        self.colors: list[np.ndarray] = []

    def add(self, label: str, center, half, quat=(1.0, 0.0, 0.0, 0.0)) -> None:
        """One box of colour ``label_colors[label]``: ``center`` (3,) and half-extents ``half`` (3,)
        in metres, wxyz ``quat``."""
        self.boxes.append(make_box(np.asarray(center, np.float64) + self.offset, half, quat))
        self.labels.append(label)
        self.colors.append(np.asarray(self.label_colors[label], np.float64))

    def scene(self, meta: dict) -> tuple[AnalyticScene, np.ndarray]:
        """(the boxes as an :class:`AnalyticScene` with ``meta``, float64 (M, 3) colours)."""
        return AnalyticScene(np.stack(self.boxes), self.labels, meta), np.stack(self.colors)


def sample_splats(
    scene: AnalyticScene,
    colors: np.ndarray,  # (M, 3) base RGB per box
    n_splats: int,
    seed: int,
    seed_tag: int,
    floater_region: tuple[np.ndarray, np.ndarray],  # world AABB (lo (3,), hi (3,)) of the floaters
    density: dict,  # label -> relative spacing (2 = twice the spacing); other labels 1
    top_only: tuple[str, ...] = (),  # labels of boxes seen from above only (a floor)
) -> Splats:
    """Splats of a box layout: the level-1 look of Stonehenge, floaters that the default floater
    filter drops, ``info`` naming the scene; seeded by (seed, n_splats, seed_tag).

    Returns:
        float32 splats (wxyz, linear stds) in the layout's frame; the last ``info["n_floaters"]``
        are the floaters.
    """
    dens = np.array([float(density.get(lab, 1.0)) for lab in scene.labels])
    faces = np.ones((len(scene), 6), bool)
    for i, lab in enumerate(scene.labels):
        if lab in top_only:
            faces[i] = [False, False, False, False, True, False]  # FACE_NAMES order: only +z
    splats = splats_from_scene(
        scene,
        n_splats,
        config=replace(level_config(1), floater_transparent_fraction=1.0),
        colors=colors,
        density=dens,
        faces=faces,
        floater_region=floater_region,
        seed=np.random.default_rng([int(seed), int(n_splats), int(seed_tag)]),
    )
    splats.info.update({"scene": scene.meta["name"], "seed": int(seed), "units": scene.meta["units"]})
    return splats


class Layout(Protocol):
    """What :class:`SceneCache` reads of a scene's layout."""

    @property
    def scene(self) -> AnalyticScene: ...  # the boxes

    @property
    def colors(self) -> np.ndarray: ...  # float64 (M, 3) base RGB per box


class SceneCache:
    """The layouts and splats of one box-built scene, cached in memory (the 4 latest seeds, resp.
    (seed, splat count) pairs); callers get fresh copies.

    Args:
        build_layout: seed -> the scene's layout (an object with ``scene`` and ``colors``).
        n_splats: default total splat count (floaters included).
        seed_tag, floater_region, density, top_only: the scene's arguments of :func:`sample_splats`.
    """

    def __init__(self, build_layout: Callable[[int], Layout], n_splats: int, seed_tag: int, floater_region, density: dict, top_only: tuple[str, ...] = ()) -> None:
        self.n_splats = n_splats
        self._sample_args = (seed_tag, floater_region, density, top_only)
        self.cached_layout = functools.lru_cache(maxsize=4)(build_layout)  # shared: never mutate what it returns
        self._cached_splats = functools.lru_cache(maxsize=4)(self._sample)

    def _sample(self, seed: int, n_splats: int) -> Splats:
        lay = self.cached_layout(seed)
        seed_tag, region, density, top_only = self._sample_args
        return sample_splats(lay.scene, lay.colors, n_splats, seed, seed_tag, region, density=density, top_only=top_only)

    def layout(self, seed: int):
        """A fresh copy of the layout for ``seed``."""
        return copy.deepcopy(self.cached_layout(int(seed)))

    def build(self, seed: int, n_splats: int | None) -> tuple[Splats, AnalyticScene]:
        """Fresh copies of the splats (``n_splats`` counts floaters too; None: the default) and the boxes for ``seed``."""
        return copy_splats(self._cached_splats(int(seed), splat_count(n_splats, self.n_splats))), self.layout(seed).scene
