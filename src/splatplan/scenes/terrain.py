"""Terrain for ground robots: the floor's splats are ground to stand on, not obstacles.

A walking or driving robot touches the floor, and a real capture's floor is a layer of splats a
few centimetres thick (stds of ~4 cm on phone captures), so at any n_sigma its feet or wheels sit
"in collision". This module selects, once per scene, the splats that are **terrain** and the
collision scene drops them (the metric and its kernels are untouched: a scene-level selection).

**The rule (``TerrainConfig.rule``).** ``"band"`` (the default): a splat is
terrain when its mean lies below ``floor_z + step_height``, whatever its shape or opacity. That is
the floor's own splats (a phone capture's floor holds round and upright splats of opacity 0.3-0.9
and stds of 2-5 cm, not only flat ones), the floor-level matter where the feet and calves stand,
and everything **below the floor plane**: the floor's underside and the reflection of a shiny
floor, which captures train as opaque geometry down to half a metre under it. A ground robot stands
on the floor and cannot reach below it, so none of these can hit it; an obstacle is what rises
above the step height, and its splats up there stay obstacles (a 10 cm step, a toy, a box).

``"shape"`` (the stricter rule): a splat is terrain when its mean lies below
``floor_z + step_height`` **and** it is floor-like: either flat with a near-vertical normal (within 30 degrees of +z: a piece of the floor's surface),
or wholly inside the step band (its n_sigma extent along z, ``mean_z + n_sigma * sqrt(Sigma_zz)``,
below ``floor_z + step_height``), or faint (opacity below ``faint_below``, 0.1: the haze of
upright and round splats a capture leaves on its floor; on the bathroom capture one of opacity
0.02, 4 cm tall, ended a Go2 run at a negative clearance).

``floor_z`` is the aligned floor (z = 0 after ``splatplan scene align``), fitted from the scene
(:func:`~splatplan.scenes.align.guess_up` with up = +z) when not given.

**Only where a floor was found.** Terrain needs a floor: when the splats at floor height cover
less than ``min_floor_coverage`` of the scene's footprint (:func:`floor_coverage`; an object
capture such as a chair, whose only splats at z = 0 are the ends of its legs), nothing is terrain
and the report says so: the bottom of the object stays an obstacle.

What it can miss (by design, both rules): an obstacle lower than the step height (a threshold strip, a
cable, a flat book) is terrain too, so the robot may walk over it (the Go2 steps over 5 cm);
under ``"band"`` so are the lowest 5 cm of a taller obstacle, whose splats above still block; a sloped or stepped floor
keeps its higher parts as obstacles (one floor height per scene); a floater lying flat on the
floor is dropped with the floor; so is a faint object lower than the step height.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._config import bounded, check_config
from ..errors import SplatplanError
from .align import AlignConfig, guess_up
from .floor import floor_surface_mask
from .splats import Splats


@dataclass
class TerrainConfig:
    """Which splats a ground robot treats as terrain (see the module docstring)."""

    #: floor height (world z, scene units; 0 after `scene align`); none = fitted from the scene
    floor_z: float | None = None
    #: the robot's step height above the floor (scene units): floor-like splats with their mean
    #: below floor_z + step_height are terrain (an obstacle lower than this is missed)
    step_height: float = bounded(0.05, ge=0)
    #: a flat splat is floor-like when its normal lies within this angle of +z (degrees)
    max_tilt_deg: float = bounded(30.0, ge=0, le=90)
    #: a splat of the step band fainter than this (activated opacity) is floor haze, terrain whatever
    #: its shape (0 = off)
    faint_below: float = bounded(0.1, ge=0, le=1)
    #: "band": every splat with its mean below floor_z + step_height is terrain (the floor's splats
    #: whatever their shape, floor-level matter, reflections under the floor plane);
    #: "shape": only the floor-like ones (flat, wholly inside the band, or faint: max_tilt_deg and
    #: faint_below apply), the stricter rule
    rule: str = bounded("band", choices=("band", "shape"))
    #: terrain applies only when the splats at floor height (within step_height of floor_z) cover at
    #: least this fraction of the scene's x, y footprint (:func:`floor_coverage`); below it the scene
    #: has no floor there (an object capture) and nothing is terrain. 0 = always (a floor assumed)
    min_floor_coverage: float = bounded(0.15, ge=0, le=1)

    def validate(self) -> "TerrainConfig":
        check_config(self)  # declared ranges and finiteness
        if self.floor_z is not None and not np.isfinite(self.floor_z):
            raise SplatplanError(f"terrain floor_z must be finite, got {self.floor_z}")
        if not (np.isfinite(self.step_height) and self.step_height >= 0):
            raise SplatplanError(f"terrain step_height must be a finite number >= 0, got {self.step_height}")
        if not (np.isfinite(self.max_tilt_deg) and 0 <= self.max_tilt_deg <= 90):
            raise SplatplanError(f"terrain max_tilt_deg must lie in [0, 90], got {self.max_tilt_deg}")
        return self


def fitted_floor_z(splats: Splats) -> float:
    """The floor height of a z-up scene: the bounding plane with a +z normal (else the robust bottom)."""
    return float(guess_up(splats, AlignConfig(up="+z", floor="auto")).floor_height)


def terrain_mask(splats: Splats, floor_z: float, step_height: float, n_sigma: float = 1.0, max_tilt_deg: float = 30.0, faint_below: float = 0.0,
                 rule: str = "shape") -> np.ndarray:
    """(N,) bool: the terrain splats under ``rule`` (module docstring; ``"shape"`` here, the
    :class:`TerrainConfig` default is ``"band"``). ``n_sigma`` is the checker's."""
    z = splats.means[:, 2].astype(np.float64)
    top_band = floor_z + step_height
    if rule == "band":
        return z < top_band
    if rule != "shape":
        raise SplatplanError(f"terrain rule must be 'band' or 'shape', got {rule!r}")
    sz = np.sqrt(np.maximum(splats.covariances()[:, 2, 2], 0.0))
    band = z < top_band
    return floor_surface_mask(splats, floor_z, step_height, max_tilt_deg) | (band & (z + n_sigma * sz < top_band)) | (band & (splats.opacities < faint_below))


