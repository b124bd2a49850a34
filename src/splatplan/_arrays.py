"""Which kind of array a value is (numpy, torch or Warp), without importing torch or Warp.

Public functions accept numpy, torch and ``wp.array`` inputs; this is the one place that tells
them apart. A value is a torch tensor / Warp array only when its module is already imported (a
caller that holds one has imported it), so nothing here loads torch or Warp.
"""

from __future__ import annotations

import sys

import numpy as np


def array_kind(x) -> str:
    """"warp", "torch" or "numpy" (everything else is taken by ``np.asarray``)."""
    warp = sys.modules.get("warp")
    if warp is not None and isinstance(x, warp.array):
        return "warp"
    torch = sys.modules.get("torch")
    if torch is not None and isinstance(x, torch.Tensor):
        return "torch"
    return "numpy"


def host_array(x) -> np.ndarray:
    """A numpy, torch (any device) or Warp array as a numpy array on the host (dtype kept)."""
    k = array_kind(x)
    if k == "torch":
        return x.detach().cpu().numpy()
    if k == "warp":
        return x.numpy()
    return np.asarray(x)
