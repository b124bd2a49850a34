"""Terrain for ground robots: the floor's splats stop counting as obstacles, up to the step height."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.scenes import Splats, rotmat_to_quat
from splatplan.scenes.terrain import TerrainConfig, fitted_floor_z, remove_terrain, terrain_mask


def floor_room(seed=0) -> tuple[Splats, dict]:
    """A 4 x 4 m floor at z = 0.01 (flat splats, 4 cm stds, plus small round blobs), a 3 cm strip
    (a low obstacle) and a 40 cm box; returns the splats and the index ranges of each part."""
    rng = np.random.default_rng(seed)
    n_floor, n_blob, n_strip, n_box = 8000, 1000, 200, 1500
    fl = np.c_[rng.uniform(-2, 2, (n_floor, 2)), 0.01 + rng.normal(0, 0.003, n_floor)]
    tilt = rotmat_to_quat(np.eye(3))
    blobs = np.c_[rng.uniform(-2, 2, (n_blob, 2)), rng.uniform(0.0, 0.02, n_blob)]
    strip = np.c_[rng.uniform(-2, 2, n_strip), rng.uniform(1.0, 1.05, n_strip), rng.uniform(0.0, 0.03, n_strip)]
    box = np.c_[rng.uniform(-0.2, 0.2, (n_box, 2)) + [1.0, -1.0], rng.uniform(0.0, 0.4, n_box)]
    means = np.concatenate([fl, blobs, strip, box])
    scales = np.concatenate([np.tile([0.04, 0.04, 0.002], (n_floor, 1)), np.full((n_blob, 3), 0.01), np.full((n_strip, 3), 0.005), np.full((n_box, 3), 0.02)])
    quats = np.tile(tilt, (len(means), 1))
    parts = {"floor": slice(0, n_floor), "blobs": slice(n_floor, n_floor + n_blob), "strip": slice(n_floor + n_blob, n_floor + n_blob + n_strip),
             "box": slice(n_floor + n_blob + n_strip, len(means))}  # fmt: skip
    return Splats(means, quats, scales, np.full(len(means), 0.9), np.full((len(means), 3), 0.5)), parts


def test_terrain_mask_keeps_obstacles_above_the_step():
    s, parts = floor_room()
    m = terrain_mask(s, floor_z=0.0, step_height=0.05, n_sigma=1.0)
    assert m[parts["floor"]].all() and m[parts["blobs"]].all()
    assert m[parts["strip"]].all()  # lower than the step: terrain (the documented miss)
    box_z = s.means[parts["box"], 2]
    np.testing.assert_array_equal(m[parts["box"]], box_z + 0.02 < 0.05)  # only the box's bottom 3 cm
    assert not terrain_mask(s, 0.0, 0.0, n_sigma=1.0)[parts["blobs"]].any()


def test_fitted_floor_and_ground_robot_start():
    from splatplan.metric import CollisionChecker
    from splatplan.robots import load_robot

    s, parts = floor_room()
    assert fitted_floor_z(s) == pytest.approx(0.01, abs=0.01)
    go2 = load_robot("go2")
    q = np.array([[-1.0, 0.0, 0.0], [1.0, -1.0, 0.0]])  # open floor; on the box
    assert np.asarray(CollisionChecker(s, n_sigma=1.0).collides_robot(go2, q)).any(axis=-1)[0]  # feet in the floor's splats
    ground, rep = remove_terrain(s, TerrainConfig(step_height=0.05), n_sigma=1.0)
    assert rep.fitted and rep.n_terrain == len(s) - len(ground)
    hit = np.asarray(CollisionChecker(ground, n_sigma=1.0).collides_robot(go2, q)).any(axis=-1)
    assert not hit[0] and hit[1]
    with pytest.raises(SplatplanError):
        TerrainConfig(step_height=float("nan")).validate()


def test_floor_surface_mask_is_terrain_at_every_n_sigma():
    from splatplan.scenes.terrain import floor_surface_mask

    s, parts = floor_room()
    surf = floor_surface_mask(s, floor_z=0.0, step_height=0.05)
    assert surf[parts["floor"]].all() and not surf[parts["blobs"]].any()  # round blobs are not floor-like
    for n_sigma in (0.0, 1.0, 3.0, 100.0):
        m = terrain_mask(s, 0.0, 0.05, n_sigma=n_sigma)
        assert m[surf].all()  # the floor's surface is terrain at any n_sigma
    assert not terrain_mask(s, 0.0, 0.05, n_sigma=100.0)[parts["blobs"]].any()


def test_drop_floaters_tests_upright_faint_splats_on_the_floor():
    """A faint upright splat standing alone on the floor (a floater the capture left in the step
    band) blocks a ground robot at n_sigma 1; align's floater rule drops it, the floor stays."""
    from splatplan.scenes.align import AlignConfig, align_scene

    s, parts = floor_room()
    lone = np.array([[0.0, 0.5, 0.03], [-1.0, 1.5, 0.03]])  # 3 cm up, far from the strip and the box
    upright = rotmat_to_quat(np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]]))  # normal along y
    both = Splats(np.r_[s.means, lone], np.r_[s.quats, np.tile(upright, (2, 1))], np.r_[s.scales, np.tile([0.04, 0.04, 0.0005], (2, 1))],
                  np.r_[s.opacities, [0.03, 0.03]], np.r_[s.colors, np.zeros((2, 3))])  # fmt: skip
    assert not terrain_mask(both, 0.0, 0.05, n_sigma=1.0)[-2:].any()  # obstacles at n_sigma 1
    out, res = align_scene(both, AlignConfig(up="+z", floor=0.0, drop_floaters=True))
    kept = {tuple(np.round(m, 6)) for m in out.means}
    assert not any(tuple(np.round(m, 6)) in kept for m in lone)
    assert res.n_floaters <= 2 + 0.01 * len(s)  # the floor's surface is not tested


