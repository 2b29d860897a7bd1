"""No module reads another object's private attributes: ``x._name`` with ``x`` not ``self`` or
``cls`` is allowed only when ``_name`` is an attribute defined in the same module (a method or class
attribute of a class defined there, or assigned as ``self._name`` / ``cls._name`` there), i.e. a
class's own internals used beside it. What another module needs is public, with a name that says
what it is and a docstring.

A heuristic (the type of ``x`` is not known): a read of another class's ``_name`` is missed when the
module defines an attribute of the same name itself. The exceptions are listed, each with its
reason, in ALLOWED_NAMES (public by documentation despite the underscore) and ALLOWED_READS
(entries marked "pending" wait for code being changed elsewhere and may disappear with it).
"""

from __future__ import annotations

import ast
from pathlib import Path

import attend

PACKAGE = Path(attend.__file__).parent

#: Underscored names that are public API by their library's documentation.
ALLOWED_NAMES = {
    # collections.namedtuple / typing.NamedTuple: the underscore only avoids clashes with field names
    "_replace": "NamedTuple API",
    "_asdict": "NamedTuple API",
    "_fields": "NamedTuple API",
    "_make": "NamedTuple API",
}

#: (file relative to src/, the expression read) -> why it is allowed.
ALLOWED_READS = {
    ("attend/action/mission/map_painter.py", "os._exit"):
        "the documented way for a forked child to end without running the parent's cleanup",
}


def own_attributes(tree: ast.AST) -> set[str]:
    """Attribute names the module defines: methods, nested classes and class attributes (plain or
    annotated, e.g. dataclass fields) of its classes, and names assigned as self.X or cls.X."""
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ClassDef):
            for item in node.body:
                if isinstance(item, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                    names.add(item.name)
                elif isinstance(item, ast.Assign):
                    names.update(target.id for target in item.targets if isinstance(target, ast.Name))
                elif isinstance(item, ast.AnnAssign) and isinstance(item.target, ast.Name):
                    names.add(item.target.id)
        elif (isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store)
              and isinstance(node.value, ast.Name) and node.value.id in ("self", "cls")):
            names.add(node.attr)
    return names


def private_reads(source: str) -> list[tuple[int, str]]:
    """(line, expression) of every ``x._name`` in ``source`` (x not self or cls; _name not a dunder
    and not an attribute the module defines itself, see :func:`own_attributes`)."""
    tree = ast.parse(source)
    own = own_attributes(tree)
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Attribute) or not node.attr.startswith("_") or node.attr.startswith("__"):
            continue
        if isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"):
            continue
        if node.attr in own or node.attr in ALLOWED_NAMES:
            continue
        found.append((node.lineno, ast.unparse(node)))
    return sorted(found)


def test_the_check_finds_reads_of_another_objects_private_attributes():
    source = (
        "class Mine:\n"
        "    _limit = 3\n"
        "    def __init__(self):\n"
        "        self._state = 0\n"
        "    def _step(self):\n"
        "        return self._state\n"
        "def use(mine, other, point):\n"
        "    mine._step(); mine._state; Mine._limit; point._replace(x=1); other.__class__\n"
        "    return other._matrices['offsets'], other.estimator._check\n"
    )
    assert [text for _, text in private_reads(source)] == ["other._matrices", "other.estimator._check"]


def test_no_module_reads_another_objects_private_attributes():
    found, used = [], set()
    for path in sorted(PACKAGE.rglob("*.py")):
        name = path.relative_to(PACKAGE.parent).as_posix()
        for line, text in private_reads(path.read_text(encoding="utf-8")):
            if (name, text) in ALLOWED_READS:
                used.add((name, text))
            else:
                found.append(f"{name}:{line}: {text}")
    assert not found, "reads of another object's private attributes:\n" + "\n".join(found)
    stale = sorted(key for key in set(ALLOWED_READS) - used if not ALLOWED_READS[key].startswith("pending"))
    assert not stale, f"ALLOWED_READS entries that no longer occur (remove them): {stale}"
