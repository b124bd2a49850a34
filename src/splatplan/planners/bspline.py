"""Uniform cubic B-splines as precomputed basis matrices (numpy reference, float64).

A curve with ``n_knots`` control points ("knots" in the MPPI literature, i.e. the B-spline
coefficients) ``c_0 .. c_{n-1}`` of dimension ``dim`` is sampled at ``T`` parameter values
``u_t = t / (T - 1)``, ``t = 0 .. T-1``, ``u`` in [0, 1], as one matrix product:

    samples = basis @ knots          # (T, n) @ (..., n, dim) -> (..., T, dim)

Endpoint handling
-----------------
* ``clamped=True`` (default): the *open uniform* knot vector ``[0,0,0,0, 1/m, ..., (m-1)/m,
  1,1,1,1]`` (``m = n - 3`` segments, interior knots uniformly spaced). The curve **interpolates
  the first and the last control point** (``samples[0] == c_0``, ``samples[-1] == c_{n-1}``) and
  is tangent to ``c_1 - c_0`` / ``c_{n-1} - c_{n-2}`` there. Fixing ``c_0`` and ``c_{n-1}``
  therefore fixes a path's endpoints exactly; this is what the path refinement uses. Needs
  ``n_knots >= 4``.
* ``clamped=False``: the plain uniform knot vector ``t_i = (i - 3) / (n - 3)``, domain [0, 1]
  (= [t_3, t_n]). Every segment is the textbook uniform cubic B-spline; endpoints are *not*
  interpolated (the curve starts at ``(c_0 + 4 c_1 + c_2) / 6``).

Both are partitions of unity (rows of ``basis`` sum to 1) with non-negative entries, so each
sample is a convex combination of 4 consecutive control points: clipping the control points to a
box keeps the whole curve inside the box (MPPI uses this to enforce control bounds).

Derivatives are taken with respect to the normalised parameter ``u``; for a curve spanning a
duration ``D`` (seconds, or arc length) divide the first derivative by ``D`` and the second by
``D**2``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import SplatplanError


def knot_vector(n_knots: int, degree: int = 3, clamped: bool = True) -> np.ndarray:
    """The B-spline knot vector (length ``n_knots + degree + 1``) on the parameter domain [0, 1].

    Args:
        n_knots: number of control points n (>= degree + 1).
        degree: polynomial degree p (3 = cubic).
        clamped: open uniform (endpoint-interpolating) vector if True, plain uniform otherwise.
    """
    p = int(degree)
    if n_knots < p + 1:
        raise SplatplanError(f"a degree-{p} B-spline needs at least {p + 1} control points, got {n_knots}")
    m = n_knots - p  # number of polynomial segments
    if clamped:
        inner = np.arange(1, m) / m
        return np.concatenate([np.zeros(p + 1), inner, np.ones(p + 1)])
    return (np.arange(n_knots + p + 1) - p) / m


def _basis_recursive(t: np.ndarray, p: int, u: np.ndarray, n: int, deriv: int) -> np.ndarray:
    """Cox-de Boor basis N_{i,p}(u) (deriv = 0) or its derivatives, (len(u), n)."""
    if deriv > 0:
        # N'_{i,p} = p/(t_{i+p}-t_i) N_{i,p-1} - p/(t_{i+p+1}-t_{i+1}) N_{i+1,p-1}
        lower = _basis_recursive(t, p - 1, u, n + 1, deriv - 1)  # (T, n+1)
        out = np.zeros((u.size, n))
        for i in range(n):
            d1 = t[i + p] - t[i]
            d2 = t[i + p + 1] - t[i + 1]
            if d1 > 0:
                out[:, i] += p / d1 * lower[:, i]
            if d2 > 0:
                out[:, i] -= p / d2 * lower[:, i + 1]
        return out
    # degree 0: indicator of [t_i, t_{i+1}); the last non-empty span also owns u = t_end.
    n0 = n + p
    b = np.zeros((u.size, n0))
    last = np.max(np.nonzero(t[1:] > t[:-1])[0])  # index of the last non-empty span
    for i in range(n0):
        if t[i + 1] > t[i]:
            inside = (u >= t[i]) & (u < t[i + 1])
            if i == last:
                inside |= u == t[i + 1]
            b[:, i] = inside
    for q in range(1, p + 1):
        nb = np.zeros((u.size, n0 - q))
        for i in range(n0 - q):
            d1 = t[i + q] - t[i]
            d2 = t[i + q + 1] - t[i + 1]
            if d1 > 0:
                nb[:, i] += (u - t[i]) / d1 * b[:, i]
            if d2 > 0:
                nb[:, i] += (t[i + q + 1] - u) / d2 * b[:, i + 1]
        b = nb
    return b[:, :n]


def bspline_basis(
    n_knots: int,
    u: int | np.ndarray,
    degree: int = 3,
    clamped: bool = True,
    derivative: int = 0,
) -> np.ndarray:
    """Basis matrix B (T, n_knots) with ``samples = B @ knots``.

    Args:
        n_knots: number of control points.
        u: either the number of samples T (then ``u = linspace(0, 1, T)``) or explicit parameter
            values in [0, 1], shape (T,).
        degree: spline degree (3 = cubic).
        clamped: endpoint handling, see the module docstring.
        derivative: 0 for values, 1 / 2 for d/du and d^2/du^2 of the basis.

    Returns:
        float64 (T, n_knots).
    """
    uu = np.linspace(0.0, 1.0, int(u)) if np.ndim(u) == 0 else np.asarray(u, dtype=np.float64).reshape(-1)
    if uu.size and (uu.min() < -1e-12 or uu.max() > 1 + 1e-12):
        raise SplatplanError("B-spline parameters u must lie in [0, 1]")
    uu = np.clip(uu, 0.0, 1.0)
    if derivative < 0 or derivative > degree:
        raise SplatplanError(f"derivative order must be in [0, {degree}], got {derivative}")
    t = knot_vector(n_knots, degree, clamped)
    return _basis_recursive(t, degree, uu, n_knots, derivative)


def bspline_eval(knots: np.ndarray, basis: np.ndarray) -> np.ndarray:
    """Samples of one or many curves.

    Args:
        knots: control points (..., n_knots, dim).
        basis: (T, n_knots) from :func:`bspline_basis` (any derivative order).

    Returns:
        (..., T, dim) samples.
    """
    return np.matmul(basis, knots)  # (T, n) @ (..., n, D) -> (..., T, D)


def resample_polyline(points: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` points uniformly spaced in arc length along a polyline (P, dim) -> ((n, dim), u (n,)).

    ``u`` is the normalised arc length in [0, 1] of each returned point. A zero-length polyline
    returns ``n`` copies of its first point.
    """
    pts = np.asarray(points, dtype=np.float64)
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    u = np.linspace(0.0, 1.0, n)
    if s[-1] <= 0:
        return np.repeat(pts[:1], n, axis=0), u
    target = u * s[-1]
    out = np.stack([np.interp(target, s, pts[:, d]) for d in range(pts.shape[1])], axis=1)
    return out, u


