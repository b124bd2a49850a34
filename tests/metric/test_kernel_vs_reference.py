"""The Warp kernel against the float64 numpy brute force, on random scenes and link batches."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.metric import CollisionChecker, MetricConfig
from splatplan.metric.reference import conservative_s2_ref, link_matrices, softmin_ref, splat_inflation_ref
from splatplan.metric.wp_metric import TierConfig
from splatplan.scenes.splats import Splats

from .conftest import DEVICES, random_quats, random_scene


def _compare(scene: Splats, centers, quats, axes, cfg: MetricConfig, device: str, tiers: TierConfig | None = None, rots=None):
    ch = CollisionChecker(scene, config=cfg, device=device, tiers=tiers)
    got = ch.query(centers, quats, np.broadcast_to(axes, centers.shape), rots=rots)
    hit = ch.collides(centers, quats, np.broadcast_to(axes, centers.shape), rots=rots)
    _check_against_reference(scene, centers, quats, axes, cfg, got, hit, rots=rots)


def _check_against_reference(scene: Splats, centers, quats, axes, cfg: MetricConfig, got, hit, rots=None):
    """Every output of ``got`` (and the collision-only ``hit``) against the float64 brute force."""
    a = link_matrices(quats, axes, len(centers), rots)
    keep, ns = splat_inflation_ref(scene.opacities, len(scene), cfg)
    _, s2t = conservative_s2_ref(scene.means[keep], scene.quats[keep], scene.scales[keep], centers, a, ns[keep], cfg.linearize)  # (B, N)
    want_min = s2t.min(1) if s2t.shape[1] else np.full(len(centers), np.inf)
    below = want_min < cfg.s2_cap
    # min_s2: exact (to float32 rounding) below the cap, >= cap (up to rounding) above it
    np.testing.assert_allclose(got.min_s2[below], want_min[below], rtol=1e-4, atol=2e-5)
    assert np.all(got.min_s2[~below] >= cfg.s2_cap * (1 - 1e-4))
    # n_colliding: exact, except splats within float32 rounding of the surface s2~ = 1
    want_n = (s2t < 1.0).sum(1)
    ambiguous = (np.abs(s2t - 1.0) < 1e-4).sum(1)
    assert np.all(np.abs(got.n_colliding - want_n) <= ambiguous)
    assert np.all((got.in_collision == (want_n > cfg.k_collide)) | (ambiguous > 0))
    # collision-only kernel agrees with the counts
    assert np.all((hit == (want_n > cfg.k_collide)) | (ambiguous > 0))
    # softmin and cost over N(q) = {s2~ < cap}
    for j in range(len(centers)):
        v = s2t[j][s2t[j] < cfg.s2_cap]
        if v.size == 0:
            assert np.isinf(got.softmin[j]) and got.cost[j] == 0.0
            continue
        soft = softmin_ref(v, cfg.softmin_t, cfg.softmin_mode)
        c = cfg.cost_d_max * np.exp(-cfg.cost_gamma * np.maximum(v - cfg.cost_s_min, 0))
        cost = {"mean": c.mean(), "sum": c.sum(), "max": c.max()}[cfg.cost_reduce]
        tol = 1e-3 * max(1.0, np.abs(v).size * 1e-3)
        assert abs(got.softmin[j] - soft) < tol + 1e-4 * abs(soft)
        assert abs(got.cost[j] - cost) < 1e-4 * max(1.0, abs(cost)) + 1e-5


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("n_sigma", [0.0, 0.5, 2.0])
@pytest.mark.parametrize("kind", ["sphere", "ellipsoid"])
def test_anisotropic_splats(device, n_sigma, kind):
    rng = np.random.default_rng(int(n_sigma * 10) + (kind == "sphere"))
    scene = random_scene(rng, 1500)
    b = 300
    centers = rng.uniform(-0.3, 0.3, (b, 3))
    centers[: b // 2] = scene.means[rng.integers(0, len(scene), b // 2)] + rng.normal(0, 0.01, (b // 2, 3))
    if kind == "sphere":
        quats, axes = None, np.array([0.015, 0.015, 0.015])
    else:
        quats, axes = random_quats(rng, b), rng.uniform(0.005, 0.05, (b, 3))
    _compare(scene, centers, quats, axes, MetricConfig(n_sigma=n_sigma), device)


@pytest.mark.parametrize("device", DEVICES)
def test_2dgs_disks(device):
    rng = np.random.default_rng(7)
    scene = random_scene(rng, 1200, disks=True)
    assert scene.is_2d
    b = 200
    centers = scene.means[rng.integers(0, len(scene), b)] + rng.normal(0, 0.02, (b, 3))
    _compare(scene, centers, random_quats(rng, b), rng.uniform(0.005, 0.04, (b, 3)), MetricConfig(n_sigma=1.0), device)


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("tiers", [TierConfig(), TierConfig(mode="quantile", quantiles=(0.5, 0.8, 0.95), cell_factor=3.0), TierConfig(mode="quantile", quantiles=(), cell_factor=0.5), TierConfig(class_factor=1.5, min_tier_count=1, tier_overhead=0.0, sort_min_batch=1)])
def test_huge_splats_are_never_dropped(device, tiers):
    """Splats far larger than the robot (a few huge floaters and walls) stay exact in every tiering."""
    rng = np.random.default_rng(3)
    scene = random_scene(rng, 1000)
    big = random_scene(rng, 40, scale=0.2)  # std 0.2 vs robot 0.015: linearisation far outside its comfort zone
    scene = Splats(
        np.concatenate([scene.means, big.means]), np.concatenate([scene.quats, big.quats]),
        np.concatenate([scene.scales, big.scales]), np.concatenate([scene.opacities, big.opacities]),
        np.concatenate([scene.colors, big.colors]),
    )  # fmt: skip
    b = 250
    centers = rng.uniform(-0.5, 0.5, (b, 3))
    for ns in (0.5, 2.0):
        _compare(scene, centers, random_quats(rng, b), rng.uniform(0.01, 0.03, (b, 3)), MetricConfig(n_sigma=ns, s2_cap=9.0), device, tiers)


@pytest.mark.parametrize("reduce", ["mean", "sum", "max"])
def test_cost_reductions_and_k(reduce):
    rng = np.random.default_rng(11)
    scene = random_scene(rng, 800)
    centers = scene.means[rng.integers(0, len(scene), 120)]
    cfg = MetricConfig(n_sigma=1.0, cost_reduce=reduce, k_collide=3, cost_gamma=2.0, softmin_t=3.0)
    _compare(scene, centers, None, np.array([0.02, 0.02, 0.02]), cfg, "cpu")


def test_checker_reference_backend_matches_and_batch_shape():
    rng = np.random.default_rng(5)
    scene = random_scene(rng, 600)
    centers = rng.uniform(-0.3, 0.3, (4, 5, 2, 3))  # (K, T, links, 3)
    axes = np.array([[0.02, 0.02, 0.02], [0.01, 0.03, 0.02]])  # per link, broadcast over (K, T)
    quats = random_quats(rng, 40).reshape(4, 5, 2, 4)
    w = CollisionChecker(scene, n_sigma=1.0).query(centers, quats, axes)
    r = CollisionChecker(scene, n_sigma=1.0, backend="reference").query(centers, quats, axes)
    assert w.min_s2.shape == (4, 5, 2) and w.cost.shape == (4, 5, 2)
    m = r.min_s2 < 4.0
    np.testing.assert_allclose(w.min_s2[m], r.min_s2[m], rtol=1e-4, atol=2e-5)
    np.testing.assert_array_equal(w.n_colliding, r.n_colliding)


def test_bad_queries_are_clear_errors():
    rng = np.random.default_rng(0)
    ch = CollisionChecker(random_scene(rng, 50))
    with pytest.raises(SplatplanError, match="NaN"):
        ch.query(np.array([[0.0, np.nan, 0.0]]), None, (0.015, 0.015, 0.015))
    with pytest.raises(SplatplanError, match="shape"):
        ch.query(np.zeros((3, 2)), None, (0.015, 0.015, 0.015))
    with pytest.raises(SplatplanError, match="semi_axes"):
        ch.query(np.zeros((3, 3)), None, (0.1, -0.1, 0.1))
    with pytest.raises(SplatplanError, match="zero quaternion"):
        ch.query(np.zeros((1, 3)), np.zeros((1, 4)), (0.015, 0.015, 0.015))
    with pytest.raises(SplatplanError, match="n_sigma"):
        CollisionChecker(random_scene(rng, 5), n_sigma=-1.0)
    assert ch.query(np.zeros((0, 3)), None, (0.015, 0.015, 0.015)).min_s2.shape == (0,)


@pytest.mark.parametrize("t, gamma", [(4.0, 4.0), (12.0, 4.0), (10.0, 4.0), (30.0, 2.5)])
def test_softmin_paths(t, gamma):
    """softmin_t = m * gamma reuses the cost's exp (m = 1, 3); other ratios take two exps."""
    rng = np.random.default_rng(int(t * 10 + gamma))
    scene = random_scene(rng, 900)
    centers = scene.means[rng.integers(0, len(scene), 150)] + rng.normal(0, 0.01, (150, 3))
    cfg = MetricConfig(n_sigma=0.7, softmin_t=t, cost_gamma=gamma)
    _compare(scene, centers, random_quats(rng, 150), rng.uniform(0.01, 0.04, (150, 3)), cfg, "cpu")
