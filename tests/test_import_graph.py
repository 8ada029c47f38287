"""The library's import graph: it stands alone, has no cycle and only looks down.

Every module under ``fricenv/`` is parsed (nothing is imported), and an edge is drawn for
each import, at module or function level, for each ``importlib.import_module`` of a
constant name, for each string that names a module (``"fricenv.cli.simulate"``, an entry
point ``"fricenv.envs.vector:StickSlipVectorEnv"``) and for each value of a package's
``_HOMES`` table (the public names its ``__getattr__`` imports on first use). Attribute use of
an imported name is an import too: ``import fricenv`` then ``fricenv.regime_map`` imports
``fricenv.sweep``. The layers are read from ``docs/development.md``, so that the page and the
check cannot drift apart. The agents (``agents/``, installed as ``fricenv_agents``) are
parsed the same way and checked for cycles.
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


def _homes_table(node: ast.expr) -> dict[str, str]:
    """A ``_HOMES`` table's literal entries: ``{"name": "module"}`` and
    ``**dict.fromkeys(("a", "b"), "module")``."""
    table: dict[str, str] = {}
    for sub in ast.walk(node):
        if isinstance(sub, ast.Dict):
            table.update({k.value: v.value for k, v in zip(sub.keys, sub.values, strict=True)
                          if isinstance(k, ast.Constant) and isinstance(v, ast.Constant)})
        elif (isinstance(sub, ast.Call) and getattr(sub.func, "attr", None) == "fromkeys"
              and len(sub.args) == 2 and isinstance(sub.args[1], ast.Constant)):
            table.update({e.value: sub.args[1].value for e in ast.walk(sub.args[0])
                          if isinstance(e, ast.Constant)})
    return table


def _lazy_homes() -> dict[str, dict[str, str]]:
    """package -> its ``_HOMES`` table (public name -> module relative to the package)."""
    out: dict[str, dict[str, str]] = {}
    for name, path in MODULES.items():
        if path.name != "__init__.py":
            continue
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            targets = (node.targets if isinstance(node, ast.Assign) else
                       [node.target] if isinstance(node, ast.AnnAssign) else [])
            if any(getattr(t, "id", None) == "_HOMES" for t in targets):
                assert isinstance(node, (ast.Assign, ast.AnnAssign)) and node.value is not None
                out[name] = _homes_table(node.value)
    return out


HOMES = _lazy_homes()


def _canonical(name: str) -> str:
    """``name`` as the checkout spells it: ``fricenv_agents`` installs the folder ``agents``."""
    head, dot, rest = name.partition(".")
    return f"agents{dot}{rest}" if head == "fricenv_agents" else name


def _target(name: str) -> str | None:
    """The known module ``name`` denotes: itself, the module holding it as an attribute
    (``fricenv.simulate.simulate`` -> ``fricenv.simulate``), or the home of a package's
    lazy public name (``fricenv.regime_map`` -> ``fricenv.sweep``); None if outside the
    checkout."""
    name = _canonical(name)
    while name:
        package, _, attr = name.rpartition(".")
        if package in HOMES and attr in HOMES[package]:
            return f"{package}.{HOMES[package][attr]}"
        if name in MODULES:
            return name
        name = package
    return None


def _ancestors(module: str) -> set[str]:
    parts = module.split(".")
    return {".".join(parts[:i]) for i in range(1, len(parts) + 1)}


def _attribute_chain(node: ast.Attribute) -> list[str] | None:
    """``a.b.c`` as ``["a", "b", "c"]``; None unless the chain starts at a plain name."""
    parts = [node.attr]
    value = node.value
    while isinstance(value, ast.Attribute):
        parts.append(value.attr)
        value = value.value
    return [value.id, *reversed(parts)] if isinstance(value, ast.Name) else None


def _bound_modules(tree: ast.AST, package: str) -> dict[str, str]:
    """Local name -> the dotted name it is bound to by an import (``import fricenv`` binds
    ``fricenv``; ``import fricenv.envs as E`` binds ``E``; ``from fricenv import envs``
    binds ``envs``), so that attribute use (``fricenv.regime_map``) counts as an import."""
    bound: dict[str, str] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.asname:
                    bound[alias.asname] = alias.name
                else:
                    top = alias.name.split(".")[0]
                    bound[top] = top
        elif isinstance(node, ast.ImportFrom):
            base = _resolve(node.module or "", package, node.level)
            for alias in node.names:
                bound[alias.asname or alias.name] = f"{base}.{alias.name}"
    return bound


def imports_in(source: str, module: str) -> set[str]:
    """The known modules that ``source``, read as module ``module``, imports or names
    (see the module docstring); attribute use of an imported name counts too."""
    package = _package(module)
    names: set[str] = set()
    tree = ast.parse(source)
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
    bound = _bound_modules(tree, package)
    for node in ast.walk(tree):
        chain = _attribute_chain(node) if isinstance(node, ast.Attribute) else None
        if chain and chain[0] in bound:
            names.add(".".join([bound[chain[0]], *chain[1:]]))
    targets = {_target(n) for n in names}
    return {t for t in targets if t is not None} - _ancestors(module)


def imports_of(module: str) -> set[str]:
    """The known modules ``module`` of the checkout imports or names."""
    return imports_in(MODULES[module].read_text(), module)


GRAPH = {module: imports_of(module) for module in LIBRARY}
#: The agents (``agents/``, installed as ``fricenv_agents``): the top layer.
AGENTS = {name: path for name, path in MODULES.items() if name.split(".")[0] == "agents"}
AGENTS_GRAPH = {module: imports_of(module) for module in AGENTS}


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
    assert "fricenv.plotting" in GRAPH["fricenv.trajectory"]  # function level
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


@pytest.mark.parametrize("source, found", [
    ("import fricenv\ndef f():\n    return fricenv.regime_map", "fricenv.sweep"),
    ("import fricenv\nfricenv.envs.kernels.N_OBS", "fricenv.envs.kernels"),
    ("import fricenv.envs as E\nE.vector", "fricenv.envs.vector"),
    ("from fricenv import simulate", "fricenv.simulate"),
    ("from fricenv import regime_map", "fricenv.sweep"),
    ("from fricenv import atlas\natlas.open_atlas", "fricenv.atlas.store"),
])
def test_attribute_use_of_an_imported_package_is_an_import(source: str, found: str) -> None:
    """``import fricenv`` then ``fricenv.regime_map`` in a lower layer imports the sweeps as
    surely as ``from fricenv import sweep`` does: the graph follows attributes of imported
    names and the packages' lazy public names to their home modules."""
    assert found in imports_in(source, "fricenv.core.contacts")