def fit_bspline(
    points: np.ndarray,
    n_knots: int,
    fix_endpoints: bool = True,
    n_fit: int | None = None,
    clamped: bool = True,
) -> np.ndarray:
    """Least-squares control points of a clamped cubic B-spline approximating a polyline.

    The polyline is parametrised by normalised arc length (chord-length parametrisation):
    ``n_fit`` points uniformly spaced in arc length are fitted in the least-squares sense.
    With ``fix_endpoints`` (requires ``clamped``) ``c_0`` / ``c_{n-1}`` are set to the polyline's
    first / last point and only the interior control points are solved for, so the spline starts
    and ends exactly at the polyline's endpoints.

    Args:
        points: polyline vertices (P, dim), P >= 2.
        n_knots: number of control points (>= 4).
        fix_endpoints: pin the first and last control points to the endpoints.
        n_fit: number of fitting samples (default ``max(8 * n_knots, 64)``).
        clamped: knot-vector type (see module docstring).

    Returns:
        float64 (n_knots, dim) control points.
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[0] < 2:
        raise SplatplanError(f"fit_bspline needs a polyline of shape (P >= 2, dim), got {pts.shape}")
    if fix_endpoints and not clamped:
        raise SplatplanError("fix_endpoints needs a clamped spline (only clamped splines interpolate endpoints)")
    n_fit = int(n_fit or max(8 * n_knots, 64))
    samples, u = resample_polyline(pts, n_fit)  # (F, dim), (F,)
    basis = bspline_basis(n_knots, u, clamped=clamped)  # (F, n)
    if not fix_endpoints:
        knots, *_ = np.linalg.lstsq(basis, samples, rcond=None)
        return knots
    knots = np.empty((n_knots, pts.shape[1]))
    knots[0], knots[-1] = pts[0], pts[-1]
    rhs = samples - np.outer(basis[:, 0], knots[0]) - np.outer(basis[:, -1], knots[-1])
    inner, *_ = np.linalg.lstsq(basis[:, 1:-1], rhs, rcond=None)
    knots[1:-1] = inner
    return knots


@dataclass
class UniformBSpline:
    """Precomputed bases of a cubic B-spline with ``n_knots`` control points sampled at ``n_samples``.

    ``shift_matrix`` implements a warm start by one sample step: ``S @ knots`` are the
    least-squares control points of the curve ``v(t) = c(t + 1)`` (sample index shifted by one,
    the last sample held), i.e. the time-shifted nominal of a receding-horizon controller.
    """

    n_knots: int
    n_samples: int
    clamped: bool = True
    basis: np.ndarray = field(init=False, repr=False)  # (T, n)
    dbasis: np.ndarray = field(init=False, repr=False)  # (T, n), d/du
    shift_matrix: np.ndarray = field(init=False, repr=False)  # (n, n)

    def __post_init__(self) -> None:
        if self.n_samples < 2:
            raise SplatplanError(f"a B-spline needs at least 2 samples, got {self.n_samples}")
        u = np.linspace(0.0, 1.0, self.n_samples)
        self.basis = bspline_basis(self.n_knots, u, clamped=self.clamped)
        self.dbasis = bspline_basis(self.n_knots, u, clamped=self.clamped, derivative=1)
        u_next = np.minimum(u + 1.0 / (self.n_samples - 1), 1.0)
        shifted = bspline_basis(self.n_knots, u_next, clamped=self.clamped)  # (T, n)
        self.shift_matrix = np.linalg.pinv(self.basis) @ shifted

    def __call__(self, knots: np.ndarray) -> np.ndarray:
        """(..., n, dim) -> (..., T, dim)."""
        return bspline_eval(knots, self.basis)

    def derivative(self, knots: np.ndarray, duration: float = 1.0) -> np.ndarray:
        """d/dt of the samples for a curve spanning ``duration``: (..., n, dim) -> (..., T, dim)."""
        return bspline_eval(knots, self.dbasis) / float(duration)

    def shift(self, knots: np.ndarray) -> np.ndarray:
        """Warm-start control points: the curve advanced by one sample step (see class doc)."""
        return np.einsum("mn,...nd->...md", self.shift_matrix, knots)
