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
    ],
)
def test_options_match_reference(device, opts):
    rng = np.random.default_rng(len(str(opts)))
    scene = random_scene(rng, 1000)
    c, q, a = _queries(rng, scene, 160)
    _compare(scene, c, q, a, MetricConfig(n_sigma=1.5, **opts), device)


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
    with pytest.raises(SplatplanError, match="opacity_min"):
        CollisionChecker(random_scene(rng, 5), config=MetricConfig(opacity_min=1.5))
