"""gsplat training checkpoint (``.pt`` / ``.ckpt`` / ``.pth``) reader.

gsplat's ``simple_trainer`` saves ``torch.save({"step": ..., "splats": splats.state_dict()})``;
the parameter dict may also be saved on its own. Tensors, by key:

* ``means`` (N, 3) scene units; ``quats`` (N, 4) **wxyz**, not normalised;
* ``scales`` (N, 3) log std (a (N, 2) tensor is read as 2DGS disks, third std 0);
* ``opacities`` (N,) logit; ``sh0`` (N, 1, 3) SH DC; optional ``shN`` (N, K, 3) higher bands
  (coefficient-major, channel last -- the same layout as ``Splats.sh_rest``).

Checkpoints are loaded with ``torch.load(..., weights_only=True)``, so no code from the file is
executed. PyTorch is an optional extra: without it, reading a checkpoint raises a one-line
:class:`~splatplan.errors.SplatplanError` naming ``splatplan[baselines]``. Zip entries that
inflate more than :data:`MAX_ZIP_RATIO` times are refused before torch reads them (decompression
bombs). Checkpoints trained with learned appearance (``features``/``colors`` instead of ``sh0``)
are not supported.
"""

from __future__ import annotations

import zipfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..errors import SplatplanError
from .io_common import build_splats, exp_std, scene_error, sh_dc_to_color, sigmoid
from .splats import Splats

_REQUIRED = ("means", "quats", "scales", "opacities", "sh0")


#: Largest accepted uncompressed/compressed size ratio of a compressed entry in a checkpoint zip.
#: ``torch.save`` stores entries uncompressed and float tensors barely compress, so a larger ratio
#: means a decompression bomb (torch would allocate the declared size up front).
MAX_ZIP_RATIO = 100


def _check_zip_ratio(path: str | Path) -> None:
    """Reject zip checkpoints whose compressed entries inflate more than :data:`MAX_ZIP_RATIO` times."""
    try:
        if not zipfile.is_zipfile(path):
            return  # legacy (non-zip) torch file or garbage: torch.load reports it
        with zipfile.ZipFile(path) as z:
            infos = z.infolist()
    except (OSError, zipfile.BadZipFile, ValueError):
        return  # torch.load gives the message
    for zi in infos:
        if zi.compress_type != zipfile.ZIP_STORED and zi.file_size > MAX_ZIP_RATIO * max(zi.compress_size, 1024):
            raise scene_error(
                path,
                f"checkpoint entry '{zi.filename}' claims {zi.file_size:,} bytes from {zi.compress_size:,} compressed "
                f"(more than {MAX_ZIP_RATIO}x; torch.save does not compress): refusing a likely decompression bomb",
            )


def read_gsplat_checkpoint(path: str | Path, *, drop_invalid: bool = False) -> Splats:
    """Read the splats of a gsplat checkpoint.

    Raises:
        SceneFormatError: not a torch file, no splat dict, missing keys (named), bad shapes or
            bad values.
    """
    try:
        import torch  # deferred: importing torch takes about a second, and it is an optional extra
    except ImportError:
        raise SplatplanError(
            f"{path}: reading a gsplat checkpoint needs PyTorch, which is not installed: pip install 'splatplan[baselines]' (or any torch >= 2.2)"
        ) from None

    _check_zip_ratio(path)
    try:
        obj = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # torch.load raises many unrelated types on non-torch bytes (IndexError, ...)
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise scene_error(path, f"cannot load as a torch checkpoint ({first})") from None
    params = obj.get("splats", obj) if isinstance(obj, Mapping) else None
    if not isinstance(params, Mapping):
        raise scene_error(path, "checkpoint holds no splat parameters (expected a dict, optionally under the key 'splats')")
    missing = [k for k in _REQUIRED if k not in params]
    if missing:
        raise scene_error(path, f"gsplat checkpoint lacks key(s) {', '.join(missing)} (found {', '.join(map(str, params)) or 'nothing'})")

    arrays: dict[str, np.ndarray] = {}
    for key in _REQUIRED + (("shN",) if "shN" in params else ()):
        value = params[key]
        if not isinstance(value, torch.Tensor):
            raise scene_error(path, f"checkpoint entry '{key}' is a {type(value).__name__}, expected a tensor")
        if value.is_complex() or not (value.is_floating_point() or value.dtype in (torch.int8, torch.uint8, torch.int16, torch.int32, torch.int64)):
            raise scene_error(path, f"checkpoint entry '{key}' has dtype {str(value.dtype).removeprefix('torch.')}, expected real numbers")
        arrays[key] = value.detach().to(torch.float64).cpu().numpy()
    n = arrays["means"].shape[0] if arrays["means"].ndim >= 1 else -1
    if n == 0:
        raise scene_error(path, "the checkpoint holds no splats ('means' has 0 rows)")
    opac = arrays["opacities"].reshape(-1)
    sh0 = arrays["sh0"].reshape(n, -1) if n > 0 and arrays["sh0"].size == 3 * n else None
    want = {"means": (n, 3), "quats": (n, 4)}
    bad = [f"{k} {arrays[k].shape} (expected {s})" for k, s in want.items() if arrays[k].shape != s]
    if arrays["scales"].ndim != 2 or arrays["scales"].shape[0] != n or arrays["scales"].shape[1] not in (2, 3):
        bad.append(f"scales {arrays['scales'].shape} (expected ({n}, 3) or ({n}, 2))")
    if opac.shape != (n,):
        bad.append(f"opacities {arrays['opacities'].shape} (expected ({n},))")
    if sh0 is None:
        bad.append(f"sh0 {arrays['sh0'].shape} (expected ({n}, 1, 3))")
    if "shN" in arrays and (arrays["shN"].ndim != 3 or arrays["shN"].shape[0] != n or arrays["shN"].shape[2] != 3):
        bad.append(f"shN {arrays['shN'].shape} (expected ({n}, K, 3))")
    if bad or sh0 is None:  # (sh0 None is among the bad shapes)
        raise scene_error(path, f"gsplat checkpoint tensors have wrong shapes: {'; '.join(bad)}")

    is_2d = arrays["scales"].shape[1] == 2
    scales = exp_std(arrays["scales"])  # (N, 2 or 3) linear std, Inf on overflow (reported below)
    if is_2d:
        scales = np.concatenate([scales, np.zeros((n, 1))], axis=1)  # (N, 3)
    sh_rest = arrays.get("shN")
    return build_splats(
        path,
        "gsplat_ckpt",
        means=arrays["means"],
        quats=arrays["quats"],
        scales=scales,
        opacities=sigmoid(opac),
        colors=sh_dc_to_color(sh0),
        sh_rest=None if sh_rest is None or sh_rest.shape[1] == 0 else sh_rest,
        is_2d=is_2d,
        drop_invalid=drop_invalid,
        activation={"scales": "std = exp(scales)", "opacities": "sigmoid(opacities)", "colors": "0.5 + C0 * sh0"},
    )
