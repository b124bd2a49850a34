"""Versioning: one version (``splatplan.__version__``, read by pyproject.toml), a changelog section
for it, and the type annotations shipped (``py.typed`` in the package data)."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import splatplan

REPO = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())
CHANGELOG = (REPO / "CHANGELOG.md").read_text()


def test_the_version_has_one_home():
    assert re.fullmatch(r"\d+\.\d+\.\d+", splatplan.__version__), splatplan.__version__
    project = PYPROJECT["project"]
    assert "version" not in project and "version" in project["dynamic"]  # no second copy to forget
    assert PYPROJECT["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "splatplan.__version__"}


def test_changelog_has_a_section_for_this_version():
    released = re.findall(r"^## \[(\d+\.\d+\.\d+)\]", CHANGELOG, flags=re.M)
    assert released and released[0] == splatplan.__version__, (released, splatplan.__version__)
    assert "Deprecation policy" in CHANGELOG and "DeprecationWarning" in CHANGELOG
    section = CHANGELOG.split(f"## [{splatplan.__version__}]", 1)[1].split("\n## [", 1)[0]
    assert "CollisionChecker.query" in section and "margin_for" in section


def test_py_typed_ships():
    assert (REPO / "src" / "splatplan" / "py.typed").is_file()
    assert "py.typed" in PYPROJECT["tool"]["setuptools"]["package-data"]["splatplan"]
