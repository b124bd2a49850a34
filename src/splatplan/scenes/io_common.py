"""Shared helpers for the scene readers: activations, bounded decompression, input checks and
building a :class:`Splats`.

Every reader decodes its file into arrays of *activated* values (linear stds, opacities in
[0, 1], RGB) and hands them to :func:`build_splats`, which applies the one policy the SPEC asks
for: values that are NaN/Inf **after activation and conversion to float32** (an Inf in the file,
or a log-scale of 100 whose exp overflows float32), zero quaternions and non-positive scales are
bad input. By default they raise :class:`SceneFormatError` naming the file, the field, how many
splats are affected and the first bad row; with ``drop_invalid=True`` the bad splats are dropped
and the count is recorded in ``splats.info["invalid_dropped"]``.

Compressed inputs are decompressed incrementally into a buffer of the exact size the header
fixes (:func:`read_exact`), so a decompression bomb stops with an error as soon as its output
exceeds that size instead of filling memory.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Protocol

import numpy as np

from ..errors import SceneFormatError
from .splats import SH_C0, Splats

#: Quaternions with a norm below this are treated as zero (no defined rotation).
ZERO_QUAT_EPS = 1e-8
#: Rows per block when checking or converting large arrays (bounds temporary memory).
BLOCK_ROWS = 1 << 18
#: Decompressed bytes per read call of :func:`read_exact`.
READ_CHUNK = 1 << 22
#: Natural log of the largest float32: a log-scale above this overflows float32 when activated.
LOG_FLOAT32_MAX = float(np.log(np.finfo(np.float32).max))
#: A PLY field of the higher SH bands (INRIA and compressed PLY): ``f_rest_{c*K + j}`` is
#: coefficient j of colour channel c (**channel-major**), stored as ``sh_rest[:, j, c]``.
F_REST = re.compile(r"^f_rest_(\d+)$")


def sigmoid(x: np.ndarray) -> np.ndarray:
    """Logistic function in float64, overflow-free; non-finite inputs give NaN.

    NaN rather than 0 or 1 for an infinite logit, so that :func:`build_splats` reports the file's
    Inf instead of silently accepting it.
    """
    x = np.asarray(x, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        e = np.exp(-np.abs(x))  # in (0, 1], never overflows
        return np.where(np.isfinite(x), np.where(x >= 0, 1.0 / (1.0 + e), e / (1.0 + e)), np.nan)


def logit(p: np.ndarray, eps: float = 1e-7) -> np.ndarray:
    """Inverse of :func:`sigmoid`, with p clipped to [eps, 1 - eps] so the result is finite."""
    p = np.clip(np.asarray(p, dtype=np.float64), eps, 1.0 - eps)
    return np.log(p) - np.log1p(-p)


def exp_std(log_s: np.ndarray) -> np.ndarray:
    """Linear std from log std, float64; overflow gives Inf silently (reported by :func:`build_splats`)."""
    with np.errstate(over="ignore", invalid="ignore"):
        return np.exp(np.asarray(log_s, dtype=np.float64))


def sh_dc_to_color(f_dc: np.ndarray) -> np.ndarray:
    """RGB colour from the SH DC coefficient: 0.5 + C0 * f_dc (not clipped), shape (N, 3)."""
    with np.errstate(over="ignore", invalid="ignore"):
        return 0.5 + SH_C0 * np.asarray(f_dc, dtype=np.float64)


def color_to_sh_dc(color: np.ndarray) -> np.ndarray:
    """SH DC coefficient from RGB colour: (color - 0.5) / C0, shape (N, 3)."""
    return (np.asarray(color, dtype=np.float64) - 0.5) / SH_C0


def f_rest_layout(names: Iterable[str]) -> tuple[list[int], int | None]:
    """The sorted indices of the ``f_rest_*`` fields among ``names``, and K, the SH coefficients per
    channel they hold: 0 when there are none, None when the indices are not exactly 0..3K-1."""
    idx = sorted(int(m.group(1)) for f in names if (m := F_REST.match(f)))
    if idx != list(range(len(idx))) or len(idx) % 3:
        return idx, None
    return idx, len(idx) // 3


def fill_sh_rest(sh_rest: np.ndarray, rows: np.ndarray, decode: Callable[[np.ndarray], np.ndarray] | None = None) -> None:
    """Fill ``sh_rest`` (M, K, 3) in place from the channel-major ``f_rest_*`` fields of the
    structured ``rows`` (M,): ``f_rest_{c*K + j}`` -> ``sh_rest[:, j, c]``, each field passed
    through ``decode`` first when given (a quantised file)."""
    k = sh_rest.shape[1]
    for i in range(3 * k):
        col = rows[f"f_rest_{i}"]  # (M,)
        sh_rest[:, i % k, i // k] = col if decode is None else decode(col)


def scene_error(path: str | Path, problem: str) -> SceneFormatError:
    """A :class:`SceneFormatError` whose message starts with the file name."""
    return SceneFormatError(f"{path}: {problem}")


# ----------------------------------------------------------------------------- bounded reads
class _Readable(Protocol):
    def read(self, size: int = ..., /) -> bytes: ...


def read_exact(stream: _Readable, size: int, path: str | Path, what: str, *, allow_more: bool = False) -> np.ndarray:
    """Read exactly ``size`` bytes from a (decompressing) stream into a new uint8 array.

    The output buffer is allocated once at the exact size the caller derived from the header, and
    the stream is read in :data:`READ_CHUNK` pieces, so memory never exceeds that size however far
    the stream would inflate. Unless ``allow_more``, one more byte is then requested: if the stream
    has it, the input is rejected as larger than its header says (corrupt, or a decompression bomb).

    Args:
        stream: object with ``read(n)`` returning at most n bytes (``b""`` at the end).
        size: exact number of bytes expected.
        path: file name for messages.
        what: what is being read (for messages), e.g. "the gzip payload".
        allow_more: do not check for further bytes (the caller reads more from the stream).

    Returns:
        uint8 array of length ``size``.

    Raises:
        SceneFormatError: the stream ends early or holds more than ``size`` bytes, or the size
            cannot be allocated.
    """
    try:
        out = np.empty(size, dtype=np.uint8)
    except (MemoryError, ValueError):
        raise scene_error(path, f"{what} would need {size:,} bytes according to the header, more than this machine can allocate; the header is corrupt or the scene is too large") from None
    view = out.data  # (a memoryview of the bytes)
    pos = 0
    while pos < size:
        chunk = stream.read(min(READ_CHUNK, size - pos))
        if not chunk:
            raise scene_error(path, f"{what} ends after {pos:,} of the {size:,} bytes its header describes; the file is truncated or corrupt")
        view[pos : pos + len(chunk)] = chunk
        pos += len(chunk)
    if not allow_more and stream.read(1):
        raise scene_error(
            path,
            f"{what} decompresses to more than the {size:,} bytes its header fixes; the file is corrupt or a "
            "decompression bomb (stopped reading)",
        )
    return out


# ----------------------------------------------------------------------------- validation
def _bad_rows(arr: np.ndarray) -> np.ndarray:
    """(N,) bool: rows of ``arr`` (N, ...) holding a NaN/Inf, computed block by block."""
    n = arr.shape[0]
    bad = np.zeros(n, dtype=bool)
    flat = arr.reshape(n, -1)
    for a in range(0, n, BLOCK_ROWS):
        bad[a : a + BLOCK_ROWS] = ~np.isfinite(flat[a : a + BLOCK_ROWS]).all(axis=1)
    return bad


def as_float32(arr: np.ndarray) -> np.ndarray:
    """``arr`` as float32 (no copy when it already is); values beyond float32 become Inf silently."""
    with np.errstate(over="ignore", invalid="ignore"):
        return np.asarray(arr, dtype=np.float32)


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
    activation: dict[str, str] | None = None,
) -> Splats:
    """Check decoded arrays for bad values, normalise the quaternions and build a :class:`Splats`.

    Arrays are converted to float32 first (no copy when they already are), so a value that is
    finite in the file but overflows float32 after activation is caught here.

    Args:
        path: the file the arrays came from (for messages).
        source_format: value for ``Splats.source_format``.
        means, quats, scales, opacities, colors, sh_rest: decoded arrays (see shapes above).
        is_2d: the file is a 2DGS file, so ``scales[:, 2] == 0`` is expected and allowed.
        drop_invalid: drop bad splats (counted in ``info["invalid_dropped"]``) instead of raising.
        activation: per field, how the reader computed it from the file (e.g.
            ``{"scales": "exp(scale_*)"}``); quoted in the message when that field is non-finite.

    Returns:
        The scene with unit quaternions (w >= 0) and opacities clipped to [0, 1].

    Raises:
        SceneFormatError: on an empty scene, or on NaN/Inf, zero quaternions or non-positive scales (unless
            ``drop_invalid``), naming the file, the field, the count and the first bad index.
    """
    activation = activation or {}
    fields = {
        "means": as_float32(means),
        "quats": as_float32(quats),
        "scales": as_float32(scales),
        "opacities": as_float32(opacities).reshape(-1),
        "colors": as_float32(colors),
    }
    if sh_rest is not None:
        fields["sh_rest"] = as_float32(sh_rest)
    n = fields["means"].shape[0]
    if n == 0:
        raise scene_error(path, "the file holds no splats")

    problems: list[tuple[str, str, np.ndarray]] = []  # (description, hint, bad-row mask (N,))
    for name, arr in fields.items():
        bad = _bad_rows(arr)
        if bad.any():
            hint = f" after activation ({activation[name]}, which must be finite in float32)" if name in activation else ""
            problems.append((f"NaN/Inf in '{name}'", hint, bad))
    quats32 = fields["quats"]
    qnorm = np.empty(n, dtype=np.float64)  # (N,) computed in float64, block by block
    with np.errstate(invalid="ignore", over="ignore"):
        for a in range(0, n, BLOCK_ROWS):
            qb = quats32[a : a + BLOCK_ROWS].astype(np.float64)
            qnorm[a : a + BLOCK_ROWS] = np.sqrt(np.einsum("ij,ij->i", qb, qb))
    zero_q = np.isfinite(qnorm) & (qnorm < ZERO_QUAT_EPS)
    if zero_q.any():
        problems.append(("a zero quaternion (no defined rotation)", "", zero_q))
    scales32 = fields["scales"]
    n_pos = 2 if is_2d else 3
    with np.errstate(invalid="ignore"):
        bad_s = (scales32[:, :n_pos] <= 0).any(axis=1) & np.isfinite(scales32).all(axis=1)
    if bad_s.any():
        problems.append(("non-positive scales (linear std must be > 0)", "", bad_s))

    info: dict = {}
    keep = None
    if problems:
        if not drop_invalid:
            desc, hint, mask = problems[0]
            others = "; also " + ", ".join(d for d, _, _ in problems[1:]) if len(problems) > 1 else ""
            raise scene_error(
                path,
                f"{int(mask.sum())} of {n} splat(s) have {desc} (first at index {int(np.argmax(mask))}){hint}{others}. "
                "The file is corrupt or was written by a broken exporter; re-export it, or load with "
                "drop_invalid=True to drop these splats.",
            )
        keep = np.ones(n, dtype=bool)
        for _, _, mask in problems:
            keep &= ~mask
        info["invalid_dropped"] = {d: int(m.sum()) for d, _, m in problems} | {"total": int((~keep).sum())}
        fields = {k: v[keep] for k, v in fields.items()}
        qnorm = qnorm[keep]

    quats32 = fields["quats"]
    q = np.empty(quats32.shape, dtype=np.float32)  # (M, 4) unit wxyz, w >= 0
    for a in range(0, len(q), BLOCK_ROWS):
        qb = quats32[a : a + BLOCK_ROWS].astype(np.float64) / qnorm[a : a + BLOCK_ROWS, None]
        qb *= np.where(qb[:, :1] < 0, -1.0, 1.0)
        q[a : a + BLOCK_ROWS] = qb
    return Splats(
        means=fields["means"],
        quats=q,
        scales=fields["scales"],
        opacities=np.clip(fields["opacities"], 0.0, 1.0),
        colors=fields["colors"],
        sh_rest=fields.get("sh_rest"),
        source_format=source_format,
        info=info,
    )