def test_faint_splats_of_the_step_band_are_floor_haze():
    s, parts = floor_room()
    op = s.opacities.copy()
    blobs = np.arange(len(s))[parts["blobs"]]
    op[blobs[:500]] = 0.05  # faint haze
    hazy = Splats(s.means, s.quats, s.scales, op, s.colors)
    m0 = terrain_mask(hazy, 0.0, 0.05, n_sigma=5.0)  # at n_sigma 5 the round blobs reach above the band
    m = terrain_mask(hazy, 0.0, 0.05, n_sigma=5.0, faint_below=0.1)
    assert not m0[blobs].any() and np.array_equal(m[blobs], np.arange(len(blobs)) < 500)
    box = np.arange(len(s))[parts["box"]]
    assert not (m & ~m0)[box].any()  # opaque obstacles are never haze
    _, rep = remove_terrain(hazy, TerrainConfig(floor_z=0.0, step_height=0.05, rule="shape"), n_sigma=5.0)
    _, rep0 = remove_terrain(hazy, TerrainConfig(floor_z=0.0, step_height=0.05, faint_below=0.0, rule="shape"), n_sigma=5.0)
    assert rep.n_terrain - rep0.n_terrain == 500


def test_band_rule_feet_stand_on_the_floor_and_low_obstacles_still_block():
    """The default rule (issue #36): every splat with its mean in the step band or below the floor
    is terrain (round floor blobs, a mirror layer under the plane); what rises above the step
    height still blocks the Go2 (a 10 cm step under a foot, the 40 cm box)."""
    from splatplan.metric import CollisionChecker
    from splatplan.robots import load_robot

    s, parts = floor_room()
    rng = np.random.default_rng(5)
    # round, fairly opaque floor-level matter (not flat, reaching above the band at n_sigma 1)
    n_fm = 300
    fm = np.c_[rng.uniform(-2, 2, (n_fm, 2)), rng.uniform(0.0, 0.03, n_fm)]
    # a mirror layer: opaque, large splats under the plane
    n_mir = 400
    mir = np.c_[rng.uniform(-2, 2, (n_mir, 2)), rng.uniform(-0.45, -0.05, n_mir)]
    # a 10 cm step (a threshold / a low toy) at x in [-0.2, 0.2], y in [1.3, 1.7]: splats on its faces up to z = 0.1
    n_step = 600
    step = np.c_[rng.uniform(-0.2, 0.2, n_step), rng.uniform(1.3, 1.7, n_step), rng.uniform(0.0, 0.1, n_step)]
    means = np.concatenate([s.means, fm, mir, step])
    scales = np.concatenate([s.scales, np.full((n_fm, 3), 0.04), np.full((n_mir, 3), 0.12), np.full((n_step, 3), 0.01)])
    op = np.concatenate([s.opacities, np.full(n_fm, 0.6), np.full(n_mir, 0.9), np.full(n_step, 0.9)])
    room = Splats(means, np.tile(s.quats[:1], (len(means), 1)), scales, op, np.full((len(means), 3), 0.5))
    n0 = len(s)
    band = terrain_mask(room, 0.0, 0.05, rule="band")
    assert band[n0:n0 + n_fm + n_mir].all()  # floor matter and the mirror layer: terrain
    assert not terrain_mask(room, 0.0, 0.05, n_sigma=1.0)[n0:n0 + n_fm].all()  # not under the shape rule
    step_z = room.means[n0 + n_fm + n_mir:, 2]
    np.testing.assert_array_equal(band[n0 + n_fm + n_mir:], step_z < 0.05)  # the step's upper half stays
    box_z = s.means[parts["box"], 2]
    np.testing.assert_array_equal(band[parts["box"]], box_z < 0.05)
    go2 = load_robot("go2")
    q = np.array([[-1.0, -1.0, 0.0],  # open floor over floor matter and the mirror layer
                  [1.0, -1.0, 0.0],  # over the 40 cm box
                  [0.0, 1.5, 0.0],  # the 10 cm step under the body's middle, between the legs: it fits under
                  [0.22, 1.5, 0.0]])  # a front leg over the step
    ground, rep = remove_terrain(room, TerrainConfig(floor_z=0.0))  # the default rule
    hit = np.asarray(CollisionChecker(ground).collides_robot(go2, q)).any(axis=-1)
    assert not hit[0] and hit[1] and hit[3]
    # open floor (away from the strip at y = 1, the box and the step): every pose free under the
    # band rule; the shape rule leaves round floor matter at the feet that blocks some
    X, Y = np.meshgrid(np.linspace(-1.6, -0.6, 6), np.linspace(-1.6, 0.4, 8), indexing="ij")
    grid = np.c_[X.ravel(), Y.ravel(), np.zeros(X.size)]
    assert not np.asarray(CollisionChecker(ground).collides_robot(go2, grid)).any()
    shape_ground, _ = remove_terrain(room, TerrainConfig(floor_z=0.0, rule="shape"))
    assert np.asarray(CollisionChecker(shape_ground).collides_robot(go2, grid)).any(axis=-1).sum() >= 3
    with pytest.raises(SplatplanError):
        terrain_mask(room, 0.0, 0.05, rule="nope")
