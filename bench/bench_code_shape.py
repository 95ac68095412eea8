"""The shape of the shells, as the code rules measure it: the longest CLI command and HTTP route, the
longest function in app/, and the import circles among src/doorloc's modules.

    python bench/bench_code_shape.py [REPO]

Uses the measures of tests/core/test_code_rules.py (the test asserts the limits; this prints the figures).
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

REPO = Path(sys.argv[1]).resolve() if len(sys.argv) > 1 else Path(__file__).resolve().parents[1]
RULES = (
    Path(__file__).resolve().parents[1] / "tests" / "core" / "test_code_rules.py"
)  # (measures another REPO too)
_spec = importlib.util.spec_from_file_location("code_rules", RULES)
rules = importlib.util.module_from_spec(_spec)  # type: ignore[arg-type]
_spec.loader.exec_module(rules)  # type: ignore[union-attr]

app = REPO / "src" / "doorloc" / "app"
entries, whole = [], []
for path in sorted(app.rglob("*.py")):
    where = path.relative_to(app).as_posix()
    entries += [(n, f"{where}:{name}") for name, n, entry in rules.function_lengths(path) if entry]
    whole += [(n, f"{where}:{name}") for name, n in rules.whole_lengths(path)]
print(f"longest command or route body (statements, limit {rules.MAX_COMMAND_LINES}):", *sorted(entries)[-3:])
print(f"longest function in app/ (def to end, limit {rules.MAX_FUNCTION_LINES}):", *sorted(whole)[-3:])
graph = rules.import_graph(REPO / "src")
print("import circle, any:", rules.import_circle(graph))
