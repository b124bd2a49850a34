"""The documentation site builds with ``mkdocs build --strict`` (warnings are errors), its generated
reference covers every command and every public name, its benchmark tables and the README's
headline table come from benchmarks/results/, and a real browser opens its pages.

The browser is Debian's ``chromium`` (``make test`` installs it as root); without it that test
skips with the reason.
"""

from __future__ import annotations

import functools
import http.server
import importlib.util
import re
import shutil
import subprocess
import sys
import threading
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MKDOCS = Path(sys.executable).with_name("mkdocs")


def _module(name: str, path: Path):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def generate():
    return _module("_docs_generate", ROOT / "docs" / "hooks" / "generate.py")


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    if not MKDOCS.exists():
        pytest.skip("mkdocs is not installed: pip install -e '.[docs]' (make test installs it)")
    out = tmp_path_factory.mktemp("site")
    proc = subprocess.run([str(MKDOCS), "build", "--strict", "-d", str(out)], cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-4000:]
    return out


@pytest.mark.slow  # builds the whole site (about 30 s of mkdocstrings on 2 cores)
def test_site_builds_strict_with_every_command_and_public_name(site, generate):
    cli = (site / "reference" / "cli" / "index.html").read_text()
    for cmd in generate.cli_commands():
        assert f"<code>{cmd}</code>" in cli, f"the CLI reference misses {cmd!r}"
    for package, names in generate.public_api().items():
        page = site / "reference" / "api" / ("" if package == "splatplan" else package.split(".", 1)[1]) / "index.html"
        html = page.read_text()
        for name in names:
            short = name.rsplit(".", 1)[-1]
            assert short in html, f"{package}: {name} is public (__all__) but not on {page.relative_to(site)}"
    bench = (site / "benchmarks" / "pr" / "index.html").read_text()
    assert "results:" not in bench and "Measured on:" in bench


def test_cli_reference_lists_every_flag(generate):
    """Every flag of every command appears with its help (generated from the parser, no site build)."""
    import argparse

    sys.path.insert(0, str(ROOT / "src"))
    from splatplan.cli import build_parser

    md = generate.cli_reference()

    def walk(p):
        for a in p._actions:
            if isinstance(a, argparse._SubParsersAction):
                for sp in a.choices.values():
                    walk(sp)
            if isinstance(a, argparse._HelpAction):
                continue
            for o in a.option_strings:
                assert f"`{o}`" in md, o

    walk(build_parser())


def test_benchmark_markers_name_known_sections():
    pages = _module("_bench_pages", ROOT / "benchmarks" / "pages.py")
    for page in (ROOT / "docs").rglob("*.md"):
        for name in re.findall(r"^<!-- results: ([\w/.-]+) -->$", page.read_text(), re.M):
            assert name in pages.SECTIONS, f"{page.relative_to(ROOT)}: unknown results section {name!r}"


def test_readme_headline_table_is_generated():
    """The README's numbers are those of benchmarks/results (python benchmarks/pages.py --readme)."""
    pages = _module("_bench_pages", ROOT / "benchmarks" / "pages.py")
    text = (ROOT / "README.md").read_text()
    assert "<!-- BEGIN:headline -->" in text
    assert pages.readme_with_headline(text) == text, "run: python benchmarks/pages.py --readme"


class _Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):  # noqa: D102 - keep the test output clean
        pass


@pytest.mark.slow
def test_site_in_headless_chromium(site):
    chromium = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
    if not chromium:
        pytest.skip("no headless browser: apt-get install chromium (make test does this as root)")
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(_Quiet, directory=str(site)))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    base = f"http://127.0.0.1:{server.server_address[1]}"
    try:
        for path, heading in (("/", "splatplan"), ("/howto/arm/", "Arm planning from a pose goal"), ("/reference/api/metric/", "CollisionChecker")):
            proc = subprocess.run(
                [chromium, "--headless=new", "--no-sandbox", "--enable-unsafe-swiftshader", "--disable-gpu", "--dump-dom", base + path],
                capture_output=True, text=True, timeout=120,
            )
            dom = proc.stdout
            assert "<h1" in dom, (path, proc.stderr[-2000:])
            assert heading in dom, (path, heading)
    finally:
        server.shutdown()
        server.server_close()
