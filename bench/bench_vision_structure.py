#!/usr/bin/env python
"""How readable the vision package is, by counts: lines per module (as ``wc -l``), functions longer than 100
and 80 lines (``def`` to last line, nested functions counted on their own too), functions taking more than 8
parameters (``self`` not counted), private names imported across modules and import cycles (the rules of
tests/vision/test_module_rules.py).

Run:  python bench/bench_vision_structure.py [--src src] [--package doorloc/vision]
"""

from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _rules():
    """tests/vision/test_module_rules.py, whose measures of the import rules these counts share."""
    sys.path.insert(0, str(REPO / "tests" / "vision"))
    import test_module_rules

    return test_module_rules


def functions(folder: Path) -> list[tuple[str, int, int]]:
    """``(module.function, lines, parameters)`` of every function in ``folder``'s modules."""
    out = []
    for path in sorted(folder.glob("*.py")):
        for n in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef):
                a = n.args
                params = len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs)
                params += (a.vararg is not None) + (a.kwarg is not None)
                if a.args and a.args[0].arg in ("self", "cls"):
                    params -= 1
                out.append((f"{path.stem}.{n.name}", n.end_lineno - n.lineno + 1, params))  # type: ignore[operator]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--src", default=str(REPO / "src"))
    ap.add_argument("--package", default="doorloc/vision")
    args = ap.parse_args()
    folder = Path(args.src) / args.package
    sizes = {p.name: len(p.read_text(encoding="utf-8").splitlines()) for p in sorted(folder.glob("*.py"))}
    print(f"lines: {sum(sizes.values())} in {len(sizes)} modules")
    for name, n in sorted(sizes.items(), key=lambda kv: -kv[1]):
        print(f"  {n:5d} {name}")
    fns = functions(folder)
    for limit in (100, 80):
        long = sorted((f for f in fns if f[1] > limit), key=lambda f: -f[1])
        print(
            f"functions over {limit} lines: {len(long)}"
            + (f" (longest: {', '.join(f'{f[0]} {f[1]}' for f in long[:3])})" if long else "")
        )
    many = sorted((f for f in fns if f[2] > 8), key=lambda f: -f[2])
    print(
        f"functions over 8 parameters: {len(many)}"
        + (f" (most: {', '.join(f'{f[0]} {f[2]}' for f in many[:3])})" if many else "")
    )
    rules = _rules()
    graph, private = rules.module_imports(folder, args.package.replace("/", "."))
    print(
        f"private names imported across modules: {len(private)}"
        + (f" ({'; '.join(private)})" if private else "")
    )
    loop = rules.cycle(graph)
    print(f"import cycle: {loop or 'none'}")


if __name__ == "__main__":
    main()
