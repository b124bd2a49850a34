"""Invariants of the metric (hypothesis): point-cloud limit, monotonicity in n_sigma, rigid invariance,
and the neighbour-radius bound that makes the hash-grid search exact."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from splatplan.metric import CollisionChecker, MetricConfig
from splatplan.metric.reference import conservative_s2_ref, link_matrices, search_radius_ref
from splatplan.metric.wp_metric_kernel import search_radius
from splatplan.scenes.splats import Splats, quat_to_rotmat, rotmat_to_quat

from .conftest import random_quats, random_scene

SETTINGS = settings(max_examples=15, deadline=None)


@SETTINGS
@given(seed=st.integers(0, 10_000))
def test_n_sigma_zero_is_the_point_cloud_metric(seed):
    rng = np.random.default_rng(seed)
    scene = random_scene(rng, 300)
    centers = rng.uniform(-0.3, 0.3, (40, 3))
    quats, axes = random_quats(rng, 40), rng.uniform(0.01, 0.1, (40, 3))
    res = CollisionChecker(scene, n_sigma=0.0).query(centers, quats, axes)
    # point cloud: s2 = d^T A d of the splat means, independent of the splat shapes
    a = link_matrices(quats, axes, 40)
    d = scene.means[None].astype(np.float64) - centers[:, None]
    s2 = np.einsum("bni,bij,bnj->bn", d, a, d)
    m = s2.min(1) < 4.0
    np.testing.assert_allclose(res.min_s2[m], s2.min(1)[m], rtol=1e-4, atol=2e-5)
    np.testing.assert_array_equal(res.n_colliding, (s2 < 1).sum(1))


@SETTINGS
@given(seed=st.integers(0, 10_000), n1=st.floats(0, 3), dn=st.floats(0.01, 2))
def test_monotone_in_n_sigma(seed, n1, dn):
    rng = np.random.default_rng(seed)
    scene = random_scene(rng, 300)
    centers = scene.means[rng.integers(0, 300, 50)] + rng.normal(0, 0.02, (50, 3))
    ch = CollisionChecker(scene, n_sigma=n1)
    lo = ch.query(centers, None, 0.02)
    hi = ch.with_config(n_sigma=n1 + dn).query(centers, None, 0.02)
    m = lo.min_s2 < 4.0
    assert np.all(hi.min_s2[m] <= lo.min_s2[m] + 1e-5)
    assert np.all(hi.n_colliding >= lo.n_colliding)
    assert np.all(hi.in_collision >= lo.in_collision)


@SETTINGS
@given(seed=st.integers(0, 10_000))
def test_invariant_under_rigid_transform(seed):
    rng = np.random.default_rng(seed)
    scene = random_scene(rng, 300)
    centers = scene.means[rng.integers(0, 300, 40)] + rng.normal(0, 0.02, (40, 3))
    quats, axes = random_quats(rng, 40), rng.uniform(0.01, 0.05, (40, 3))
    r = quat_to_rotmat(random_quats(rng, 1))[0]
    t = rng.uniform(-2, 2, 3)

    def move_q(q):
        return rotmat_to_quat(r @ quat_to_rotmat(q))

    moved = Splats(scene.means @ r.T + t, move_q(scene.quats), scene.scales, scene.opacities, scene.colors)
    a = CollisionChecker(scene, n_sigma=1.0).query(centers, quats, axes)
    b = CollisionChecker(moved, n_sigma=1.0).query(centers @ r.T + t, move_q(quats), axes)
    m = a.min_s2 < 3.9
    np.testing.assert_allclose(b.min_s2[m], a.min_s2[m], rtol=2e-3, atol=2e-4)
    amb = np.abs(a.min_s2 - 1) < 1e-3
    assert np.all((a.n_colliding == b.n_colliding) | amb)


@SETTINGS
@given(seed=st.integers(0, 10_000), n_sigma=st.floats(0, 4), cap=st.floats(1, 16))
def test_radius_bound(seed, n_sigma, cap):
    """Every splat beyond rho = a_max (k + sqrt(k^2 + cap)), k = n_sigma sigma_g / a_min, has s2~ >= cap."""
    rng = np.random.default_rng(seed)
    scene = random_scene(rng, 2000, scale=float(rng.uniform(0.001, 0.05)))
    axes = rng.uniform(0.005, 0.08, (1, 3))
    c = rng.uniform(-0.3, 0.3, (1, 3))
    a = link_matrices(random_quats(rng, 1), axes, 1)
    _, s2t = conservative_s2_ref(scene.means, scene.quats, scene.scales, c, a, n_sigma)
    rho = search_radius(float(n_sigma), float(scene.scales.max()), float(axes.min()), float(axes.max()), float(cap))
    far = np.linalg.norm(scene.means - c, axis=1) > rho
    assert np.all(s2t[0][far] >= cap * (1 - 1e-9))


@SETTINGS
@given(seed=st.integers(0, 10_000))
def test_search_radius_ref_matches_kernel_function(seed):
    """The glue's vectorised radius (float64) is the kernels' @wp.func (evaluated in Python scope, float32)."""
    rng = np.random.default_rng(seed)
    n = 20
    n_sigma, sig = rng.uniform(0, 4, n), 10 ** rng.uniform(-4, -1, n)
    a_min = 10 ** rng.uniform(-3, -1, n)
    a_max = a_min * rng.uniform(1, 20, n)
    cap = rng.uniform(1, 16, n)
    got = search_radius_ref(n_sigma, sig, a_min, a_max, cap)
    want = [search_radius(float(n_sigma[i]), float(sig[i]), float(a_min[i]), float(a_max[i]), float(cap[i])) for i in range(n)]
    np.testing.assert_allclose(got, want, rtol=1e-5)
    assert search_radius_ref(0.0, 0.01, 0.02, 0.05, 1.0) == pytest.approx(0.05 * 1.0001, rel=1e-12)


def test_softmin_bounds():
    rng = np.random.default_rng(1)
    scene = random_scene(rng, 500)
    cfg = MetricConfig(n_sigma=1.0, softmin_t=5.0)
    res = CollisionChecker(scene, config=cfg).query(scene.means[:60], None, 0.03)
    fin = np.isfinite(res.softmin)
    assert np.all(res.softmin[fin] <= res.min_s2[fin] + 1e-5)
    assert np.all(res.softmin[fin] >= res.min_s2[fin] - np.log(len(scene)) / cfg.softmin_t - 1e-5)
