"""MkDocs hook: the pages that are generated from the code and the results, so they cannot drift.

* ``reference/cli.md``: every command and subcommand of ``splatplan.cli.build_parser()``, every
  flag with its help, its choices or declared range, and its default.
* ``reference/api/<stage>.md``: one page per stage package; mkdocstrings renders each name of the
  package's ``__all__`` (packages without ``__all__`` get their public modules).
* Benchmark tables: a line ``<!-- results: NAME -->`` in any page is replaced by the table that
  ``benchmarks/pages.py`` builds from ``benchmarks/results/`` (see that script); the figures of
  ``benchmarks/results/`` and the MotionBenchMaker plot are added to the site under ``benchmarks/img/``.

Registered in ``mkdocs.yml`` (``hooks:``); ``make docs`` runs it. The functions are importable
(``tests/test_docs_site.py`` uses them) without MkDocs.
"""

from __future__ import annotations

import argparse
import ast
import importlib.util
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "src"
#: stage packages in the order of the data flow (a package found under src/splatplan but not named here is appended)
STAGES = ("scenes", "metric", "robots", "planners", "render", "encoders", "tasks", "baselines", "eval", "viewer")
#: results figures copied into the site (benchmarks/results/NAME -> benchmarks/img/NAME)
FIGURES = ("pr.png", "fig4_paths.png", "fig5_metric_along_path.png", "navigate_tree.png", "navigate_trial0.png", "reach_goal0.png")


def _src_path() -> None:
    if str(SRC) not in sys.path:
        sys.path.insert(0, str(SRC))


# ----------------------------------------------------------------------------------------- CLI
def _bounds_text(action: argparse.Action) -> str:
    """The declared range of a flag: the ``Bounds`` (or config field) its ``type=`` callable closes over."""
    fn = action.type
    cells = [c.cell_contents for c in (getattr(fn, "__closure__", None) or ()) if _has_contents(c)]
    from splatplan._config import field_bounds

    for v in cells:
        if hasattr(v, "describe") and hasattr(v, "problem"):
            return v.describe()
        if v.__class__.__name__ == "Field" and hasattr(v, "metadata"):
            return field_bounds(v).describe()
    return ""


def _has_contents(cell) -> bool:
    try:
        cell.cell_contents
    except ValueError:
        return False
    return True


def _cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def _default_text(action: argparse.Action) -> str:
    d = action.default
    if d is None or d is argparse.SUPPRESS or type(d).__name__ == "_UnsetType" or repr(d).startswith("<"):
        return ""
    if isinstance(action, (argparse._StoreTrueAction, argparse._StoreFalseAction)):
        return ""
    return f"`{d}`" if d != "" else '`""`'


def _flag_rows(actions) -> list[str]:
    rows = []
    for a in actions:
        if isinstance(a, (argparse._SubParsersAction, argparse._HelpAction)):
            continue
        name = ", ".join(f"`{o}`" for o in a.option_strings) or f"`{a.metavar or a.dest}` (positional)"
        if a.option_strings and a.nargs != 0 and not isinstance(a, argparse._VersionAction):
            name += f" `{a.metavar or a.dest.upper()}`" if isinstance(a.metavar, str) or a.metavar is None else ""
        if a.choices is not None:
            rng = "one of " + ", ".join(f"`{c}`" for c in a.choices)
        else:
            rng = _cell(_bounds_text(a))
        help_ = (a.help or "").replace("%%", "%")
        if "%(default)" in help_:
            help_ = help_.replace("%(default)s", str(a.default))
        rows.append(f"| {name} | {_cell(help_)} | {rng} | {_default_text(a)} |")
    return rows


def _command_md(parser: argparse.ArgumentParser, words: list[str], help_: str, out: list[str]) -> None:
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    level = "#" * min(len(words) + 1, 4)
    out += [f"{level} `{' '.join(words)}`", ""]
    text = parser.description or help_
    if text:
        out += [_cell(text), ""]
    usage = " ".join(parser.format_usage().split())
    out += ["```text", usage.replace("usage: ", "", 1), "```", ""]
    for group in parser._action_groups:
        rows = _flag_rows(group._group_actions)
        if not rows:
            continue
        title = group.title if group.title not in ("options", "optional arguments") else "options"
        out += [f"**{title}**", "", "| argument | help | choices / range | default |", "|---|---|---|---|", *rows, ""]
    for a in subs:
        helps = {c.dest: c.help for c in a._choices_actions}
        for name, sp in a.choices.items():
            _command_md(sp, words + [name], helps.get(name, ""), out)


def cli_reference() -> str:
    """The CLI reference page (markdown), walked from ``splatplan.cli.build_parser()``."""
    _src_path()
    from splatplan.cli import build_parser

    out = [
        "# Command-line reference",
        "",
        "Generated from the argparse parser (`splatplan.cli.build_parser()`) each time the site is built:",
        "every command, every flag, its help, its choices or declared range, and its default. A flag built",
        'from a config field shows "(default ...)" in its help: leaving it out keeps the config\'s value.',
        "Exit codes and output rules: [Exit codes](exit-codes.md).",
        "",
    ]
    _command_md(build_parser(), ["splatplan"], "", out)
    return "\n".join(out) + "\n"


