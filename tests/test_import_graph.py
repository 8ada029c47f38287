"""The library's import graph: it stands alone, has no cycle and only looks down.

Every module under ``fricenv/`` is parsed (nothing is imported), and an edge is drawn for
each import, at module or function level, for each ``importlib.import_module`` of a
constant name, for each string that names a module (``"fricenv.cli.simulate"``, an entry
point ``"fricenv.envs.vector:StickSlipVectorEnv"``) and for each value of a package's
``_HOMES`` table (the public names its ``__getattr__`` imports on first use). The layers
are read from ``docs/development.md``, so that the page and the check cannot drift apart.
"""

from __future__ import annotations

import ast
import fnmatch
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "fricenv"
#: Top-level names of the checkout that are not part of the library.
OUTSIDE = ("agents", "fricenv_agents", "scripts", "tests")



def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _known_modules() -> dict[str, Path]:
    """Every module of the checkout's packages: the library and what lies beside it."""
    return {_module_name(path): path for top in ("fricenv", *OUTSIDE)
            for path in (ROOT / top).rglob("*.py")}


MODULES = _known_modules()
LIBRARY = {name: path for name, path in MODULES.items() if name.split(".")[0] == "fricenv"}


def _package(module: str) -> str:
    """The package relative imports in ``module`` start from."""
    return module if MODULES[module].name == "__init__.py" else module.rpartition(".")[0]


def _resolve(name: str, package: str, level: int) -> str:
    """The absolute name of ``name`` imported with ``level`` leading dots in ``package``."""
    if not level:
        return name
    base = package.split(".")[: len(package.split(".")) - level + 1]
    return ".".join([*base, name] if name else base)


def _target(name: str) -> str | None:
    """The known module ``name`` denotes: itself, or the module holding it as an attribute
    (``fricenv.simulate.simulate`` -> ``fricenv.simulate``); None if outside the checkout."""
    while name:
        if name in MODULES:
            return name
        name = name.rpartition(".")[0]
    return None


def _ancestors(module: str) -> set[str]:
    parts = module.split(".")
    return {".".join(parts[:i]) for i in range(1, len(parts) + 1)}


def imports_of(module: str) -> set[str]:
    """The known modules ``module`` imports or names (see the module docstring)."""
    path = LIBRARY[module]
    package = _package(module)
    names: set[str] = set()
    tree = ast.parse(path.read_text(), str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = _resolve(node.module or "", package, node.level)
            names.update(f"{base}.{alias.name}" for alias in node.names)
        elif (isinstance(node, ast.Call) and getattr(node.func, "attr", None) == "import_module"
              and node.args and isinstance(node.args[0], ast.Constant)
              and isinstance(node.args[0].value, str)):
            spec = node.args[0].value
            level = len(spec) - len(spec.lstrip("."))
            names.add(_resolve(spec.lstrip("."), package, level))
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            spec = node.value.partition(":")[0]
            if re.fullmatch(r"[A-Za-z_]\w*(\.\w+)+", spec) and spec in MODULES:
                names.add(spec)
        elif (isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "_HOMES"
                                                     for t in node.targets)):
            names.update(_resolve(v.value, package, 1) for v in ast.walk(node.value)
                         if isinstance(v, ast.Constant) and isinstance(v.value, str)
                         and f"{package}.{v.value}" in MODULES)
    targets = {_target(n) for n in names}
    return {t for t in targets if t is not None} - _ancestors(module)


GRAPH = {module: imports_of(module) for module in LIBRARY}


