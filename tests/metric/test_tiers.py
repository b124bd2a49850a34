"""Size-class tiers: each tier's radius fits its members, a far "sky shell" gets its own tier, and
the kernel stays exact (vs the float64 reference) on a scene with such a shell."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.metric import CollisionChecker, MetricConfig
from splatplan.metric.wp_metric import TierConfig, size_class_tiers
from splatplan.scenes.splats import Splats

from .conftest import DEVICES, random_quats, random_scene
from .test_kernel_vs_reference import _compare


def _shell_scene(rng, n_scene=900, n_shell=300, radius=60.0, std=2.0) -> Splats:
    """A small random scene in [-0.3, 0.3]^3 inside an opaque shell of huge splats (a phone scan's sky)."""
    s = random_scene(rng, n_scene)
    d = rng.normal(size=(n_shell, 3))
    m = radius * d / np.linalg.norm(d, axis=1, keepdims=True)
    sc = np.tile([std, std, std / 4], (n_shell, 1)) * rng.uniform(0.9, 1.0, (n_shell, 1))
    return Splats(
        np.concatenate([s.means, m]), np.concatenate([s.quats, random_quats(rng, n_shell)]),
        np.concatenate([s.scales, sc]), np.concatenate([s.opacities, np.ones(n_shell)]),
        np.concatenate([s.colors, np.full((n_shell, 3), 0.5)]),
    )  # fmt: skip


def test_size_classes_fit_their_members():
    rng = np.random.default_rng(0)
    smax = np.concatenate([np.exp(rng.normal(np.log(0.003), 0.8, 5000)), np.full(300, 7.39), [0.5, 0.6]])
    tier = size_class_tiers(smax, factor=2.0, min_count=50, max_tiers=12)
    shell = tier[5000:5300]
    assert len(set(shell)) == 1 and not np.isin(shell[0], tier[:5000])  # the shell alone in its tier
    assert set(tier[5300:]) != {shell[0]}  # two big floaters do not join the shell
    for t in np.unique(tier):
        s = smax[tier == t]
        if len(s) >= 50 and t != tier.max():
            assert s.max() / s.min() <= 4.0 + 1e-9  # at most one merge of adjacent classes
    assert tier.max() + 1 <= 12
    few = size_class_tiers(smax, factor=2.0, min_count=50, max_tiers=3)
    assert few.max() + 1 == 3 and len(set(few[5000:5300])) == 1
    # the merge order never pushes small splats into the shell's tier
    assert not np.isin(few[5000], few[:5000])


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("tiers", [TierConfig(), TierConfig(mode="quantile"), TierConfig(max_tiers=2, min_tier_count=1)])
def test_shell_scene_is_exact(device, tiers):
    rng = np.random.default_rng(8)
    scene = _shell_scene(rng)
    b = 240
    centers = scene.means[rng.integers(0, 900, b)] + rng.normal(0, 0.01, (b, 3))
    centers[:40] = scene.means[900 + rng.integers(0, 300, 40)] * rng.uniform(0.93, 1.02, (40, 1))  # near the shell
    axes = rng.uniform(0.01, 0.5, (b, 3))
    axes[40:] = rng.uniform(0.01, 0.03, (b - 40, 3))
    _compare(scene, centers, random_quats(rng, b), axes, MetricConfig(n_sigma=1.0), device, tiers)


def _tiers_of(impl, a: float = 0.02, cap: float = 4.0) -> list[np.ndarray]:
    """Original splat indices per tier of the grid set used for queries of radius a."""
    gs = impl.gridset(1.0, cap, a, a)
    return [impl.order[impl.class_offset[i] : impl.class_offset[j] + impl.class_count[j]] for i, j in gs.groups]


@pytest.mark.parametrize("cap", [1.0, 4.0])
def test_shell_gets_its_own_tier(cap):
    scene = _shell_scene(np.random.default_rng(9), n_shell=60)  # 6% of the splats, as in the phone scan
    new = _tiers_of(CollisionChecker(scene, n_sigma=1.0)._impl, cap=cap)
    assert sorted(new[-1]) == list(range(900, 960))  # the shell alone in the top tier
    old = _tiers_of(CollisionChecker(scene, n_sigma=1.0, tiers=TierConfig(mode="quantile"))._impl, cap=cap)
    # the old quantile tiers put ordinary splats into a tier with (part of) the shell: they get its radius
    assert any((t >= 900).any() and (t < 900).any() for t in old)


def test_classes_are_grouped_by_query_size():
    """Classes whose radii are alike for a query size share a tier; tiny robots see more tiers."""
    rng = np.random.default_rng(3)
    smax_scene = random_scene(rng, 20000, scale=0.004)
    impl = CollisionChecker(smax_scene, n_sigma=1.0)._impl
    n_classes = len(impl.class_count)
    assert n_classes >= 4
    for a in (0.001, 0.02, 0.5):
        gs = impl.gridset(1.0, 4.0, a, a)
        flat = [c for i, j in gs.groups for c in range(i, j + 1)]
        assert flat == list(range(n_classes))  # a partition into contiguous runs
        assert gs.counts == [sum(impl.class_count[i : j + 1]) for i, j in gs.groups]
    assert len(impl.gridset(1.0, 4.0, 0.5, 0.5).groups) <= len(impl.gridset(1.0, 4.0, 0.001, 0.001).groups)


@pytest.mark.parametrize("device", DEVICES)
def test_query_order_does_not_change_results(device):
    """Morton-sorted launches give bit-identical outputs, in the caller's order, invalid rows included."""
    rng = np.random.default_rng(12)
    scene = random_scene(rng, 800)
    b = 3000
    c = (scene.means[rng.integers(0, 800, b)] + rng.normal(0, 0.02, (b, 3))).astype(np.float32)
    c[[5, 2000]] = np.nan
    q = random_quats(rng, b).astype(np.float32)
    axes = rng.uniform(0.01, 0.03, (b, 3)).astype(np.float32)
    wp = __import__("splatplan._warp", fromlist=["wp"]).wp()
    args = (wp.array(c, dtype=wp.vec3, device=device), wp.array(q, dtype=wp.vec4, device=device), wp.array(axes, dtype=wp.vec3, device=device))
    got = {}
    for sort in (True, False):
        ch = CollisionChecker(scene, n_sigma=1.0, device=device, tiers=TierConfig(sort_queries=sort))
        res = ch.query(*args)
        got[sort] = {k: v.numpy() for k, v in res.as_dict().items()} | {"hit": ch.collides(*args).numpy()}
    for k in got[True]:
        np.testing.assert_array_equal(got[True][k], got[False][k], err_msg=k)
    assert got[True]["n_colliding"][5] == -1 and got[True]["hit"][2000]


def _average_per_cell_ref(points: np.ndarray, width: float) -> float:
    """Points per occupied cell floor(p / width), counted with a Python set (the slow reference)."""
    cells = {tuple(int(v) for v in np.floor(p / width)) for p in np.asarray(points, dtype=np.float64)}
    return len(points) / len(cells)


@pytest.mark.parametrize("seed", range(4))
def test_finer_cell_steps_matches_a_direct_count(seed):
    from splatplan.metric.tiers import finer_cell_steps

    rng = np.random.default_rng(seed)
    n = int(rng.integers(2000, 6000))
    # points on a few random planes (surface-like) and some volume noise
    normals = rng.normal(size=(3, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    pts = rng.uniform(-1.0, 1.0, (n, 3))
    k = rng.integers(0, 3, n)
    pts -= (np.einsum("ij,ij->i", pts, normals[k]))[:, None] * normals[k]  # onto plane k (through the origin)
    pts[: n // 10] = rng.uniform(-1.0, 1.0, (n // 10, 3))
    width, target = float(rng.uniform(0.2, 0.6)), float(rng.uniform(10.0, 60.0))
    want = 4
    for s in range(5):
        if _average_per_cell_ref(pts, width * 2.0 ** (-s / 4.0)) <= target:
            want = s
            break
    assert finer_cell_steps(pts, width, target) == want
    assert finer_cell_steps(pts, width, target, max_steps=1) == min(want, 1)


def test_finer_cell_steps_edge_cases():
    from splatplan.metric.tiers import finer_cell_steps

    plane = np.stack(np.meshgrid(np.arange(64.0), np.arange(64.0), [0.5], indexing="ij"), -1).reshape(-1, 3)  # spacing 1
    assert finer_cell_steps(plane, 4.0, 16.0) == 0  # 16 a cell already
    assert finer_cell_steps(plane, 8.0, 16.0) == 4  # 64 a cell: 2x finer
    assert finer_cell_steps(plane, 1e6, 16.0) == 4  # one huge cell: at most max_steps
    assert finer_cell_steps(np.zeros((0, 3)), 1.0, 16.0) == 0
    assert finer_cell_steps(plane[:10], 100.0, 16.0) == 0  # fewer points than the target
    assert finer_cell_steps(plane, 0.0, 16.0) == 0 and finer_cell_steps(plane, float("nan"), 16.0) == 0
    assert finer_cell_steps(plane * 1e30, 1e-300, 16.0) == 0  # (cells too fine to count: no step)


@pytest.mark.parametrize("n_sigma", [0.0, 1.0])
def test_dense_scene_gets_finer_robot_cells_and_the_same_answers(n_sigma):
    """A densely sampled wall fills the robot-check cells with hundreds of splats: the checker's
    grid for collides_configs is finer than with the rule off, and every answer is the same."""
    from splatplan.robots import load_robot

    rng = np.random.default_rng(3)
    n = 60000
    scene = random_scene(rng, n, scale=0.002)
    scene.means[:] = rng.uniform(-1.0, 1.0, (n, 3)) * np.array([0.003, 0.5, 0.4]) + np.array([0.55, 0.0, 0.4])  # a thin wall
    robot = load_robot("panda").inflated(0.01)
    cfg = MetricConfig(n_sigma=n_sigma)
    on = CollisionChecker(scene, config=cfg, device="cpu", tiers=TierConfig())
    off = CollisionChecker(scene, config=cfg, device="cpu", tiers=TierConfig(robot_collide_cell_splats=None))
    lim = robot.joint_limits
    q = lim[:, 0] + rng.random((400, robot.dof)) * (lim[:, 1] - lim[:, 0])
    got, want = np.asarray(on.collides_configs(robot, q)), np.asarray(off.collides_configs(robot, q))
    np.testing.assert_array_equal(got, want)
    assert 0.05 < want.mean() < 0.95
    np.testing.assert_array_equal(np.asarray(on.collides_robot(robot, q[:100])), np.asarray(off.collides_robot(robot, q[:100])))
    (cells_on,) = {k[1] for k in on._impl._gridsets}  # (the robot checks' grid set: one here)
    (cells_off,) = {k[1] for k in off._impl._gridsets}
    assert all(a <= b for a, b in zip(cells_on, cells_off)) and any(a < b for a, b in zip(cells_on, cells_off)), (cells_on, cells_off)  # (sparse tiers keep theirs)
    on.close()
    off.close()