def cli_commands() -> list[str]:
    """Every command path, e.g. ``splatplan scene align`` (for the tests)."""
    _src_path()
    from splatplan.cli import build_parser

    found: list[str] = []

    def walk(p, words):
        found.append(" ".join(words))
        for a in p._actions:
            if isinstance(a, argparse._SubParsersAction):
                for n, sp in a.choices.items():
                    walk(sp, words + [n])

    walk(build_parser(), ["splatplan"])
    return found


# ----------------------------------------------------------------------------------------- API
def _static_all(init: Path) -> list[str] | None:
    tree = ast.parse(init.read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "__all__" for t in node.targets):
            try:
                return list(ast.literal_eval(node.value))
            except ValueError:
                return None
    return None


def public_api() -> dict[str, list[str]]:
    """``{package: names}``: each stage package's ``__all__``; a package without one maps its public
    modules (``splatplan.eval.pr``, ...) as names. ``splatplan`` itself comes first."""
    _src_path()
    import splatplan

    pkg_dir = SRC / "splatplan"
    api = {"splatplan": list(splatplan.__all__)}
    found = sorted(p.name for p in pkg_dir.iterdir() if (p / "__init__.py").exists() and not p.name.startswith("_") and p.name != "cli")
    for name in [s for s in STAGES if s in found] + [s for s in found if s not in STAGES]:
        init = pkg_dir / name / "__init__.py"
        names = _static_all(init)
        if names is None and "__all__" in init.read_text():
            names = list(importlib.import_module(f"splatplan.{name}").__all__)
        if names is None:
            names = sorted(f"{name}.{m.stem}" for m in (pkg_dir / name).glob("*.py") if not m.stem.startswith("_"))
        api[f"splatplan.{name}"] = names
    return api


_GRIFFE: dict = {}


def _path_of(package: str, name: str) -> str:
    """The path mkdocstrings can collect for ``package.name``: the package's own member, or (for a
    name the package provides lazily through ``__getattr__``) the submodule that defines it."""
    import griffe

    if package not in _GRIFFE:
        _GRIFFE[package] = griffe.load(package, search_paths=[str(SRC)], resolve_aliases=False)
    mod = _GRIFFE[package]
    if name in mod.members:
        return f"{package}.{name}"
    stack = list(mod.modules.values())
    while stack:
        sub = stack.pop()
        if name in sub.members and not sub.members[name].is_alias:
            return f"{sub.path}.{name}"
        stack.extend(sub.modules.values())
    raise LookupError(f"{package}.__all__ names {name!r}, which no module of {package} defines")


def api_page(package: str, names: list[str], api: dict[str, list[str]]) -> str:
    out = [f"# `{package}`", ""]
    if package == "splatplan":
        out += ["::: splatplan", "    options:", "      members: false", "      show_root_heading: false", ""]
        out += ["The root package re-exports the names most scripts need; each is documented on its stage's page.", ""]
        out += ["| name | documented in |", "|---|---|"]
        for n in names:
            home = next((p for p, ns in api.items() if p != "splatplan" and n in ns), None)
            out.append(f"| `{n}` | " + (f"[`{home}`]({home.split('.', 1)[1]}.md)" if home else "this page") + " |")
        return "\n".join(out) + "\n"
    if names and "." in names[0]:  # modules of a package without __all__
        out += [f"::: {package}", "    options:", "      members: false", "      show_root_heading: false", ""]
        for mod in names:
            out += [f"## `splatplan.{mod}`", "", f"::: splatplan.{mod}", "    options:", "      show_root_heading: false", ""]
        return "\n".join(out) + "\n"
    out += [f"::: {package}", "    options:", "      members: false", "      show_root_heading: false", ""]
    for n in names:
        out += [f"::: {_path_of(package, n)}", "    options:", "      show_root_heading: true", "      heading_level: 2", ""]
    return "\n".join(out) + "\n"


# ----------------------------------------------------------------------------------------- benchmarks
def _bench_pages():
    spec = importlib.util.spec_from_file_location("_bench_pages", ROOT / "benchmarks" / "pages.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


MARKER = re.compile(r"^<!-- results: ([\w/.-]+) -->$", re.M)


def expand_results(markdown: str, bench=None) -> str:
    """Replace each ``<!-- results: NAME -->`` line by the generated table NAME."""
    bench = bench or _bench_pages()
    return MARKER.sub(lambda m: bench.section(m.group(1)), markdown)


# ----------------------------------------------------------------------------------------- MkDocs events
def on_files(files, config):
    from mkdocs.structure.files import File

    api = public_api()
    files.append(File.generated(config, "reference/cli.md", content=cli_reference()))
    for pkg, names in api.items():
        files.append(File.generated(config, f"reference/api/{pkg.split('.', 1)[-1] if pkg != 'splatplan' else 'index'}.md", content=api_page(pkg, names, api)))
    results = ROOT / "benchmarks" / "results"
    for name in FIGURES:
        if (results / name).exists():
            files.append(File.generated(config, f"benchmarks/img/{name}", abs_src_path=str(results / name)))
    png = _bench_pages().mbm_plot()
    if png is not None:
        files.append(File.generated(config, "benchmarks/img/mbm_speed.png", content=png))
    return files


def on_page_markdown(markdown, page, config, files):
    return expand_results(markdown) if MARKER.search(markdown) else markdown
