"""Structure of the source tree: no import cycle between modules of ``src/splatplan``.

The test reads every module with :mod:`ast` (nothing is imported) and builds the graph of which
module imports which. Every ``import`` / ``from ... import`` statement counts, wherever it is: at
module level, inside a function or method, under ``if TYPE_CHECKING:`` or in a ``try:`` block. An
import hidden in a function still ties the two modules' concepts together; it only postpones the
failure to run time.

How an import becomes an edge:

* Relative imports are resolved against the importing module (``from ..x import y`` in
  ``splatplan/a/b.py`` reads ``splatplan.x``).
* ``import splatplan.a.b`` is an edge to ``splatplan.a.b``: the module ``a/b.py``, or the package
  ``a/b/__init__.py``. Only the named module counts, not the parent packages Python initialises on
  the way (every module would otherwise depend on ``splatplan/__init__.py``).
* ``from P import x`` where ``P.x`` is a submodule is an edge to that submodule
  (``from . import transforms`` imports ``transforms.py``).
* ``from P import x`` where ``x`` is a name: an edge to the module that *defines* ``x``.
  **Re-exporting package ``__init__`` files are transparent**: when ``P/__init__.py`` only binds
  ``x`` by importing it (``from .splats import Splats``), the edge follows the re-export to the
  defining module (``from splatplan.scenes import Splats`` is an edge to ``scenes/splats.py``), as
  far as the chain of re-exports goes. A submodule that takes a name from its own package's
  ``__init__`` therefore depends on the module that defines the name, not on every submodule the
  ``__init__`` re-exports, and no apparent cycle ``scenes/__init__ -> align -> scenes/__init__``
  appears. When ``x`` is defined in the ``__init__`` itself (a function, class or assignment there)
  the edge goes to the ``__init__``, and its own imports count like any module's: an ``__init__``
  that holds logic is a module like the others.
* Names resolved lazily by a module ``__getattr__`` through :func:`importlib.import_module`
  (string tables) are not edges: they run on first attribute access, not at import.
* Imports of anything outside ``splatplan`` are ignored.

The test fails if a strongly connected component of that graph holds more than one module, and
names every module of each cycle with the import lines that close it.
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"
ROOT_PKG = "splatplan"


class _Module:
    """One parsed module: its dotted name, whether it is a package, its import statements."""

    def __init__(self, name: str, path: Path, is_pkg: bool):
        self.name, self.path, self.is_pkg = name, path, is_pkg
        self.tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        #: names the module binds by importing them: name -> (source module, attribute or None)
        self.reexports: dict[str, tuple[str, str | None]] = {}
        #: names the module defines itself (def, class, assignment at module level)
        self.defines: set[str] = set()

    @property
    def package(self) -> str:
        return self.name if self.is_pkg else self.name.rpartition(".")[0]


def _collect_modules(src: Path = SRC) -> dict[str, _Module]:
    mods: dict[str, _Module] = {}
    for path in sorted((src / ROOT_PKG).rglob("*.py")):
        rel = path.relative_to(src).with_suffix("")
        parts = list(rel.parts)
        is_pkg = parts[-1] == "__init__"
        if is_pkg:
            parts = parts[:-1]
        mods[".".join(parts)] = _Module(".".join(parts), path, is_pkg)
    return mods


def _resolve_from(mod: _Module, node: ast.ImportFrom) -> str | None:
    """The absolute module name of ``from X import ...`` (None: not resolvable)."""
    if node.level == 0:
        return node.module
    base = mod.package.split(".")
    if node.level - 1 > len(base) - 1:
        return None
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _module_level_bindings(mods: dict[str, _Module]) -> None:
    """Fill each module's re-export table and set of names it defines (top-level statements only,
    descending into if/try blocks that run at import)."""

    def walk(stmts, mod: _Module):
        for st in stmts:
            if isinstance(st, ast.ImportFrom):
                base = _resolve_from(mod, st)
                if base is None:
                    continue
                for a in st.names:
                    if a.name != "*":
                        mod.reexports[a.asname or a.name] = (base, a.name)
            elif isinstance(st, ast.Import):
                for a in st.names:
                    if a.asname:
                        mod.reexports[a.asname] = (a.name, None)
            elif isinstance(st, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                mod.defines.add(st.name)
            elif isinstance(st, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
                targets = st.targets if isinstance(st, ast.Assign) else [st.target]
                for t in targets:
                    for n in ast.walk(t):
                        if isinstance(n, ast.Name):
                            mod.defines.add(n.id)
            elif isinstance(st, (ast.If, ast.Try)):
                walk(st.body, mod)
                walk(st.orelse, mod)
                for h in getattr(st, "handlers", []):
                    walk(h.body, mod)
                walk(getattr(st, "finalbody", []), mod)

    for mod in mods.values():
        walk(mod.tree.body, mod)


def _target_of_name(mods: dict[str, _Module], base: str, name: str, seen: frozenset = frozenset()) -> str | None:
    """The module that ``from base import name`` depends on (see the module docstring)."""
    sub = f"{base}.{name}"
    if sub in mods:
        return sub
    if base not in mods:
        return None
    mod = mods[base]
    if (base, name) in seen or name in mod.defines or name not in mod.reexports:
        return base
    src, attr = mod.reexports[name]
    if attr is None:  # ``import a.b as name``
        return src if src in mods else base
    target = _target_of_name(mods, src, attr, seen | {(base, name)})
    return target if target is not None else base


def import_graph(src: Path = SRC) -> tuple[dict[str, set[str]], dict[tuple[str, str], list[str]]]:
    """(module -> modules it imports, (a, b) -> 'path:line' of each import of b in a)."""
    mods = _collect_modules(src)
    _module_level_bindings(mods)
    graph: dict[str, set[str]] = {m: set() for m in mods}
    where: dict[tuple[str, str], list[str]] = defaultdict(list)

    def add(a: _Module, b: str | None, line: int):
        if b is None or b not in mods or b == a.name:
            return
        graph[a.name].add(b)
        loc = f"{a.path.relative_to(src.parent)}:{line}"
        if loc not in where[(a.name, b)]:
            where[(a.name, b)].append(loc)

    for mod in mods.values():
        for node in ast.walk(mod.tree):
            if isinstance(node, ast.Import):
                for a in node.names:
                    if a.name == ROOT_PKG or a.name.startswith(ROOT_PKG + "."):
                        add(mod, a.name, node.lineno)
            elif isinstance(node, ast.ImportFrom):
                base = _resolve_from(mod, node)
                if base is None or not (base == ROOT_PKG or base.startswith(ROOT_PKG + ".")):
                    continue
                for a in node.names:
                    add(mod, base if a.name == "*" else _target_of_name(mods, base, a.name), node.lineno)
    return graph, where


def strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's algorithm (iterative); every component, each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    out: list[list[str]] = []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            v, it = work[-1]
            advanced = False
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                    advanced = True
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                out.append(sorted(comp))
    return out


def _describe(comp: list[str], graph, where) -> str:
    members = set(comp)
    lines = [f"cycle among {len(comp)} modules: {', '.join(comp)}"]
    for a in comp:
        for b in sorted(graph[a] & members):
            lines.append(f"    {a} -> {b}   ({'; '.join(where[(a, b)])})")
    return "\n".join(lines)


def test_graph_sees_imports_inside_functions_and_relative_imports(tmp_path):
    pkg = tmp_path / ROOT_PKG
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("from .a import A\nfrom . import b\n")
    (pkg / "sub" / "a.py").write_text("class A: ...\n")
    (pkg / "sub" / "b.py").write_text("from . import A\ndef f():\n    from .. import c\n")
    (pkg / "c.py").write_text("import splatplan.sub\nfrom splatplan.sub import b\n")
    graph, _ = import_graph(tmp_path)
    assert graph["splatplan.sub.b"] == {"splatplan.sub.a", "splatplan.c"}  # re-export followed; import inside a function
    assert graph["splatplan.sub"] == {"splatplan.sub.a", "splatplan.sub.b"}
    assert graph["splatplan.c"] == {"splatplan.sub", "splatplan.sub.b"}
    comps = [c for c in strongly_connected(graph) if len(c) > 1]
    assert comps == [["splatplan.c", "splatplan.sub", "splatplan.sub.b"]]


def test_no_import_cycles():
    graph, where = import_graph()
    assert len(graph) > 100, "the source tree was not found"
    cycles = [c for c in strongly_connected(graph) if len(c) > 1]
    assert not cycles, "import cycles (each strongly connected component of the module graph):\n" + "\n\n".join(_describe(c, graph, where) for c in cycles)


def test_scene_stage_does_not_import_robots():
    """Robots read the scene stage (quaternion maths of ``scenes.splats``), so the scene stage must
    not read the robot stage: stage-level edges both ways are a cycle between the two packages."""
    graph, where = import_graph()
    bad = sorted(
        f"{a} -> {b} ({'; '.join(where[(a, b)])})"
        for a in graph if a.startswith("splatplan.scenes")
        for b in graph[a] if b.startswith("splatplan.robots")
    )  # fmt: skip
    assert not bad, "the scene stage imports the robot stage:\n" + "\n".join(bad)


#: modules that hold a concept several modules share -> the modules that read it (none of which it may import, directly or not)
SHARED_BELOW = {
    "splatplan.robots.ellipsoid": ("splatplan.robots.fit", "splatplan.robots.fit_cover", "splatplan.robots.fit_opt", "splatplan.robots.fit_measure", "splatplan.robots.solids"),
    "splatplan.robots.solids": ("splatplan.robots.fit", "splatplan.robots.fit_cover", "splatplan.robots.fit_opt", "splatplan.robots.fit_measure"),
    "splatplan.scenes.floor": ("splatplan.scenes.align", "splatplan.scenes.terrain"),
    "splatplan.scenes.builtin.levels": ("splatplan.scenes.builtin.stonehenge", "splatplan.scenes.builtin._layout", "splatplan.scenes.builtin.tabletop", "splatplan.scenes.builtin.apartment"),
    "splatplan.scenes.margin": ("splatplan.eval.mbm",),
    "splatplan.eval._pr_config": ("splatplan.eval.pr", "splatplan.eval._pr_scoring"),
}


def _reachable(graph: dict[str, set[str]], start: str) -> set[str]:
    seen, todo = set(), [start]
    while todo:
        for b in graph[todo.pop()]:
            if b not in seen:
                seen.add(b)
                todo.append(b)
    return seen


def test_shared_concepts_sit_below_their_users():
    """Each leaf module a cycle was broken with is read by its users and reads none of them."""
    graph, _ = import_graph()
    for leaf, users in SHARED_BELOW.items():
        assert leaf in graph, leaf
        below = _reachable(graph, leaf)
        assert not below & set(users), f"{leaf} imports (directly or not) its users {sorted(below & set(users))}"
        assert any(leaf in graph[u] for u in users), f"no user of {leaf} imports it"


def test_no_private_names_imported_across_modules():
    """A helper another module needs is public in its stage (or moves): no module imports a
    ``_private`` name from another splatplan module. Private *modules* (``_config``, ``_warp``, ...)
    are shared helpers of the package and may be imported; the command-line package's own
    ``cli/_common`` helpers are shared within it."""
    import splatplan

    root = Path(splatplan.__file__).resolve().parent
    bad = []
    for f in sorted(root.rglob("*.py")):
        rel = f.relative_to(root)
        parts = list(rel.with_suffix("").parts)
        pkg = ["splatplan"] + (parts[:-1] if parts[-1] != "__init__" else parts[:-1])
        for node in ast.walk(ast.parse(f.read_text())):
            if not isinstance(node, ast.ImportFrom):
                continue
            if node.level:
                base = ".".join(pkg[: len(pkg) - node.level + 1] + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            if not base.startswith("splatplan"):
                continue
            if base.startswith("splatplan.cli") and str(rel).startswith("cli"):
                continue  # the CLI's shared helpers (cli/_common) stay inside the CLI package
            bad += [f"{rel}: {a.name} from {base}" for a in node.names if a.name.startswith("_") and not a.name.startswith("__")]
    assert not bad, "private names imported across modules:\n" + "\n".join(bad)


#: checks that read a robot's name to decide what the robot is (``robot.name == "go2"``,
#: ``"go2" in name``, ``robot.name.startswith(...)``, ``args.robot != "go2"``): code asks the robot
#: instead (``robot.base``, ``robot.walks_on_terrain``, ``robot.is_point``)
_NAME_CHECKS = (
    r"\bname\s*(==|!=)\s*[\"'](go2|panda)",
    r"\.name\s+(not\s+)?in\s*[\(\[\{]",
    r"[\"'](go2|panda|planar)[\"']\s+(not\s+)?in\s+[\w.]*name\b",
    r"\bname\s*\.\s*(lower\(\)\s*\.\s*)?(startswith|endswith)\(\s*[\"'](go2|panda|sphere|ellipsoid)",
    r"\bargs\.robot\s*(==|!=)",
)
#: the one place that turns a robot's name into a robot (and may compare names)
_NAME_PARSER = "robots/builtin.py"


def test_no_behaviour_keyed_on_a_robots_name():
    """A robot carries its kind (fixed base, planar base, point; walks on terrain or not): no module
    of ``src/`` but the name parser decides what a robot is from its name."""
    import re

    root = SRC / ROOT_PKG
    pats = [re.compile(p) for p in _NAME_CHECKS]
    bad = []
    for f in sorted(root.rglob("*.py")):
        rel = f.relative_to(root).as_posix()
        if rel == _NAME_PARSER:
            continue
        for i, line in enumerate(f.read_text(encoding="utf-8").splitlines(), 1):
            code = line.split("#", 1)[0]
            bad += [f"{rel}:{i}: {line.strip()}" for p in pats if p.search(code)]
    assert not bad, "behaviour keyed on a robot's name (ask robot.base / robot.walks_on_terrain / robot.is_point):\n" + "\n".join(bad)


def test_name_check_patterns_catch_the_smells():
    """The patterns above catch the forms that were in the tree, and not the checks that are fine."""
    import re

    pats = [re.compile(p) for p in _NAME_CHECKS]
    smells = ['if robot.name == "go2":', 'if robot.name == "go2" or name == "go2":', '    if "go2" in name or "planar" in name:',
              'if args.robot == "go2":', 'elif args.robot != "go2":', 'if robot.name in ("go2", "a1"):', 'robot.name.startswith("sphere")']  # fmt: skip
    fine = ['if robot.walks_on_terrain:', 'if cfg.name == "thumbnail":', 'if args.name == "from-moveit":', 'kind == "planar"']
    assert all(any(p.search(s) for p in pats) for s in smells)
    assert not any(p.search(s) for p in pats for s in fine)


#: modules whose public ``robot`` parameters stay unannotated, and why: the scene stage may not import
#: the robot stage (test above); the FK kernel glue and the fit measure sit below ``robots/robot.py``
#: (which imports them), so naming the type there would close a cycle; the visual reaching goals and
#: study are being reworked in their own branch
_ROBOT_UNANNOTATED = ("scenes/moveit.py", "robots/wp_fk.py", "robots/fit_measure.py", "planners/reach_goals.py", "eval/reach.py")


def test_public_robot_parameters_are_annotated():
    """Every public function or method of ``src/`` that takes a ``robot`` says what it takes
    (``Robot``, ``Robot | str`` where names are accepted, ``Robot | None``)."""
    root = SRC / ROOT_PKG
    bad = []
    for f in sorted(root.rglob("*.py")):
        rel = f.relative_to(root).as_posix()
        if rel in _ROBOT_UNANNOTATED or (f.name.startswith("_") and f.name != "__init__.py"):
            continue

        def visit(node, owner: str, public: bool) -> None:
            for ch in ast.iter_child_nodes(node):
                if isinstance(ch, ast.ClassDef):
                    visit(ch, ch.name + ".", public and not ch.name.startswith("_"))
                elif isinstance(ch, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    pub = public and (not ch.name.startswith("_") or ch.name in ("__init__", "__call__"))
                    args = ch.args.posonlyargs + ch.args.args + ch.args.kwonlyargs
                    bad.extend(f"{rel}:{ch.lineno} {owner}{ch.name}" for a in args if pub and a.arg == "robot" and a.annotation is None)

        visit(ast.parse(f.read_text(encoding="utf-8")), "", True)
    assert not bad, "public functions with an unannotated robot parameter:\n" + "\n".join(bad)


#: the most lines a module of ``src/splatplan`` may have (a module over it holds several concepts: split it)
MAX_MODULE_LINES = 600
#: modules allowed to be longer, and why: the Warp kernels of the metric and their ``@wp.func``
#: helpers stay in one file (Warp compiles a module's kernels together; the exactness argument
#: in its docstring covers them all)
LONG_MODULES = {"metric/wp_metric_kernel.py"}
#: the most lines a function or method may have, from its ``def`` line to its last line
MAX_FUNCTION_LINES = 150


def test_modules_are_at_most_600_lines():
    root = SRC / ROOT_PKG
    long = sorted(
        (n, rel)
        for f in root.rglob("*.py")
        if (rel := f.relative_to(root).as_posix()) not in LONG_MODULES
        and (n := len(f.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES
    )  # fmt: skip
    assert not long, f"modules over {MAX_MODULE_LINES} lines (split them by concept):\n" + "\n".join(f"  {rel}: {n}" for n, rel in long)
    assert all((root / rel).is_file() for rel in LONG_MODULES), "an exempt module is gone: drop it from LONG_MODULES"


def test_functions_are_at_most_150_lines():
    root = SRC / ROOT_PKG
    long = []
    for f in sorted(root.rglob("*.py")):
        rel = f.relative_to(root).as_posix()
        for node in ast.walk(ast.parse(f.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = (node.end_lineno or node.lineno) - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    long.append(f"  {rel}:{node.lineno} {node.name}: {n} lines")
    assert not long, f"functions over {MAX_FUNCTION_LINES} lines (split them into named helpers):\n" + "\n".join(long)
