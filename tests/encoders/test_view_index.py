"""View index (encoders.view_index): greedy node thinning and retrieval with a stand-in encoder."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.encoders.view_index import ViewIndex, retrieve, thin_nodes
from splatplan.errors import SplatplanError


def test_thin_nodes_keeps_nodes_spacing_apart_in_order():
    nodes = np.array([[0.0, 0.0, 0.0], [0.05, 0.0, 0.0], [0.2, 0.0, 0.0], [0.21, 0.05, 1.0], [0.0, 0.3, 0.0]])
    keep = thin_nodes(nodes, 0.15)
    np.testing.assert_array_equal(keep, [0, 2, 4])
    for i, a in enumerate(keep):
        for b in keep[:i]:
            assert np.linalg.norm(nodes[a, :2] - nodes[b, :2]) >= 0.15
    np.testing.assert_array_equal(thin_nodes(nodes, 0.0), np.arange(5))
    assert len(thin_nodes(np.zeros((0, 3)), 0.15)) == 0


class _MeanColour:
    """A stand-in encoder: the mean colour of each image."""

    dim = 3

    def encode(self, images):
        return np.asarray(images, np.float64).mean(axis=(1, 2))


def test_retrieve_the_closest_view_and_flag_weak_matches():
    emb = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.5, 0.5, 0.5]])
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.5], [2.0, 0.0, 1.0], [3.0, 0.0, 1.5]])
    index = ViewIndex(poses, np.array([0, 0, 1, 2]), emb, _MeanColour())
    target = np.zeros((4, 4, 3))
    target[..., 1] = 1.0
    m = retrieve(index, target, weak_ratio=0.5)
    assert (m.index, m.node, m.weak) == (1, 0, False) and m.cost == 0.0
    np.testing.assert_array_equal(m.pose, poses[1])
    grey = np.full((4, 4, 3), 0.4)
    assert retrieve(index, grey, weak_ratio=0.5).index == 3
    with pytest.raises(SplatplanError, match="must be"):
        retrieve(index, np.zeros((4, 4)))
