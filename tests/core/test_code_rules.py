"""Code rules that stay true only if a test measures them (developers' brief: thin CLI and HTTP shells)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

APP = Path(__file__).resolve().parents[2] / "src" / "doorloc" / "app"
#: a command or route is a few lines over one library call. Counted: the body's statements, not the
#: signature and docstring (ruff format writes one typer option per line, and a command's options are
#: declarations, not work).
MAX_COMMAND_LINES = 60
_ENTRY_DECORATORS = {"command", "callback", "get", "post", "put", "patch", "delete", "route", "websocket"}


def _functions(tree: ast.AST):
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield node


def _registered(tree: ast.AST) -> set[str]:
    """Names of functions registered by a call, ``app.command("x")(fn)`` or ``router.get("/x")(fn)``."""
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Call) and node.args:
            f = node.func.func
            if (
                isinstance(f, ast.Attribute)
                and f.attr in _ENTRY_DECORATORS
                and isinstance(node.args[0], ast.Name)
            ):
                names.add(node.args[0].id)
    return names


def _is_entry_point(fn: ast.FunctionDef | ast.AsyncFunctionDef, registered: set[str] = frozenset()) -> bool:
    """Decorated ``@app.command(...)`` (typer) or ``@router.get(...)`` and the like (FastAPI), or registered
    by a call (``app.command("x")(fn)``)."""
    if fn.name in registered:
        return True
    for d in fn.decorator_list:
        call = d.func if isinstance(d, ast.Call) else d
        if isinstance(call, ast.Attribute) and call.attr in _ENTRY_DECORATORS:
            return True
    return False


def _lines(node: ast.AST) -> int:
    return node.end_lineno - node.lineno + 1  # type: ignore[attr-defined]


def _body_lines(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """Lines from the first statement after the docstring to the end of ``fn``."""
    body = fn.body
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
        if isinstance(body[0].value.value, str):
            body = body[1:]
    if not body:
        return 0
    first = min([body[0].lineno] + [d.lineno for d in getattr(body[0], "decorator_list", [])])
    return body[-1].end_lineno - first + 1  # type: ignore[operator]


def _own_lines(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """Lines of ``fn`` less those of the functions and classes defined inside it (a ``register`` holding commands)."""
    nested = 0
    stack = list(ast.iter_child_nodes(fn))
    while stack:
        node = stack.pop()
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            nested += _lines(node) + len(getattr(node, "decorator_list", []))
        else:
            stack.extend(ast.iter_child_nodes(node))
    return _body_lines(fn) - nested


def function_lengths(path: Path) -> list[tuple[str, int, bool]]:
    """``(name, body lines, is_entry_point)`` for every function in ``path``; entry points counted whole."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    registered = _registered(tree)
    out = []
    for fn in _functions(tree):
        entry = _is_entry_point(fn, registered)
        out.append((fn.name, _body_lines(fn) if entry else _own_lines(fn), entry))
    return out


APP_FILES = sorted(APP.rglob("*.py"))


@pytest.mark.parametrize("path", APP_FILES, ids=lambda p: str(p.relative_to(APP)))
def test_commands_and_routes_are_thin(path):
    too_long = [
        f"{name} ({n} lines)" for name, n, entry in function_lengths(path) if entry and n > MAX_COMMAND_LINES
    ]
    assert not too_long, f"{path.name}: move the work into the library: {', '.join(too_long)}"


@pytest.mark.parametrize("path", sorted(APP.glob("cli*.py")), ids=lambda p: p.name)
def test_cli_helpers_are_short_too(path):
    """A command kept short by one long helper beside it is not a thin shell."""
    too_long = [f"{name} ({n} lines)" for name, n, _ in function_lengths(path) if n > MAX_COMMAND_LINES]
    assert not too_long, f"{path.name}: {', '.join(too_long)}"


def test_the_measure_sees_a_long_command(tmp_path):
    body = "".join(f"        x{i} = {i}\n" for i in range(70))
    src = tmp_path / "cli_x.py"
    src.write_text(
        f"def register(app):\n    @app.command('x')\n    def x() -> None:\n{body}    return None\n"
    )
    lengths = {name: (n, entry) for name, n, entry in function_lengths(src)}
    assert lengths["x"] == (70, True)  # its body; over the limit
    assert lengths["register"] == (1, False)  # the return; the command is counted on its own
    src.write_text(
        f"def x() -> None:\n{body[4:].replace(chr(10) + '    ', chr(10))}\n\ndef register(app):\n    app.command('x')(x)\n"
    )
    assert {name: (n, entry) for name, n, entry in function_lengths(src)}["x"] == (
        70,
        True,
    )  # registered by call
    assert [name for name, n in whole_lengths(src) if n > MAX_FUNCTION_LINES] == []  # 72 lines whole
    src.write_text("def register(app):\n    def x():\n" + "".join(f"        x{i} = {i}\n" for i in range(79)))
    assert whole_lengths(src) == [("register", 81), ("x", 80)]  # the register holding it counts it too


