"""Device-resident API: numpy, torch and wp.array inputs give the same results; workspaces are
reused; invalid device inputs are flagged on the device; the checker's pool and grid cache."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from splatplan._warp import wp as _wp
from splatplan.errors import SplatplanError
from splatplan.metric import CollisionChecker, MetricConfig
from splatplan.scenes.splats import quat_to_rotmat

from .conftest import DEVICES, random_quats, random_scene

wp = _wp()
FIELDS = ("min_s2", "n_colliding", "in_collision", "softmin", "cost")


def _batch(rng, scene, shape=(6, 5, 2)):
    """(K, T, E) link batch near the splats, per-link semi-axes (E, 3) and quats (K, T, E, 4)."""
    n = int(np.prod(shape))
    c = scene.means[rng.integers(0, len(scene), n)] + rng.normal(0, 0.015, (n, 3))
    return c.reshape(shape + (3,)), random_quats(rng, n).reshape(shape + (4,)), rng.uniform(0.01, 0.03, (shape[-1], 3))


def _assert_same(got: dict, want, to_np):
    for k in FIELDS:
        g = to_np(getattr(got, k))
        w = getattr(want, k)
        assert g.shape == w.shape, k
        assert g.dtype == w.dtype, k
        np.testing.assert_allclose(g, w, rtol=1e-5, atol=1e-6, err_msg=k)


@pytest.fixture(scope="module")
def scene():
    return random_scene(np.random.default_rng(21), 800)


def _torch_devices():
    torch = pytest.importorskip("torch")
    return [d for d in DEVICES if d == "cpu" or torch.cuda.is_available()]


@pytest.mark.parametrize("device", DEVICES)
def test_torch_inputs_match_numpy(scene, device):
    torch = pytest.importorskip("torch")
    if device != "cpu" and not torch.cuda.is_available():
        pytest.skip("torch without CUDA")
    rng = np.random.default_rng(1)
    c, q, a = _batch(rng, scene)
    ch = CollisionChecker(scene, n_sigma=1.0, device=device)
    want = ch.query(c, q, a)
    tdev = torch.device("cpu" if device == "cpu" else device)
    for dtype in (torch.float32, torch.float64):
        tc, tq = torch.tensor(c, dtype=dtype, device=tdev), torch.tensor(q, dtype=dtype, device=tdev)
        got = ch.query(tc, tq, torch.tensor(a, dtype=dtype, device=tdev))
        assert isinstance(got.min_s2, torch.Tensor) and got.min_s2.device == tdev and got.in_collision.dtype == torch.bool
        _assert_same(got, want, lambda x: x.cpu().numpy())
        hit = ch.collides(tc, tq, a)  # host semi-axes with device centres
        assert isinstance(hit, torch.Tensor) and hit.shape == c.shape[:-1]
        np.testing.assert_array_equal(hit.cpu().numpy(), ch.collides(c, q, a))
    # per-query quats shaped (E, 4) broadcast over (K, T); a non-tiling torch shape is expanded on the device
    qe = q[0, 0]  # (E, 4)
    np.testing.assert_array_equal(ch.query(torch.tensor(c, device=tdev), torch.tensor(qe, device=tdev), a).n_colliding.cpu().numpy(), ch.query(c, qe, a).n_colliding)
    ak = a[None, None, :, :] * np.linspace(1, 1.5, 6)[:, None, None, None]  # (K, 1, E, 3): does not tile
    np.testing.assert_array_equal(ch.collides(torch.tensor(c, device=tdev), None, torch.tensor(ak, device=tdev)).cpu().numpy(), ch.collides(c, None, ak))


@pytest.mark.parametrize("device", DEVICES)
def test_warp_inputs_match_numpy(scene, device):
    rng = np.random.default_rng(2)
    c, q, a = _batch(rng, scene)
    ch = CollisionChecker(scene, n_sigma=1.0, device=device)
    want = ch.query(c, q, a)
    f32 = np.float32
    # float32 (..., 3) arrays and vec3 / vec4 arrays (flat batch)
    got = ch.query(wp.array(c.astype(f32), device=device), wp.array(q.astype(f32), device=device), wp.array(a.astype(f32), device=device))
    assert isinstance(got.min_s2, wp.array) and got.min_s2.shape == c.shape[:-1] and got.in_collision.dtype == wp.bool
    _assert_same(got, want, lambda x: x.numpy())
    flat = ch.query(
        wp.array(c.reshape(-1, 3).astype(f32), dtype=wp.vec3, device=device),
        wp.array(q.reshape(-1, 4).astype(f32), dtype=wp.vec4, device=device),
        wp.array(np.tile(a, (30, 1)).astype(f32), dtype=wp.vec3, device=device),
    )
    assert flat.min_s2.shape == (60,)
    np.testing.assert_allclose(flat.min_s2.numpy(), want.min_s2.reshape(-1), rtol=1e-5, atol=1e-6)
    hit = ch.collides(wp.array(c.astype(f32), device=device), None, 0.02)
    np.testing.assert_array_equal(hit.numpy(), ch.collides(c, None, 0.02))
    # rotation matrices instead of quaternions, on both paths
    r = quat_to_rotmat(q.reshape(-1, 4)).reshape(q.shape[:-1] + (3, 3))
    by_rot = ch.query(wp.array(c.astype(f32), device=device), None, rots=wp.array(r.astype(f32), dtype=wp.mat33, device=device), semi_axes=a)
    np.testing.assert_allclose(by_rot.min_s2.numpy(), want.min_s2, rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(ch.query(c, None, rots=r, semi_axes=a).min_s2, want.min_s2, rtol=1e-4, atol=1e-5)
    with pytest.raises(SplatplanError, match="dtype"):
        ch.query(wp.array(c.reshape(-1, 3), dtype=wp.vec3d, device=device), None, 0.02)
    with pytest.raises(SplatplanError, match="tile"):
        ch.query(wp.array(c.astype(f32), device=device), None, wp.array(np.ones((4, 3), f32) * 0.02, device=device))


@pytest.mark.parametrize("device", DEVICES)
def test_workspace_buffers_are_reused(scene, device):
    rng = np.random.default_rng(3)
    ch = CollisionChecker(scene, n_sigma=1.0, device=device)
    ws = ch.workspace(500)
    ptr = ws.min_s2.ptr
    for b in (500, 200, 500):
        c = scene.means[rng.integers(0, len(scene), b)] + rng.normal(0, 0.01, (b, 3))
        cw = wp.array(c.astype(np.float32), dtype=wp.vec3, device=device)
        got = ch.query(cw, None, 0.02, out=ws)
        assert got.min_s2.ptr == ptr  # results live in the workspace
        want = ch.query(c, None, 0.02)
        np.testing.assert_allclose(got.min_s2.numpy(), want.min_s2, rtol=1e-6)
        np.testing.assert_array_equal(ch.collides(cw, None, 0.02, out=ws).numpy(), want.in_collision)
    assert ws.reallocations == 1 and ws.capacity == 500 and ws.min_s2.ptr == ptr
    ch.query(np.zeros((600, 3)), None, 0.02, out=ws)  # grows once
    assert ws.reallocations == 2 and ws.capacity >= 600


@pytest.mark.parametrize("device", DEVICES)
def test_invalid_device_queries_are_flagged_not_free(scene, device):
    c = np.tile(scene.means[:1], (5, 1)).astype(np.float32)  # every query on a splat: colliding
    c[2, 1] = np.nan
    q = random_quats(np.random.default_rng(0), 5).astype(np.float32)
    q[4] = 0.0  # zero quaternion
    ch = CollisionChecker(scene, n_sigma=1.0, device=device)
    cw, qw = wp.array(c, dtype=wp.vec3, device=device), wp.array(q, dtype=wp.vec4, device=device)
    res = ch.query(cw, qw, 0.02)
    assert res.in_collision.numpy().all()
    n = res.n_colliding.numpy()
    assert n[2] == -1 and n[4] == -1 and np.isnan(res.min_s2.numpy()[[2, 4]]).all() and (n[[0, 1, 3]] > 0).all()
    assert ch.collides(cw, qw, 0.02).numpy().all()
    with pytest.raises(SplatplanError, match="query 2"):
        ch.query(cw, qw, 0.02, validate=True)
    with pytest.raises(SplatplanError, match="query 2"):
        ch.collides(cw, qw, 0.02, validate=True)
    with pytest.raises(SplatplanError, match="NaN"):  # the numpy adapter keeps today's host checks
        ch.query(c, q, 0.02)
    ok = ch.query(cw[:2], None, 0.02, validate=True)
    assert ok.in_collision.numpy().all()


def test_reference_backend_accepts_device_inputs(scene):
    torch = pytest.importorskip("torch")
    rng = np.random.default_rng(4)
    c, q, a = _batch(rng, scene, (3, 4, 2))
    ref = CollisionChecker(scene, n_sigma=1.0, backend="reference")
    got = ref.query(torch.tensor(c), torch.tensor(q), a)
    assert isinstance(got.min_s2, torch.Tensor)
    np.testing.assert_array_equal(got.n_colliding.numpy(), ref.query(c, q, a).n_colliding)
    hit = ref.collides(wp.array(c.astype(np.float32)), None, 0.02)
    assert isinstance(hit, wp.array) and hit.shape == (3, 4, 2)


def test_grid_cache_from_two_threads(scene):
    """Two threads querying one checker with different configs (so grids are built concurrently)."""
    rng = np.random.default_rng(5)
    c = scene.means[rng.integers(0, len(scene), 3000)] + rng.normal(0, 0.01, (3000, 3))
    base = CollisionChecker(scene, n_sigma=0.5)
    variants = [base.with_config(n_sigma=ns, s2_cap=cap) for ns, cap in ((0.5, 4.0), (2.0, 9.0), (1.0, 1.0), (3.0, 4.0))]
    want = [CollisionChecker(scene, config=v.config).query(c, None, 0.02) for v in variants]
    got: dict = {}
    errors = []

    def work(i):
        try:
            for rep in range(3):
                for j in (i, (i + 1) % 4, (i + 2) % 4):
                    got[(i, j, rep)] = variants[j].query(c, None, 0.02).min_s2
        except Exception as exc:  # pragma: no cover - reported below
            errors.append(exc)

    ts = [threading.Thread(target=work, args=(i,)) for i in range(2)]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    assert not errors
    for (_, j, _), v in got.items():
        np.testing.assert_array_equal(v, want[j].min_s2)


def test_thread_pool_belongs_to_the_checker(scene):
    rng = np.random.default_rng(6)
    c = rng.uniform(-0.3, 0.3, (2000, 3))
    with CollisionChecker(scene, n_sigma=1.0) as ch:
        first = ch.query(c, None, 0.02).min_s2
        impl = ch._impl
    assert impl._pool is None  # closed on exit
    np.testing.assert_array_equal(ch.query(c, None, 0.02).min_s2, first)  # still usable: a new pool
    ch.close()
    assert impl._pool is None