def test_the_agents_are_seen() -> None:
    """The agents' graph holds module- and function-level imports of the library and of
    each other (else the checks below would pass on an empty graph)."""
    assert "fricenv.envs.scenes" in AGENTS_GRAPH["agents.benchmark_rows"]  # module level
    assert "agents.estimation" in AGENTS_GRAPH["agents.benchmark_rows"]  # function level


def test_the_agents_import_no_scripts_or_tests() -> None:
    outside = {(m, t) for m, targets in AGENTS_GRAPH.items() for t in targets
               if t.split(".")[0] in ("scripts", "tests")}
    assert outside == set()


def test_no_import_cycle_in_the_agents() -> None:
    """No cycle among the agents' modules, function-level imports included."""
    assert _strongly_connected(AGENTS_GRAPH) == []


def test_only_programs_import_the_command_line() -> None:
    """The command line sits on top: no module outside ``fricenv.cli`` imports it, but the
    ``python -m`` programs (``__main__``), which nothing imports. So ``fricenv.atlas`` and
    ``fricenv.cli`` never import each other."""
    def outside(module: str) -> bool:
        return not (module == "fricenv.cli" or module.startswith("fricenv.cli."))

    found = {(m, t) for m, targets in GRAPH.items() for t in targets
             if outside(m) and not m.endswith(".__main__") and not outside(t)}
    assert found == set()
    assert not any("__main__" in t for targets in GRAPH.values() for t in targets)


#: Prefixes of the slot constants that index the library's flat arrays (``P_*`` parameters,
#: ``S_*`` state, ``ST_*`` statistics, ``PL_*`` plant vectors, ``T_*`` table columns,
#: ``C_*`` configuration, ``O_*`` observation, ``D_*`` draws, ``W_*`` workspace, ...) and
#: their sizes (``N_*``).
SLOT = re.compile(r"(P|S|ST|PL|T|C|O|OB|D|I|IV|R|W|A|F|CT|N)_[A-Z0-9_]+")


def slot_uses(path: Path) -> list[str]:
    """The slot constants a module of the agents takes from the library: imported by name
    (``from fricenv.params import P_LAM``) or read off an imported module (``K.O_X``)."""
    tree = ast.parse(path.read_text())
    modules: set[str] = set()
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "fricenv":
            for alias in node.names:
                if SLOT.fullmatch(alias.name):
                    found.append(f"{node.module}.{alias.name}")
                else:
                    modules.add(alias.asname or alias.name)
        elif isinstance(node, ast.Import):
            modules.update(a.asname or a.name.split(".")[0] for a in node.names
                           if a.name.split(".")[0] == "fricenv")
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and SLOT.fullmatch(node.attr)
                and _attribute_chain(node) and (_attribute_chain(node) or [""])[0] in modules):
            found.append(".".join(_attribute_chain(node) or []))
    return found


def test_the_agents_take_no_slot_constant() -> None:
    """The agents reach plants, observations and actions through named functions and
    records (``fricenv.envs.observation``), never through the library's array slots."""
    assert "fricenv.params.P_V" in slot_uses(ROOT / "tests" / "test_estimation.py")  # (seen)
    found = {module: uses for module, path in AGENTS.items() if (uses := slot_uses(path))}
    assert found == {}