#: no function in app/ longer than this, counted whole (signature, docstring, nested functions and all)
MAX_FUNCTION_LINES = 80


def whole_lengths(path: Path) -> list[tuple[str, int]]:
    """``(name, lines from its ``def`` to its end)`` of every function in ``path``."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    return [(fn.name, _lines(fn)) for fn in _functions(tree)]


@pytest.mark.parametrize("path", APP_FILES, ids=lambda p: str(p.relative_to(APP)))
def test_no_function_in_app_is_long(path):
    """A long function in a shell is work that belongs in the library (a ``register`` holding its commands
    counts whole, so commands are written at module level and registered by name)."""
    too_long = [f"{name} ({n} lines)" for name, n in whole_lengths(path) if n > MAX_FUNCTION_LINES]
    assert not too_long, f"{path.name}: {', '.join(too_long)}"


# ---------------------------------------------------------------------------------------------- import circles

SRC = APP.parents[1]


def _module_name(path: Path, src: Path) -> str:
    parts = list(path.relative_to(src).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _is_type_checking(node: ast.If) -> bool:
    t = node.test
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (
        isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING"
    )


def import_graph(src: Path, package: str = "doorloc") -> dict[str, set[str]]:
    """``module -> modules of the package it imports``, at any depth: module level and inside functions
    (a lazy import is still an import); ``if TYPE_CHECKING:`` blocks are left out (never run)."""
    files = {_module_name(p, src): p for p in sorted((src / package).rglob("*.py"))}
    graph: dict[str, set[str]] = {}
    for mod, path in files.items():
        deps: set[str] = set()
        stack: list[ast.AST] = [ast.parse(path.read_text(encoding="utf-8"), filename=str(path))]
        while stack:
            node = stack.pop()
            if isinstance(node, ast.If) and _is_type_checking(node):
                stack.extend(node.orelse)
                continue
            if isinstance(node, ast.Import):
                deps |= {a.name for a in node.names if a.name in files}
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    pkg = mod.split(".") if path.name == "__init__.py" else mod.split(".")[:-1]
                    pkg = pkg[: len(pkg) - (node.level - 1)]
                    base = ".".join([*pkg, *([base] if base else [])])
                for a in node.names:
                    sub = f"{base}.{a.name}"
                    deps |= {sub} if sub in files else ({base} if base in files else set())
            stack.extend(ast.iter_child_nodes(node))
        graph[mod] = deps - {mod}
    return graph


def import_circle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import circle of ``graph`` (its modules, first repeated last), or None when there is none."""
    import graphlib

    try:
        graphlib.TopologicalSorter(graph).prepare()
    except graphlib.CycleError as e:
        return list(reversed(e.args[1]))
    return None


def test_no_import_circle_in_src():
    circle = import_circle(import_graph(SRC))
    assert circle is None, "import circle: " + " -> ".join(circle or [])


def test_the_circle_test_sees_a_lazy_circle(tmp_path):
    pkg = tmp_path / "doorloc"
    (pkg / "vision").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "vision" / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from doorloc.b import x\n")
    (pkg / "b.py").write_text("def f():\n    from doorloc import a\n")
    (pkg / "vision" / "p.py").write_text("from doorloc.vision import q\n")
    (pkg / "vision" / "q.py").write_text("def g():\n    from . import p\n")
    (pkg / "c.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from doorloc import d\n"
    )
    (pkg / "d.py").write_text("import doorloc.c\n")
    graph = import_graph(tmp_path)
    assert graph["doorloc.vision.q"] == {"doorloc.vision.p"} and graph["doorloc.c"] == set()
    assert set(import_circle(graph) or []) in (
        {"doorloc.a", "doorloc.b"},
        {"doorloc.vision.p", "doorloc.vision.q"},
    )
    (pkg / "b.py").write_text("x = 1\n")
    assert set(import_circle(import_graph(tmp_path)) or []) == {"doorloc.vision.p", "doorloc.vision.q"}
    (pkg / "vision" / "q.py").write_text("x = 1\n")
    assert import_circle(import_graph(tmp_path)) is None


@pytest.mark.parametrize("path", sorted(APP.glob("cli*.py")), ids=lambda p: p.name)
def test_cli_commands_are_short_whole(path):
    """Counted whole too (options and help included), a command stays within the limit: its options are
    shared declarations (cli_common) and its work a library call."""
    commands = {name for name, _, entry in function_lengths(path) if entry}
    too_long = [f"{n} ({k} lines)" for n, k in whole_lengths(path) if n in commands and k > MAX_COMMAND_LINES]
    assert not too_long, f"{path.name}: {', '.join(too_long)}"
