"""Every baseline: sanity (far = free, at a mean = collision), orientation, invariances, inputs."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from splatplan.baselines import BASELINES, as_scene_tensors
from splatplan.errors import SplatplanError
from splatplan.scenes.splats import Splats, quat_to_rotmat

NAMES = sorted(BASELINES)


def _scene(n: int = 50, seed: int = 0) -> Splats:
    rng = np.random.default_rng(seed)
    return Splats(
        means=rng.uniform(-0.3, 0.3, (n, 3)),
        quats=Rotation.random(n, random_state=seed).as_quat()[:, [3, 0, 1, 2]],
        scales=rng.uniform(0.003, 0.012, (n, 3)),
        opacities=rng.uniform(0.8, 1.0, n),
        colors=np.zeros((n, 3)),
    )


@pytest.mark.parametrize("name", NAMES)
def test_far_is_free_and_mean_is_collision(name):
    info = BASELINES[name]
    sp = _scene()
    r = 0.015
    centers = np.concatenate([sp.means[:5], [[5.0, 5.0, 5.0], [-3.0, 4.0, 0.0]]])
    score = info.score(sp, centers, r)
    col = info.collision_from_score(score)
    assert col.tolist() == [True] * 5 + [False] * 2
    # Oriented score: larger = collision, consistent with the native decision.
    cs = info.collision_score(sp, centers, r)
    assert cs[:5].min() > cs[5:].max()
    obj = info.cls(sp, "cpu")
    np.testing.assert_array_equal(obj.in_collision(centers, r), col)
    np.testing.assert_allclose(obj.collision_score(centers, r), cs)


@pytest.mark.parametrize("name", NAMES)
def test_rigid_transform_invariance(name):
    # float64 arrays (a Splats object would round to float32 and blur the comparison).
    s32 = _scene(30, seed=1)
    sp = {k: getattr(s32, k).astype(np.float64) for k in ("means", "quats", "scales", "opacities")}
    rng = np.random.default_rng(2)
    centers = rng.uniform(-0.3, 0.3, (20, 3))
    rot = Rotation.random(random_state=3)
    t = np.array([0.7, -0.2, 1.1])
    q = (rot * Rotation.from_quat(sp["quats"][:, [1, 2, 3, 0]])).as_quat()[:, [3, 0, 1, 2]]
    moved = dict(sp, means=rot.apply(sp["means"]) + t, quats=q)
    info = BASELINES[name]
    a = info.score(sp, centers, 0.02, dtype=torch.float64)
    b = info.score(moved, rot.apply(centers) + t, 0.02, dtype=torch.float64)
    np.testing.assert_allclose(a, b, rtol=1e-7, atol=1e-10)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda v: np.linalg.norm(v) > 1e-3))
def test_torch_rotations_match_numpy_wxyz(q):
    q = np.array(q)[None]
    st_ = as_scene_tensors({"means": np.zeros((1, 3)), "quats": q, "scales": np.ones((1, 3))}, dtype=torch.float64)
    np.testing.assert_allclose(st_.rotations.numpy(), quat_to_rotmat(q), atol=1e-12)


def test_bad_inputs_raise_clear_errors():
    sp = _scene(5)
    with pytest.raises(SplatplanError, match="radius"):
        BASELINES["atlasnav"].score(sp, np.zeros((1, 3)), 0.0)
    with pytest.raises(SplatplanError, match=r"shape \(B, 3\)"):
        BASELINES["splatnav"].score(sp, np.zeros((2, 2)), 0.1)
    with pytest.raises(SplatplanError, match="zero quaternion"):
        as_scene_tensors({"means": np.zeros((1, 3)), "quats": np.zeros((1, 4)), "scales": np.ones((1, 3))})
    with pytest.raises(SplatplanError, match="negative scales"):
        as_scene_tensors({"means": np.zeros((1, 3)), "quats": np.array([[1.0, 0, 0, 0]]), "scales": -np.ones((1, 3))})


def test_registry_batches():
    assert {k: v.native_batch for k, v in BASELINES.items()} == {"splatnav": 1, "safersplat": 1, "atlasnav": 4096, "splanning": 4096}
