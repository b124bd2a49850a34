"""Robot.inflated / inflate_semi_axes: the grown ellipsoid contains every point within the margin
of the original (random ellipsoids, random points), while growing each semi-axis by the margin does
not in general."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.robots import load_robot
from splatplan.robots.robot import inflate_semi_axes


def _points_near(a, m, rng, n):
    """Points within distance m of the axis-aligned ellipsoid a (3,): on its surface plus a vector of
    length <= m (the worst ones: along the outward normal, length m)."""
    u = rng.standard_normal((n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    x = u * a  # on the surface
    nrm = x / a**2
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    v = rng.standard_normal((n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    along = rng.random(n) < 0.5
    d = np.where(along[:, None], nrm, v) * (m * np.where(along, 1.0, rng.random(n)))[:, None]
    return x + d


@pytest.mark.parametrize("seed", range(5))
def test_inflated_contains_minkowski_sum(seed):
    rng = np.random.default_rng(seed)
    naive_fails = 0
    for _ in range(40):
        a = rng.uniform(0.005, 0.3, 3)
        m = rng.uniform(0.0005, 0.05)
        b = inflate_semi_axes(a, m)
        p = _points_near(a, m, rng, 4000)
        assert np.all(np.sum((p / b) ** 2, axis=1) <= 1 + 1e-9)
        assert np.all(b >= a + m - 1e-15)
        naive_fails += np.any(np.sum((p / (a + m)) ** 2, axis=1) > 1 + 1e-9)
    assert naive_fails > 0  # a + m alone misses points for elongated ellipsoids
    np.testing.assert_allclose(inflate_semi_axes(np.full(3, 0.1), 0.02), np.full(3, 0.12))  # spheres: exact


def test_robot_inflated_copy():
    r = load_robot("ellipsoid:0.1,0.05,0.02")
    r2 = r.inflated(0.01)
    np.testing.assert_allclose(r2.semi_axes, inflate_semi_axes(r.semi_axes, 0.01))
    assert r.semi_axes[0, 0] == 0.1 and r2.info["inflated_by_m"] == 0.01
    assert np.all(r2.motion_bound >= r.motion_bound)
    q = np.zeros((1, 3))
    c1, q1, _ = r.ellipsoids(q)
    c2, q2, _ = r2.ellipsoids(q)
    np.testing.assert_array_equal(c1, c2)
    with pytest.raises(SplatplanError, match="margin"):
        r.inflated(-1.0)
