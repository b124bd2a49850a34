"""ROW_CLIP of the full kernel: the x interval of a cell row never misses a point of the link's
s2 <= s2_cut ellipsoid inside the query ball (random ellipsoids and tubes, sampled points)."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan._warp import wp as _wp
from splatplan.metric.wp_metric_kernel import row_x_span, schur_form

wp = _wp()


@wp.kernel
def _spans(
    c: wp.array(dtype=wp.vec3),
    a: wp.array(dtype=wp.mat33),
    s_cut: wp.array(dtype=float),
    cb: wp.array(dtype=wp.vec3),
    rb: wp.array(dtype=float),
    tube: wp.array(dtype=wp.vec4),  # y0, y1, z0, z1
    ball_only: int,
    out: wp.array(dtype=wp.vec2),
):
    i = wp.tid()
    e1, e2 = schur_form(a[i])
    t = tube[i]
    xl, xh = row_x_span(c[i], e1, e2, s_cut[i], cb[i], rb[i], t[0], t[1], t[2], t[3], ball_only != 0)
    out[i] = wp.vec2(xl, xh)


def _random_rot(rng, n):
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        1,
    )


@pytest.mark.parametrize("ball_only", [False, True])
def test_row_span_holds_every_point(ball_only):
    rng = np.random.default_rng(7)
    n = 400
    axes = rng.uniform(0.02, 0.3, size=(n, 3))
    if ball_only:
        axes[:] = axes[:, :1]
    rot = _random_rot(rng, n)
    a = np.einsum("nij,nj,nkj->nik", rot, 1.0 / axes**2, rot)  # R diag(1/a^2) R^T
    c = rng.uniform(-1, 1, size=(n, 3))
    s_cut = rng.uniform(0.5, 6.0, size=n)
    rb = np.sqrt(s_cut) * axes.max(1) * rng.uniform(0.6, 1.2, size=n)
    cb = c + rng.normal(scale=0.05, size=(n, 3))
    w = rng.uniform(0.02, 0.2, size=n)
    y0 = c[:, 1] + rng.uniform(-1.2, 1.2, size=n) * np.sqrt(s_cut) * axes.max(1)
    z0 = c[:, 2] + rng.uniform(-1.2, 1.2, size=n) * np.sqrt(s_cut) * axes.max(1)
    tube = np.stack([y0, y0 + w, z0, z0 + w], 1)
    out = wp.empty(n, dtype=wp.vec2, device="cpu")
    f32 = lambda v, t: wp.array(np.asarray(v, np.float32), dtype=t, device="cpu")  # noqa: E731
    wp.launch(_spans, dim=n, inputs=[f32(c, wp.vec3), f32(a, wp.mat33), f32(s_cut, float), f32(cb, wp.vec3), f32(rb, float), f32(tube, wp.vec4), int(ball_only), out], device="cpu")
    span = out.numpy()
    n_hit = 0
    for i in range(n):
        # points of the ellipsoid (p - c)^T a (p - c) <= s_cut: c + R diag(axes) sqrt(s_cut) u, |u| <= 1
        u = rng.normal(size=(20000, 3))
        u *= (rng.uniform(size=(20000, 1)) ** (1 / 3)) / np.linalg.norm(u, axis=1, keepdims=True)
        p = c[i] + (u * axes[i] * np.sqrt(s_cut[i])) @ rot[i].T
        keep = (p[:, 1] >= y0[i]) & (p[:, 1] <= y0[i] + w[i]) & (p[:, 2] >= z0[i]) & (p[:, 2] <= z0[i] + w[i])
        keep &= np.linalg.norm(p - cb[i], axis=1) <= rb[i]
        if not keep.any():
            continue
        n_hit += 1
        xl, xh = span[i]
        assert xl <= xh, f"row {i}: span empty but {keep.sum()} points of the ellipsoid lie in the tube"
        x = p[keep, 0]
        assert x.min() >= xl - 1e-6 and x.max() <= xh + 1e-6, (i, x.min(), x.max(), xl, xh)
    assert n_hit > 50  # the test exercised rows that hold points


def test_row_span_is_tight_for_an_axis_aligned_needle():
    """A needle along x through a tube around its axis: the span is its length, not its bounding ball's."""
    a = np.diag([1 / 0.3**2, 1 / 0.02**2, 1 / 0.02**2]).astype(np.float32)
    out = wp.empty(1, dtype=wp.vec2, device="cpu")
    wp.launch(
        _spans,
        dim=1,
        inputs=[
            wp.array([[0.0, 0.0, 0.0]], dtype=wp.vec3, device="cpu"),
            wp.array([a], dtype=wp.mat33, device="cpu"),
            wp.array([1.0], dtype=float, device="cpu"),
            wp.array([[0.0, 0.0, 0.0]], dtype=wp.vec3, device="cpu"),
            wp.array([10.0], dtype=float, device="cpu"),
            wp.array([[0.015, 0.05, -0.01, 0.01]], dtype=wp.vec4, device="cpu"),  # a tube beside the needle
            0,
            out,
        ],
        device="cpu",
    )
    xl, xh = out.numpy()[0]
    assert xl < -0.1 and xh > 0.1  # the needle crosses y = 0.015 over part of its length
    assert xh - xl < 0.6 * 1.02  # never more than the needle's length (2% margin)
