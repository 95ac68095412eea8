"""Rules of the vision package's structure that stay true only if a test measures them.

- No private name (a leading underscore) is imported from, or read off, another module of the package:
  what two modules share is public, documented, in the module that owns it.
- No import cycle among the package's modules, counting every import a file holds (inside functions and
  under ``if __name__ == "__main__"`` too: a command-line block that imports its importers closes a loop
  for a reader as surely as a top-level import).
- No module over 700 lines; a function over 80 lines or 8 parameters says why in its head (a numba kernel's
  arguments are arrays and scalars, so its list stays flat; a kernel split in two may sum in another order).
"""

from __future__ import annotations

import ast
import graphlib
from pathlib import Path

VISION = Path(__file__).resolve().parents[2] / "src" / "doorloc" / "vision"
PACKAGE = "doorloc.vision"


def _is_private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def _imported_module(node: ast.ImportFrom, package: str) -> str | None:
    """The package module a ``from ... import`` names (``edges`` for ``from doorloc.vision.edges import``
    or ``from .edges import``), "" for the package itself, None for a module outside it."""
    if node.level == 1:
        return (node.module or "").split(".")[0]
    if node.module == package:
        return ""
    if node.module and node.module.startswith(package + "."):
        return node.module[len(package) + 1 :].split(".")[0]
    return None


def module_imports(folder: Path, package: str) -> tuple[dict[str, set[str]], list[str]]:
    """The import graph among ``folder``'s modules (each module: the modules it imports) and every private
    name one takes from another."""
    graph: dict[str, set[str]] = {}
    private: list[str] = []
    for path in sorted(folder.glob("*.py")):
        me = path.stem
        graph.setdefault(me, set())
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        aliases: dict[str, str] = {}  # local name -> package module bound to it
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                mod = _imported_module(node, package)
                if mod is None:
                    continue
                for a in node.names:
                    if mod == "":  # from doorloc.vision import jit
                        graph[me].add(a.name)
                        aliases[a.asname or a.name] = a.name
                    else:
                        graph[me].add(mod)
                        if _is_private(a.name) and mod != me:
                            private.append(f"{me} imports {mod}.{a.name}")
            elif isinstance(node, ast.Import):
                for a in node.names:
                    if a.name.startswith(package + "."):
                        mod = a.name[len(package) + 1 :].split(".")[0]
                        graph[me].add(mod)
                        if a.asname:
                            aliases[a.asname] = mod
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Attribute)
                and isinstance(node.value, ast.Name)
                and node.value.id in aliases
                and aliases[node.value.id] != me
                and _is_private(node.attr)
            ):
                private.append(f"{me} reads {aliases[node.value.id]}.{node.attr}")
    for me, imported in graph.items():
        imported.discard(me)
    return graph, sorted(set(private))


def cycle(graph: dict[str, set[str]]) -> list[str]:
    """One loop of modules importing each other (sorted names; empty where there is none)."""
    try:
        tuple(graphlib.TopologicalSorter(graph).static_order())
    except graphlib.CycleError as e:
        return sorted(set(e.args[1]))
    return []


def test_no_private_name_crosses_a_module_border():
    _, private = module_imports(VISION, PACKAGE)
    assert not private, "make them public in the module that owns them: " + "; ".join(private)


def test_no_import_cycle_in_vision():
    graph, _ = module_imports(VISION, PACKAGE)
    assert sum(map(len, graph.values())) > 10  # the graph was read (a parser that saw nothing would pass)
    assert not cycle(graph), f"modules importing each other: {cycle(graph)}"


def test_the_rules_see_a_private_import_and_a_loop(tmp_path):
    pkg = tmp_path / "vision"
    pkg.mkdir()
    (pkg / "a.py").write_text("from doorloc.vision.b import _hidden\n")
    (pkg / "b.py").write_text("def f():\n    from doorloc.vision import c\n    return c._x\n")
    (pkg / "c.py").write_text('if __name__ == "__main__":\n    import doorloc.vision.a\n')
    (pkg / "d.py").write_text("from .a import public\n")
    graph, private = module_imports(pkg, PACKAGE)
    assert private == ["a imports b._hidden", "b reads c._x"]
    assert cycle(graph) == ["a", "b", "c"]
    (pkg / "c.py").write_text("")
    graph, _ = module_imports(pkg, PACKAGE)
    assert not cycle(graph)


#: the sizes past which a module or a function must say why it is that big
MAX_MODULE_LINES = 700
MAX_FUNCTION_LINES = 80
MAX_PARAMETERS = 8
WHY_LONG = "# why long:"
WHY_MANY = "# why many parameters:"


def unexplained_sizes(folder: Path) -> list[str]:
    """Every module over :data:`MAX_MODULE_LINES` lines and every function over :data:`MAX_FUNCTION_LINES`
    lines (``def`` to its last line) or :data:`MAX_PARAMETERS` parameters (``self`` and ``cls`` not counted)
    whose head does not say why, in a ``# why long: ...`` or ``# why many parameters: ...`` comment between
    its ``def`` and its first statement after the docstring."""
    found = []
    for path in sorted(folder.glob("*.py")):
        lines = path.read_text(encoding="utf-8").splitlines()
        if len(lines) > MAX_MODULE_LINES:
            found.append(f"{path.stem}: {len(lines)} lines")
        for node in ast.walk(ast.parse("\n".join(lines), filename=str(path))):
            if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            a = node.args
            params = len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs)
            params += (a.vararg is not None) + (a.kwarg is not None)
            if a.args and a.args[0].arg in ("self", "cls"):
                params -= 1
            length = node.end_lineno - node.lineno + 1  # type: ignore[operator]
            body = node.body[1:] if ast.get_docstring(node) is not None and len(node.body) > 1 else node.body
            head = "\n".join(lines[node.lineno - 1 : body[0].lineno - 1])
            if length > MAX_FUNCTION_LINES and WHY_LONG not in head:
                found.append(f"{path.stem}.{node.name}: {length} lines")
            if params > MAX_PARAMETERS and WHY_MANY not in head:
                found.append(f"{path.stem}.{node.name}: {params} parameters")
    return found


def test_long_functions_and_long_parameter_lists_say_why():
    found = unexplained_sizes(VISION)
    assert not found, f"split them, or say why in a '{WHY_LONG}' / '{WHY_MANY}' comment: " + "; ".join(found)


def test_the_size_rule_sees_a_long_function_and_reads_its_reason(tmp_path):
    long_body = "".join(f"    x{i} = {i}\n" for i in range(MAX_FUNCTION_LINES))
    many = ", ".join(f"p{i}" for i in range(MAX_PARAMETERS + 1))
    (tmp_path / "m.py").write_text(
        f'def long():\n    """Doc."""\n{long_body}\n'
        f"def wide(self, {many[:-4]}):\n    return 1\n"
        f"def wider({many}):\n    return 1\n"
    )
    assert unexplained_sizes(tmp_path) == ["m.long: 82 lines", "m.wider: 9 parameters"]
    (tmp_path / "m.py").write_text(
        f'def long():\n    """Doc."""\n    {WHY_LONG} one table, read in one pass\n{long_body}\n'
        f"def wider({many}):\n    {WHY_MANY} a compiled kernel's arguments\n    return 1\n"
    )
    assert unexplained_sizes(tmp_path) == []
    (tmp_path / "m.py").write_text("\n" * (MAX_MODULE_LINES + 1))
    assert unexplained_sizes(tmp_path) == ["m: 701 lines"]
