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


def _is_entry_point(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    """Decorated ``@app.command(...)`` (typer) or ``@router.get(...)`` and the like (FastAPI)."""
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
    out = []
    for fn in _functions(tree):
        entry = _is_entry_point(fn)
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