def _strongly_connected(graph: dict[str, set[str]]) -> list[set[str]]:
    """Tarjan's strongly connected components of more than one module."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[set[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in graph:
                continue
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(component)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def documented_layers() -> list[tuple[str, list[str]]]:
    """The layers of ``docs/development.md``, lowest first: each numbered item of its
    "Layers" section reads ``N. **name**: `pattern`, `pattern`, ...``."""
    text = (ROOT / "docs" / "development.md").read_text()
    section = text.split("\n### Layers\n", 1)[1].split("\n#", 1)[0]
    layers = []
    for item in re.findall(r"^\d+\. \*\*(.+?)\*\*:(.*(?:\n   .*)*)", section, re.M):
        name, body = item
        layers.append((name, re.findall(r"`(fricenv[\w.*]*)`", body)))
    return layers


def layer_of(module: str, layers: list[tuple[str, list[str]]]) -> int:
    """The index of the layer whose patterns match ``module`` (the most specific pattern
    wins); ``LookupError`` if none does."""
    best: tuple[int, int] | None = None
    for i, (_, patterns) in enumerate(layers):
        for pattern in patterns:
            if fnmatch.fnmatchcase(module, pattern):
                rank = len(pattern.replace("*", ""))
                if best is None or rank > best[0]:
                    best = (rank, i)
    if best is None:
        raise LookupError(module)
    return best[1]


def test_the_graph_sees_every_kind_of_import() -> None:
    """The parser finds module- and function-level imports, ``import_module`` and the
    ``_HOMES`` tables (else the checks below would pass on an empty graph)."""
    assert "fricenv.core" in GRAPH["fricenv.simulate"]  # module level
    assert "fricenv.plotting" in GRAPH["fricenv.simulate"]  # function level
    assert "fricenv.sweep" in GRAPH["fricenv"]  # the package's _HOMES
    assert "fricenv.cli.simulate" in GRAPH["fricenv.cli"]  # a command's module name
    assert "fricenv.envs.stick_slip" in GRAPH["fricenv.envs"]  # an entry point


def test_the_library_imports_nothing_beside_it() -> None:
    """``fricenv`` works installed alone: nothing of the agents (``fricenv_agents``, which
    the command line reaches only through entry points), ``scripts`` or ``tests``."""
    outside = {(m, t) for m, targets in GRAPH.items() for t in targets
               if t.split(".")[0] in OUTSIDE}
    assert outside == set()


def test_no_import_cycle() -> None:
    """No cycle among the library's modules, lazy imports included."""
    assert _strongly_connected(GRAPH) == []


def test_every_module_has_a_documented_layer() -> None:
    layers = documented_layers()
    assert len(layers) >= 5
    unplaced = []
    for module in LIBRARY:
        try:
            layer_of(module, layers)
        except LookupError:
            unplaced.append(module)
    assert unplaced == []


def test_no_module_imports_a_higher_layer() -> None:
    """Each module imports only its own layer and those below (docs/development.md)."""
    layers = documented_layers()
    upward = []
    for module, targets in GRAPH.items():
        mine = layer_of(module, layers)
        for target in targets:
            if target in LIBRARY:
                theirs = layer_of(target, layers)
                if theirs > mine:
                    upward.append(f"{module} ({layers[mine][0]}) -> {target} "
                                  f"({layers[theirs][0]})")
    assert upward == []


def _imports_numba(module: str) -> tuple[bool, bool]:
    """Whether ``module`` imports numba at module level, and at function level."""
    tree = ast.parse(LIBRARY[module].read_text())
    top = {id(n) for n in tree.body}
    found = [False, False]
    for node in ast.walk(tree):
        names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                 [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level
                 else [])
        if any(n == "numba" or n.startswith("numba.") for n in names):
            found[id(node) not in top] = True
    return found[0], found[1]


#: numba extensions that decorate no kernel and read no setting: an ``@intrinsic`` is typed
#: and compiled only inside the kernels that call it, which import fricenv.jit.
NUMBA_EXTENSIONS = {"fricenv.atomic"}
#: The cold-start profile's child records numba's compile events from before it imports
#: the package (the import's own compiles included), so it imports numba first on purpose.
NUMBA_PROBES = {"fricenv.bench.compile"}


@pytest.mark.parametrize("module", sorted(LIBRARY))
def test_numba_is_imported_with_fricenv_jit(module: str) -> None:
    """fricenv.jit loads TBB, keys numba's cache on the package's source and picks the
    threading layer; a module that uses numba imports it at module level, so that all that
    is done before any of the module's kernels is decorated or its code starts numba's
    threads. Function-level imports of numba go through fricenv.jit."""
    if module in ("fricenv.jit", "fricenv._numba_cache"):
        return
    at_top, in_function = _imports_numba(module)
    assert not in_function or module in NUMBA_PROBES, f"{module} imports numba in a function"
    if at_top and module not in NUMBA_EXTENSIONS:
        tree = ast.parse(LIBRARY[module].read_text())
        top_level = {_resolve(n.module or "", _package(module), n.level)
                     for n in tree.body if isinstance(n, ast.ImportFrom)}
        assert "fricenv.jit" in top_level, f"{module} imports numba but not fricenv.jit"
