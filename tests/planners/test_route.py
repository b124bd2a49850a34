"""Route helpers of a planar base (planners.route): angle wrapping, tree branches, the carrot point."""

from __future__ import annotations

import numpy as np

from splatplan.planners.route import carrot, tree_branch, wrap_angle


def test_wrap_angle_range_and_identity():
    a = np.linspace(-20.0, 20.0, 401)
    w = wrap_angle(a)
    assert np.all((w >= -np.pi) & (w < np.pi))
    np.testing.assert_allclose(np.cos(w), np.cos(a), atol=1e-12)
    np.testing.assert_allclose(np.sin(w), np.sin(a), atol=1e-12)


def test_tree_branch_walks_parents_from_the_root():
    nodes = np.arange(15, dtype=float).reshape(5, 3)
    parents = np.array([-1, 0, 1, 0, 2])
    np.testing.assert_array_equal(tree_branch(nodes, parents, 4), nodes[[0, 1, 2, 4]])
    np.testing.assert_array_equal(tree_branch(nodes, parents, 0), nodes[[0]])


def test_carrot_moves_ahead_along_the_polyline_and_never_back():
    path = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    pt, prog = carrot(path, np.array([0.2, 0.1]), 0.5, 0)
    np.testing.assert_allclose(pt, [0.7, 0.0], atol=1e-12)
    assert prog == 0
    pt, prog = carrot(path, np.array([0.9, 0.2]), 0.5, 0)  # past the corner: on the second segment
    np.testing.assert_allclose(pt, [1.0, 0.7], atol=1e-12)
    assert prog == 1
    pt, _ = carrot(path, np.array([0.1, 0.0]), 0.5, prog)  # progress 1: the first segment is not used again
    np.testing.assert_allclose(pt, [1.0, 0.5], atol=1e-12)
    pt, _ = carrot(path, np.array([1.0, 0.9]), 0.5, 1)  # beyond the end: the last point
    np.testing.assert_allclose(pt, [1.0, 1.0])
    np.testing.assert_allclose(carrot(path[:1], np.zeros(2), 0.5, 0)[0], path[0])
