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


def test_render_is_the_rendering_package_whatever_was_imported_first():
    """``splatplan.render`` names the package (a plain module, not callable) whether the root's lazy
    lookup or an import of the package comes first; the function is ``splatplan.render.render``."""
    code = (
        "import types, splatplan\n"
        "first = splatplan.render\n"
        "import splatplan.render.cameras\n"
        "from splatplan.render.api import render\n"
        "print(type(first) is types.ModuleType, splatplan.render is first, splatplan.render.render is render, callable(first))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["True", "True", "True", "False"]
