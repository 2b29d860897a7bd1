"""Code size: modules over MAX_MODULE_LINES lines and functions over MAX_FUNCTION_LINES lines.

Usage: python benchmarks/code_size.py [ROOT] (default: src/attend beside this folder).
Lines are physical lines (docstrings and comments included); a function's size runs from its
``def`` (decorators excluded) to its last line, nested functions counted inside their parent and
listed on their own as well. Exit status 0 always: this is a report, not a gate.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 80


def module_sizes(root: Path) -> list[tuple[int, str]]:
    """(lines, path) of every .py file under root."""
    return [(len(path.read_text().splitlines()), str(path)) for path in sorted(root.rglob("*.py"))]


def function_sizes(root: Path) -> list[tuple[int, str]]:
    """(lines, path:qualified name) of every function and method under root."""
    found = []
    for path in sorted(root.rglob("*.py")):
        tree = ast.parse(path.read_text(), filename=str(path))

        def visit(node, prefix):
            for child in ast.iter_child_nodes(node):
                if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    name = f"{prefix}{child.name}"
                    found.append((child.end_lineno - child.lineno + 1, f"{path}:{child.lineno} {name}"))
                    visit(child, f"{name}.")
                elif isinstance(child, ast.ClassDef):
                    visit(child, f"{prefix}{child.name}.")
                else:
                    visit(child, prefix)

        visit(tree, "")
    return found


def main(argv: list[str]) -> int:
    root = Path(argv[1]) if len(argv) > 1 else Path(__file__).resolve().parents[1] / "src" / "attend"
    modules = sorted((m for m in module_sizes(root) if m[0] > MAX_MODULE_LINES), reverse=True)
    functions = sorted((f for f in function_sizes(root) if f[0] > MAX_FUNCTION_LINES), reverse=True)
    base = root.parent
    print(f"modules over {MAX_MODULE_LINES} lines: {len(modules)}")
    for lines, path in modules:
        print(f"  {lines:5d}  {Path(path).relative_to(base)}")
    print(f"functions over {MAX_FUNCTION_LINES} lines: {len(functions)}")
    for lines, where in functions:
        path, name = where.split(" ", 1)
        print(f"  {lines:5d}  {Path(path.rsplit(':', 1)[0]).relative_to(base)}:{path.rsplit(':', 1)[1]} {name}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
