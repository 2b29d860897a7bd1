"""The package's import graph: no module imports itself back through others (no cycles among
the module-level imports), so any module can be imported first and the layers stay layers."""

from __future__ import annotations

import ast
from pathlib import Path

import attend

PACKAGE = Path(attend.__file__).parent


def _module_graph() -> dict[str, set[str]]:
    """module -> the attend modules its module-level statements import (imports inside
    functions are lazy by design and not counted)."""
    modules = {}
    for path in PACKAGE.rglob("*.py"):
        name = ".".join(("attend",) + path.relative_to(PACKAGE).with_suffix("").parts)
        modules[name.removesuffix(".__init__")] = path
    graph = {name: set() for name in modules}
    for name, path in modules.items():
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("attend"):
                for alias in node.names:
                    target = f"{node.module}.{alias.name}"
                    graph[name].add(target if target in modules else node.module)
            elif isinstance(node, ast.Import):
                graph[name].update(a.name for a in node.names if a.name in modules)
    return {name: {t for t in targets if t in modules and t != name} for name, targets in graph.items()}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index, low, on_stack, stack, found, counter = {}, {}, set(), [], [], 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def test_the_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycles():
    graph = _module_graph()
    assert len(graph) > 100
    assert _cycles(graph) == []


def test_no_private_name_is_imported_from_another_package():
    """A name starting with "_" stays inside its package (attend.X for a top-level X): other
    packages use the public name. Shared private modules (attend._validation, attend._threads,
    attend._lazy, ...) hold public names for the whole package and are not counted."""
    crossings = []
    for path in PACKAGE.rglob("*.py"):
        parts = ("attend",) + path.relative_to(PACKAGE).with_suffix("").parts
        package = parts[1] if len(parts) > 1 else ""
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("attend."):
                target = node.module.split(".")[1]
                crossings += [f"{'.'.join(parts)} imports {node.module}.{alias.name}" for alias in node.names
                              if alias.name.startswith("_") and target.removesuffix(".py") != package]
    assert not crossings, "\n".join(crossings)


#: What attend.models may import: itself, and the shared helpers every layer uses.
MODELS_MAY_IMPORT = ("attend.models", "attend._validation", "attend._lazy", "attend.constants")


def _attend_imports(tree: ast.AST) -> list[str]:
    """Every attend module or name a file imports, at module level or inside functions."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").split(".")[0] == "attend":
            found += [node.module if node.module != "attend" else f"attend.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            found += [a.name for a in node.names if a.name.split(".")[0] == "attend"]
    return found


def test_models_import_nothing_from_the_rest_of_attend():
    """attend.models (systems, noise, generalised coordinates, theta, the problem bank) is the layer
    everything else builds on: none of its modules imports perception, action, control, rhythm, io,
    the experiments or the command line, not even inside a function, and its lazy exports name
    only its own modules."""
    outside = []
    for path in sorted((PACKAGE / "models").rglob("*.py")):
        for name in _attend_imports(ast.parse(path.read_text(encoding="utf-8"))):
            if not any(name == allowed or name.startswith(allowed + ".") for allowed in MODELS_MAY_IMPORT):
                outside.append(f"{path.relative_to(PACKAGE.parent)} imports {name}")
    assert not outside, "\n".join(outside)
    import attend.models

    assert all(module.startswith("attend.models.") for module in attend.models._EXPORTS.values())


def test_the_models_check_sees_imports_inside_functions():
    tree = ast.parse("def f():\n    from attend.perception.dem import DEMObserver\nimport attend.io\nfrom attend import rhythm")
    assert sorted(_attend_imports(tree)) == ["attend.io", "attend.perception.dem", "attend.rhythm"]


#: What attend.io (reading, validating and writing files) may import: itself, the models it reads
#: into, and the shared helpers. Running estimators and learners on the files is attend.workflows'.
IO_MAY_IMPORT = ("attend.io", "attend.models", "attend._validation", "attend._lazy", "attend.constants")


def test_io_reads_and_writes_files_and_runs_no_estimator():
    """No module of attend.io imports perception, action, control, rhythm, the workflows that run
    estimators on its files, the experiments or the command line: not at module level, not inside
    a function, not for type annotations."""
    outside = []
    for path in sorted((PACKAGE / "io").rglob("*.py")):
        for name in _attend_imports(ast.parse(path.read_text(encoding="utf-8"))):
            if not any(name == allowed or name.startswith(allowed + ".") for allowed in IO_MAY_IMPORT):
                outside.append(f"{path.relative_to(PACKAGE.parent)} imports {name}")
    assert not outside, "\n".join(outside)
