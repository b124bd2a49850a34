"""B-spline basis: partition of unity, endpoint interpolation, derivatives, fitting, warm-start shift."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import BSpline

from splatplan.errors import SplatplanError
from splatplan.planners.bspline import UniformBSpline, bspline_basis, bspline_eval, fit_bspline, knot_vector


@pytest.mark.parametrize("clamped", [True, False])
@pytest.mark.parametrize("n", [4, 5, 9])
def test_partition_of_unity_and_nonnegative(n, clamped):
    b = bspline_basis(n, 57, clamped=clamped)
    assert b.shape == (57, n)
    np.testing.assert_allclose(b.sum(axis=1), 1.0, atol=1e-12)
    assert b.min() >= -1e-14
    # each row touches at most 4 consecutive control points
    assert ((b > 1e-12).sum(axis=1) <= 4).all()


@pytest.mark.parametrize("clamped", [True, False])
@pytest.mark.parametrize("deriv", [0, 1, 2])
def test_matches_scipy(clamped, deriv):
    n = 7
    u = np.linspace(0, 1, 41)
    t = knot_vector(n, 3, clamped)
    c = np.random.default_rng(0).normal(size=(n, 2))
    ref = BSpline(t, c, 3, extrapolate=False).derivative(deriv)(u) if deriv else BSpline(t, c, 3)(u)
    np.testing.assert_allclose(bspline_basis(n, u, clamped=clamped, derivative=deriv) @ c, ref, atol=1e-9)


def test_clamped_interpolates_endpoints():
    c = np.random.default_rng(1).normal(size=(3, 6, 2))  # batch of 3 curves
    out = bspline_eval(c, bspline_basis(6, 30))
    assert out.shape == (3, 30, 2)
    np.testing.assert_allclose(out[:, 0], c[:, 0], atol=1e-12)
    np.testing.assert_allclose(out[:, -1], c[:, -1], atol=1e-12)
    # unclamped: the uniform cubic starts at (c0 + 4 c1 + c2) / 6
    out_u = bspline_eval(c, bspline_basis(6, 30, clamped=False))
    np.testing.assert_allclose(out_u[:, 0], (c[:, 0] + 4 * c[:, 1] + c[:, 2]) / 6, atol=1e-12)


@pytest.mark.parametrize("clamped", [True, False])
def test_derivative_vs_finite_differences(clamped):
    n = 8
    c = np.random.default_rng(2).normal(size=(n, 3))
    u = np.linspace(0.013, 0.987, 19)  # away from the knots (f''' jumps there)
    h = 1e-6
    f = lambda uu: bspline_basis(n, uu, clamped=clamped) @ c  # noqa: E731
    fd = (f(u + h) - f(u - h)) / (2 * h)
    np.testing.assert_allclose(bspline_basis(n, u, clamped=clamped, derivative=1) @ c, fd, atol=1e-5)
    fd2 = (f(u + 1e-4) - 2 * f(u) + f(u - 1e-4)) / 1e-8
    np.testing.assert_allclose(bspline_basis(n, u, clamped=clamped, derivative=2) @ c, fd2, atol=1e-3, rtol=1e-4)
    sp = UniformBSpline(n, 50, clamped=clamped)
    np.testing.assert_allclose(sp.derivative(c, duration=2.0), (sp.dbasis @ c) / 2.0)


def test_fit_polyline_fixed_endpoints_and_exact_on_splines():
    # a polyline that *is* a straight line is reproduced exactly, endpoints pinned
    line = np.linspace([0.0, 0.0, 0.06], [1.0, 0.5, 0.06], 7)
    k = fit_bspline(line, 6)
    s = bspline_basis(6, 100) @ k
    np.testing.assert_allclose(s[0], line[0], atol=1e-12)
    np.testing.assert_allclose(s[-1], line[-1], atol=1e-12)
    d = np.cross(s - line[0], line[-1] - line[0])
    assert np.abs(d).max() < 1e-9
    # a zig-zag: endpoints still exact, fit residual smaller with more knots
    zig = np.array([[0, 0], [0.1, 0.1], [0.2, 0], [0.3, 0.1], [0.4, 0]], float)
    errs = []
    for n in (5, 12, 30):
        kk = fit_bspline(zig, n)
        np.testing.assert_allclose(kk[0], zig[0])
        np.testing.assert_allclose(kk[-1], zig[-1])
        from splatplan.planners.bspline import resample_polyline

        pts, u = resample_polyline(zig, 200)
        errs.append(np.abs(bspline_basis(n, u) @ kk - pts).max())
    assert errs[0] > errs[1] > errs[2]


def test_shift_matrix_advances_curve():
    sp = UniformBSpline(6, 40)
    c = np.random.default_rng(3).normal(size=(2, 6, 2))
    shifted = sp(sp.shift(c))
    orig = sp(c)
    # least squares: the shifted curve tracks c(t + 1) much better than the unshifted one
    err = np.abs(shifted[:, :-1] - orig[:, 1:]).mean()
    err_noshift = np.abs(orig[:, :-1] - orig[:, 1:]).mean()
    assert err < 0.6 * err_noshift
    # a slowly varying curve is shifted almost exactly
    smooth = np.linspace(0.0, 1.0, 6)[:, None] ** 2 * np.array([[1.0, -0.5]])
    e = np.abs(sp(sp.shift(smooth))[:-5] - sp(smooth)[1:-4]).max()
    assert e < 0.01
    # a constant curve stays constant
    const = np.ones((6, 2)) * 0.3
    np.testing.assert_allclose(sp(sp.shift(const)), 0.3, atol=1e-12)


def test_bad_arguments():
    with pytest.raises(SplatplanError):
        bspline_basis(3, 10)
    with pytest.raises(SplatplanError):
        bspline_basis(5, np.array([0.0, 1.5]))
    with pytest.raises(SplatplanError):
        fit_bspline(np.zeros((1, 3)), 5)
