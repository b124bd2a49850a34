"""The type checker: ``python -m mypy`` (configured in ``pyproject.toml`` ``[tool.mypy]``: the files,
the Warp-kernel and not-yet-clean overrides, the cache in ``build/``) finds nothing in ``src/splatplan``."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.skipif(importlib.util.find_spec("mypy") is None, reason="mypy is not installed (it comes with pip install 'splatplan[test]')")


def test_mypy_is_clean_on_the_source_tree():
    # a cold run takes about a minute on 2 cores, a warm one (cache in build/mypy_cache) a few seconds
    res = subprocess.run([sys.executable, "-m", "mypy"], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, f"mypy found problems (run `python -m mypy` from the repository root):\n{res.stdout[-8000:]}{res.stderr[-2000:]}"
