"""E1 options of MetricConfig (log-mean-exp softmin, opacity threshold, opacity-scaled inflation):
Warp kernel vs the float64 reference, and the options' defining properties."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.metric import CollisionChecker, MetricConfig

from .conftest import DEVICES, random_quats, random_scene
from .test_kernel_vs_reference import _compare


def _queries(rng, scene, b):
    centers = scene.means[rng.integers(0, len(scene), b)] + rng.normal(0, 0.01, (b, 3))
    return centers, random_quats(rng, b), rng.uniform(0.008, 0.04, (b, 3))


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize(
    "opts",
    [
        dict(softmin_mode="mean"),
        dict(softmin_mode="mean", softmin_t=300.0),  # the paper's sharp temperature
        dict(opacity_min=0.5),
        dict(opacity_scaled_inflation=True),
        dict(opacity_min=0.4, opacity_scaled_inflation=True, softmin_mode="mean", k_collide=2),
        dict(linearize="squared"),  # the paper's linearisation
        dict(linearize="squared", opacity_min=0.0, opacity_scaled_inflation=False),  # the paper's settings
        dict(linearize="distance", opacity_min=0.0, opacity_scaled_inflation=False),
    ],
)
def test_options_match_reference(device, opts):
    rng = np.random.default_rng(len(str(opts)))
    scene = random_scene(rng, 1000)
    c, q, a = _queries(rng, scene, 160)
    _compare(scene, c, q, a, MetricConfig(n_sigma=1.5, **opts), device)


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("linearize", ["distance", "squared"])
def test_linearize_matches_reference_for_spheres(device, linearize):
    rng = np.random.default_rng(7)
    scene = random_scene(rng, 800, scale=0.01)
    c, q, _ = _queries(rng, scene, 120)
    _compare(scene, c, q, np.full(3, 0.02), MetricConfig(n_sigma=2.0, linearize=linearize), device)  # a sphere link: the kernel's own branch


def test_linearize_distance_is_tighter_and_still_conservative():
    """Both linearisations are lower bounds of the exact s2 over a splat's n-sigma ellipsoid (s2 and s
    are convex); the distance's is never below the paper's, and both equal s2 at n_sigma 0."""
    from splatplan.metric.reference import conservative_s2_ref, link_matrices, quat_to_rotmat

    rng = np.random.default_rng(11)
    n, b = 300, 40
    means, quats = rng.uniform(-0.5, 0.5, (n, 3)), random_quats(rng, n)
    scales = np.exp(rng.normal(np.log(0.05), 0.8, (n, 3)))  # large splats, up to ~0.3
    centers, axes = rng.uniform(-0.3, 0.3, (b, 3)), np.array([0.17, 0.03, 0.02])  # a thin link (a Go2 calf)
    a = link_matrices(random_quats(rng, b), axes, b)
    for ns in (0.5, 1.0, 2.0):
        s2, dist = conservative_s2_ref(means, quats, scales, centers, a, ns, "distance")
        _, sq = conservative_s2_ref(means, quats, scales, centers, a, ns, "squared")
        assert np.all(dist >= sq - 1e-12) and np.all(dist <= s2 + 1e-12)
        # the exact minimum over the n-sigma ellipsoid, sampled (inside and on its surface): never below
        u = rng.normal(size=(400, 3))
        u = u / np.linalg.norm(u, axis=1, keepdims=True) * ns * rng.uniform(0, 1, (400, 1)) ** (1 / 3)
        u[:200] *= ns / np.linalg.norm(u[:200], axis=1, keepdims=True)
        pts = means[:, None] + np.einsum("nij,nj,kj->nki", quat_to_rotmat(quats), scales, u)  # (N, K, 3)
        dp = pts[None] - centers[:, None, None]  # (B, N, K, 3)
        exact = np.einsum("bnki,bij,bnkj->bnk", dp, a, dp).min(-1)  # (B, N) sampled minimum
        assert np.all(dist <= exact + 1e-9)
        assert np.mean(dist > sq + 1e-6) > 0.5  # and tighter for most pairs
    _, d0 = conservative_s2_ref(means, quats, scales, centers, a, 0.0, "distance")
    _, q0 = conservative_s2_ref(means, quats, scales, centers, a, 0.0, "squared")
    np.testing.assert_allclose(d0, q0, rtol=1e-12)


def test_reference_backend_takes_the_options():
    rng = np.random.default_rng(2)
    scene = random_scene(rng, 500)
    c, q, a = _queries(rng, scene, 60)
    cfg = MetricConfig(n_sigma=1.0, softmin_mode="mean", opacity_min=0.5, opacity_scaled_inflation=True)
    w = CollisionChecker(scene, config=cfg).query(c, q, a)
    r = CollisionChecker(scene, config=cfg, backend="reference").query(c, q, a)
    m = r.min_s2 < 4.0
    np.testing.assert_allclose(w.min_s2[m], r.min_s2[m], rtol=1e-4, atol=2e-5)
    np.testing.assert_allclose(w.softmin[m], r.softmin[m], rtol=1e-3, atol=1e-3)
    np.testing.assert_array_equal(w.n_colliding, r.n_colliding)


def test_option_semantics():
    rng = np.random.default_rng(4)
    scene = random_scene(rng, 600)
    c, q, a = _queries(rng, scene, 80)
    ch = CollisionChecker(scene, n_sigma=1.0)
    base = ch.query(c, q, a)
    # log-mean-exp = log-sum-exp + log|N| / t: never below the sum form, never above the mean of N
    mean = ch.with_config(softmin_mode="mean").query(c, q, a)
    fin = np.isfinite(base.softmin)
    assert np.all(mean.softmin[fin] >= base.softmin[fin] - 1e-5)
    np.testing.assert_array_equal(mean.min_s2, base.min_s2)
    # opacity_min = 1 (every splat o < 1 here): empty scene; opacity_min below every opacity: unchanged
    assert scene.opacities.max() < 1.0
    none = ch.with_config(opacity_min=1.0).query(c, q, a)
    assert np.all(np.isinf(none.min_s2)) and not none.in_collision.any() and np.all(none.cost == 0)
    assert not ch.with_config(opacity_min=1.0).collides(c, q, a).any()
    same = ch.with_config(opacity_min=float(scene.opacities.min()) * 0.99).query(c, q, a)
    np.testing.assert_array_equal(same.n_colliding, base.n_colliding)
    # scaled inflation sits between n_sigma = 0 and the full inflation
    scaled = ch.with_config(opacity_scaled_inflation=True).query(c, q, a)
    zero = ch.with_config(n_sigma=0.0).query(c, q, a)
    assert np.all(scaled.n_colliding <= base.n_colliding) and np.all(scaled.n_colliding >= zero.n_colliding)


def test_bad_options_are_clear_errors():
    rng = np.random.default_rng(0)
    with pytest.raises(SplatplanError, match="softmin_mode"):
        CollisionChecker(random_scene(rng, 5), config=MetricConfig(softmin_mode="max"))
    with pytest.raises(SplatplanError, match="linearize"):
        CollisionChecker(random_scene(rng, 5), config=MetricConfig(linearize="cubic"))
    with pytest.raises(SplatplanError, match="opacity_min"):
        CollisionChecker(random_scene(rng, 5), config=MetricConfig(opacity_min=1.5))
