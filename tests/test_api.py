"""The public API: every exported name resolves, and importing the package stays light."""

from __future__ import annotations

import subprocess
import sys

import splatplan


def test_every_public_name_resolves():
    for name in splatplan.__all__:
        assert getattr(splatplan, name) is not None, name


def test_import_is_lazy():
    code = "import sys, splatplan; print('warp' in sys.modules, 'torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False", "False"]
