"""The one progress bar of the library and the CLI: tqdm on stderr, only on a terminal."""

from __future__ import annotations

import os
import sys


def progress(iterable=None, **kw):
    """A tqdm progress bar on stderr, shown only when stderr is a terminal (``SPLATPLAN_NO_TQDM=1``
    hides it there too); ``kw`` go to ``tqdm`` (``total``, ``desc``, ``unit``...)."""
    from tqdm import tqdm

    kw.setdefault("file", sys.stderr)
    kw.setdefault("leave", False)
    kw.setdefault("dynamic_ncols", True)
    kw.setdefault("disable", bool(os.environ.get("SPLATPLAN_NO_TQDM")) or not sys.stderr.isatty())
    return tqdm(iterable, **kw)
