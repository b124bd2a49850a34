"""Shared helpers for the scene readers: activations, input checks and building a :class:`Splats`.

Every reader decodes its file into raw float arrays and hands them to :func:`build_splats`, which
applies the one policy the SPEC asks for: NaN/Inf values, zero quaternions and non-positive
scales are bad input. By default they raise :class:`SceneFormatError` naming the file, the field
and how many splats are affected; with ``drop_invalid=True`` the bad splats are dropped and the
count is recorded in ``splats.info["invalid_dropped"]``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import SceneFormatError
from .splats import SH_C0, Splats

#: Quaternions with a norm below this are treated as zero (no defined rotation).
ZERO_QUAT_EPS = 1e-8


def sigmoid(x: np.ndarray) -> np.ndarray:
    """Logistic function in float64, overflow-free; non-finite inputs give NaN.

    NaN rather than 0 or 1 for an infinite logit, so that :func:`build_splats` reports the file's
    Inf instead of silently accepting it.
    """
    x = np.asarray(x, dtype=np.float64)
    e = np.exp(-np.abs(x))  # in (0, 1], never overflows
    return np.where(np.isfinite(x), np.where(x >= 0, 1.0 / (1.0 + e), e / (1.0 + e)), np.nan)


def logit(p: np.ndarray, eps: float = 1e-7) -> np.ndarray:
    """Inverse of :func:`sigmoid`, with p clipped to [eps, 1 - eps] so the result is finite."""
    p = np.clip(np.asarray(p, dtype=np.float64), eps, 1.0 - eps)
    return np.log(p) - np.log1p(-p)


def sh_dc_to_color(f_dc: np.ndarray) -> np.ndarray:
    """RGB colour from the SH DC coefficient: 0.5 + C0 * f_dc (not clipped), shape (N, 3)."""
    return 0.5 + SH_C0 * np.asarray(f_dc, dtype=np.float64)


def color_to_sh_dc(color: np.ndarray) -> np.ndarray:
    """SH DC coefficient from RGB colour: (color - 0.5) / C0, shape (N, 3)."""
    return (np.asarray(color, dtype=np.float64) - 0.5) / SH_C0


def scene_error(path: str | Path, problem: str) -> SceneFormatError:
    """A :class:`SceneFormatError` whose message starts with the file name."""
    return SceneFormatError(f"{path}: {problem}")


def build_splats(
    path: str | Path,
    source_format: str,
    *,
    means: np.ndarray,  # (N, 3) scene units, file frame
    quats: np.ndarray,  # (N, 4) wxyz, any norm
    scales: np.ndarray,  # (N, 3) linear std (third column 0 for 2DGS)
    opacities: np.ndarray,  # (N,) activated, in [0, 1]
    colors: np.ndarray,  # (N, 3) RGB from SH DC
    sh_rest: np.ndarray | None = None,  # (N, K, 3)
    is_2d: bool = False,
    drop_invalid: bool = False,
) -> Splats:
    """Check decoded arrays for bad values, normalise the quaternions and build a :class:`Splats`.

    Args:
        path: the file the arrays came from (for messages).
        source_format: value for ``Splats.source_format``.
        means, quats, scales, opacities, colors, sh_rest: decoded arrays (see shapes above).
        is_2d: the file is a 2DGS file, so ``scales[:, 2] == 0`` is expected and allowed.
        drop_invalid: drop bad splats (counted in ``info["invalid_dropped"]``) instead of raising.

    Returns:
        The scene with unit quaternions (w >= 0) and opacities clipped to [0, 1].

    Raises:
        SceneFormatError: on an empty scene, or on NaN/Inf, zero quaternions or non-positive scales (unless
            ``drop_invalid``), naming the file, the field, the count and the first bad index.
    """
    means = np.asarray(means, dtype=np.float64)
    quats = np.asarray(quats, dtype=np.float64)
    scales = np.asarray(scales, dtype=np.float64)
    opacities = np.asarray(opacities, dtype=np.float64).reshape(-1)
    colors = np.asarray(colors, dtype=np.float64)
    n = means.shape[0]
    if n == 0:
        raise scene_error(path, "the file holds no splats")

    problems: list[tuple[str, np.ndarray]] = []  # (description, bad-row mask (N,))
    fields = {"means": means, "quats": quats, "scales": scales, "opacities": opacities, "colors": colors}
    if sh_rest is not None:
        fields["sh_rest"] = np.asarray(sh_rest, dtype=np.float64)
    for name, arr in fields.items():
        bad = ~np.isfinite(arr).reshape(n, -1).all(axis=1)
        if bad.any():
            problems.append((f"NaN/Inf in '{name}'", bad))
    with np.errstate(invalid="ignore"):
        qnorm = np.linalg.norm(quats, axis=1)  # (N,)
        zero_q = np.isfinite(qnorm) & (qnorm < ZERO_QUAT_EPS)
        if zero_q.any():
            problems.append(("a zero quaternion (no defined rotation)", zero_q))
        n_pos = 2 if is_2d else 3
        bad_s = (scales[:, :n_pos] <= 0).any(axis=1)
        bad_s &= np.isfinite(scales).all(axis=1)
        if bad_s.any():
            problems.append(("non-positive scales (linear std must be > 0)", bad_s))

    info: dict = {}
    keep = np.ones(n, dtype=bool)
    if problems:
        if not drop_invalid:
            desc, mask = problems[0]
            others = "; also " + ", ".join(d for d, _ in problems[1:]) if len(problems) > 1 else ""
            raise scene_error(
                path,
                f"{int(mask.sum())} of {n} splat(s) have {desc} (first at index {int(np.argmax(mask))}){others}. "
                "The file is corrupt or was written by a broken exporter; re-export it, or load with "
                "drop_invalid=True to drop these splats.",
            )
        for _, mask in problems:
            keep &= ~mask
        info["invalid_dropped"] = {d: int(m.sum()) for d, m in problems} | {"total": int((~keep).sum())}

    q = quats[keep] / qnorm[keep, None]
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    return Splats(
        means=means[keep],
        quats=q,
        scales=scales[keep],
        opacities=np.clip(opacities[keep], 0.0, 1.0),
        colors=colors[keep],
        sh_rest=None if sh_rest is None else fields["sh_rest"][keep],
        source_format=source_format,
        info=info,
    )