#: cells per side of the x, y grid :func:`floor_coverage` counts
COVERAGE_CELLS = 32


def floor_coverage(splats: Splats, floor_z: float, step_height: float, cells: int = COVERAGE_CELLS) -> float:
    """The fraction (0..1) of the scene's x, y footprint where a splat lies at floor height: of the
    cells of a ``cells`` x ``cells`` grid over the splat means' x, y bounds that hold any splat,
    those that hold one with its mean within ``max(step_height, 2 cm)`` of ``floor_z``. A room or a
    capture standing on the ground: near 1; an object alone (its legs' ends at the floor): small."""
    m = np.asarray(splats.means, dtype=np.float64)
    if len(m) == 0:
        return 0.0
    lo, hi = m[:, :2].min(axis=0), m[:, :2].max(axis=0)
    ij = np.clip(((m[:, :2] - lo) / np.maximum(hi - lo, 1e-12) * cells).astype(np.int64), 0, cells - 1)
    key = ij[:, 0] * cells + ij[:, 1]  # (N,) cell of each splat
    near = np.abs(m[:, 2] - floor_z) <= max(float(step_height), 0.02)
    return float(np.unique(key[near]).size / max(np.unique(key).size, 1))


@dataclass
class TerrainReport:
    floor_z: float
    step_height: float
    fitted: bool
    n_terrain: int
    #: :func:`floor_coverage` at floor_z (nan when not measured)
    coverage: float = float("nan")
    #: whether a floor was found (coverage >= min_floor_coverage); without one nothing is terrain
    floor_found: bool = True

    def summary(self) -> str:
        how = "fitted" if self.fitted else "given"
        if not self.floor_found:
            return (f"terrain: no floor at z = {self.floor_z:.3g} ({how}; splats there cover {self.coverage:.0%} of the scene's footprint, an object "
                    "capture?): nothing is terrain, every splat is an obstacle (--terrain-min-floor-coverage 0 assumes a floor there)")
        return f"terrain: {self.n_terrain:,} floor splats below z = {self.floor_z + self.step_height:.3g} (floor {self.floor_z:.3g} {how} + step {self.step_height:g}) are ground, not obstacles"


def remove_terrain(splats: Splats, config: TerrainConfig | None = None, n_sigma: float = 1.0) -> tuple[Splats, TerrainReport]:
    """The scene without its terrain splats (order of the rest kept) and a report."""
    cfg = (config or TerrainConfig()).validate()
    fitted = cfg.floor_z is None
    fz = fitted_floor_z(splats) if cfg.floor_z is None else float(cfg.floor_z)
    cover = floor_coverage(splats, fz, cfg.step_height)
    found = cover >= cfg.min_floor_coverage
    mask = terrain_mask(splats, fz, cfg.step_height, n_sigma, cfg.max_tilt_deg, cfg.faint_below, cfg.rule) if found else np.zeros(len(splats), bool)
    out = splats.subset(~mask)
    out.info["terrain"] = {"floor_z": fz, "step_height": cfg.step_height, "n_terrain": int(mask.sum()), "floor_found": bool(found), "floor_coverage": round(cover, 4)}
    return out, TerrainReport(fz, cfg.step_height, fitted, int(mask.sum()), cover, found)
