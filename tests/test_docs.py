"""The documentation cannot rot: its examples run, its commands parse, its API page is current.

- every ```python block of README.md, docs/*.md and docs/experiments/*.md runs (blocks of one page share a
  namespace and a temporary working directory, in page order);
- every ```console / ```bash block whose first command starts with ``attend `` runs through
  ``attend.cli.main`` in that directory and must exit 0; a block preceded by the line
  ``<!-- no-test -->`` (expensive: full reproductions) is not run, but each of its commands must
  still parse with the CLI's argument parser and name an existing experiment;
- a block preceded by ``<!-- file: NAME -->`` is written to NAME in the working directory first
  (model files shown on a page are the files the page's commands use);
- docs/api.md has an entry for every public name of the packages it has a section for, every
  public name has a docstring, and the site (mkdocs + mkdocstrings) builds with warnings as errors;
- every registered experiment has a page docs/experiments/NAME.md that shows
  ``attend reproduce NAME``, and the settings table of the page matches the module's SETTINGS.
"""

from __future__ import annotations

import contextlib
import copy
import importlib
import io
import re
import shlex
import sys
import warnings
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"
PAGES = [DOCS.parent / "README.md"] + sorted(DOCS.glob("*.md")) + sorted((DOCS / "experiments").glob("*.md"))
NO_TEST = "<!-- no-test -->"
FILE = re.compile(r"<!--\s*file:\s*(\S+)\s*-->")
#: At most this many command blocks may be skipped (expensive reproductions only).
MAX_SKIPPED = 12  # one per expensive reproduction page (search-scale added)


def blocks(path: Path) -> list[dict]:
    """Fenced code blocks of a page: language, code, first line number, directive."""
    out, lines = [], path.read_text().splitlines()
    i = 0
    while i < len(lines):
        match = re.match(r"^```(\w*)\s*$", lines[i])
        if not match:
            i += 1
            continue
        previous = next((lines[j].strip() for j in range(i - 1, -1, -1) if lines[j].strip()), "")
        start, i = i + 1, i + 1
        while i < len(lines) and lines[i].strip() != "```":
            i += 1
        out.append(dict(lang=match.group(1), code="\n".join(lines[start:i]), line=start, directive=previous))
        i += 1
    return out


def commands(code: str) -> list[list[str]]:
    """The command lines of a console block (``$ `` prompts and # comments removed)."""
    result = []
    for line in code.splitlines():
        line = line.strip()
        if line.startswith("$ "):
            line = line[2:]
        if line and not line.startswith("#"):
            result.append(shlex.split(line, comments=True))
    return result


def is_attend_block(block: dict) -> bool:
    cmds = commands(block["code"]) if block["lang"] in ("console", "bash", "sh", "shell") else []
    return bool(cmds) and cmds[0][0] == "attend"


@contextlib.contextmanager
def restored_experiment_modules():
    """Pages may edit an experiment's SETTINGS to show how; undo it for the other tests."""
    from attend import experiments

    modules = [importlib.import_module(module) for module, _ in experiments.EXPERIMENTS.values()
               if importlib.util.find_spec(module) is not None]
    saved = [(m, dict(vars(m)), {k: copy.deepcopy(v) for k, v in vars(m).items() if isinstance(v, (dict, list))})
             for m in modules]
    try:
        yield
    finally:
        for module, attributes, containers in saved:
            for key in set(vars(module)) - set(attributes):
                delattr(module, key)
            for key, value in attributes.items():
                setattr(module, key, value)
                if isinstance(value, dict):
                    value.clear()
                    value.update(containers[key])
                elif isinstance(value, list):
                    value[:] = containers[key]


def run_cli(argv: list[str]) -> tuple[int, str]:
    from attend.cli import main

    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        code = main(argv)
    return code, stdout.getvalue() + stderr.getvalue()


@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(DOCS.parent)) for p in PAGES])
def test_page_examples_run(page: Path, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    namespace: dict = {"__name__": f"docs_{page.stem}"}
    with restored_experiment_modules(), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for block in blocks(page):
            where = f"{page.relative_to(DOCS.parent)}:{block['line']}"
            target = FILE.search(block["directive"])
            if target:
                (tmp_path / target.group(1)).write_text(block["code"] + "\n")
            if block["lang"] == "python" and NO_TEST not in block["directive"]:
                try:
                    exec(compile(block["code"], where, "exec"), namespace)
                except Exception as error:  # name the page and line in the failure
                    raise AssertionError(f"python block at {where} failed: {type(error).__name__}: {error}") from error
            elif is_attend_block(block):
                for argv in commands(block["code"]):
                    assert argv[0] == "attend", f"{where}: mixed commands in an attend block: {argv}"
                    if NO_TEST in block["directive"]:
                        check_parses(argv[1:], where)
                        continue
                    code, output = run_cli(argv[1:])
                    assert code == 0, f"{where}: `{shlex.join(argv)}` exited {code}:\n{output}"


def check_parses(argv: list[str], where: str) -> None:
    """A skipped command still has to be a valid command line of the current CLI."""
    from attend import experiments
    from attend.cli import _build_parser

    stderr = io.StringIO()
    try:
        with contextlib.redirect_stderr(stderr):
            args = _build_parser().parse_args(argv)
    except SystemExit as error:
        raise AssertionError(f"{where}: `attend {shlex.join(argv)}` does not parse: {stderr.getvalue()}") from error
    if args.command == "reproduce":
        assert args.name in (*experiments.available(), "all", "list"), f"{where}: unknown experiment {args.name!r}"


def test_few_blocks_skipped():
    skipped = [f"{p.relative_to(DOCS.parent)}:{b['line']}" for p in PAGES for b in blocks(p)
               if NO_TEST in b["directive"]]
    assert len(skipped) <= MAX_SKIPPED, f"too many <!-- no-test --> blocks: {skipped}"
    assert all(is_attend_block(b) for p in PAGES for b in blocks(p) if NO_TEST in b["directive"]), \
        "only expensive attend commands may be marked no-test"


def test_docs_have_runnable_examples():
    python = sum(b["lang"] == "python" for p in PAGES for b in blocks(p))
    cli = sum(is_attend_block(b) and NO_TEST not in b["directive"] for p in PAGES for b in blocks(p))
    assert python >= 10 and cli >= 5, (python, cli)


# --- API reference ------------------------------------------------------------------------------

ROOT = DOCS.parent
#: A package section of docs/api.md: "## attend.models: ..." (the top-level section is "## attend: ...").
SECTION = re.compile(r"^## (attend[\w.]*):", re.MULTILINE)


def _public_names(module) -> list[str]:
    """``__all__`` if the module defines it, else the functions and classes defined in it."""
    import inspect

    if hasattr(module, "__all__"):
        return list(module.__all__)
    return sorted(
        name for name, value in vars(module).items()
        if not name.startswith("_") and (inspect.isfunction(value) or inspect.isclass(value))
        and getattr(value, "__module__", None) == module.__name__
    )


def _entry(module_name: str, name: str, obj) -> str:
    """The mkdocstrings identifier docs/api.md documents ``module_name.name`` under: the
    object's own path for functions and classes, the package's path for anything else."""
    import inspect

    if (inspect.isclass(obj) or inspect.isfunction(obj)) and getattr(obj, "__module__", None):
        return f"{obj.__module__}.{obj.__qualname__}"
    return f"{module_name}.{name}"


def test_api_page_builds_without_warnings(tmp_path):
    """The site, with the API reference rendered from the docstrings by mkdocstrings, builds
    with warnings as errors (broken links and anchors, unresolved cross-references)."""
    import subprocess

    done = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file", str(ROOT / "mkdocs.yml"),
         "--site-dir", str(tmp_path / "site")],
        capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 0, done.stdout + done.stderr
    page = (tmp_path / "site" / "api" / "index.html").read_text()
    assert 'id="attend.models.linear.LinearSystem"' in page  # the docstrings were rendered


def test_public_api_documented():
    """Every public name of every package with a section in docs/api.md has an entry there and
    a docstring, and so do the public methods and properties of its classes."""
    import inspect

    import attend

    api = (DOCS / "api.md").read_text()
    entries = set(re.findall(r"^::: ([\w.]+)\s*$", api, re.MULTILINE))
    packages = SECTION.findall(api)
    assert "attend" in packages and "attend.models" in packages, packages
    undocumented, missing = [], []
    for module_name in packages:
        module = importlib.import_module(module_name)
        for name in _public_names(module):
            obj = getattr(module, name)
            entry = _entry(module_name, name, obj)
            if entry not in entries and f"{module_name}.{name}" not in entries:
                missing.append(f"{module_name}.{name} (as ::: {entry})")
            if not (inspect.isclass(obj) or callable(obj)):
                continue
            if not (obj.__doc__ or "").strip():
                undocumented.append(f"{module_name}.{name}")
            if inspect.isclass(obj):
                for member, value in vars(obj).items():
                    if member.startswith("_") or not (inspect.isfunction(value) or isinstance(value, property)):
                        continue
                    if not ((value.__doc__ or "").strip()):
                        undocumented.append(f"{module_name}.{name}.{member}")
    assert not missing, f"public names without an entry in docs/api.md: {missing}"
    assert not undocumented, f"public names without a docstring: {sorted(set(undocumented))}"
    assert set(attend.__all__) <= set(_public_names(attend))
    stale = [e for e in entries if not _resolves(e)]
    assert not stale, f"docs/api.md entries that name nothing: {stale}"


def _resolves(identifier: str) -> bool:
    """Whether ``identifier`` (a.b.c.Name) names an importable object."""
    parts = identifier.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        try:
            for attribute in parts[cut:]:
                obj = getattr(obj, attribute)
        except AttributeError:
            return False
        return True
    return False


# --- experiment pages ---------------------------------------------------------------------------

def _experiments():
    from attend import experiments

    return experiments.available()


@pytest.mark.parametrize("name", list(_experiments()))
def test_experiment_page(name):
    from attend import experiments

    page = DOCS / "experiments" / f"{name}.md"
    assert page.is_file(), f"experiment {name!r} has no page {page.relative_to(DOCS.parent)}"
    text = page.read_text()
    assert f"attend reproduce {name}" in text
    assert f"experiments/{name}.md" in (DOCS / "reproduce.md").read_text(), "link it from docs/reproduce.md"
    module = experiments.load(name)
    settings = getattr(module, "SETTINGS", None)
    rows = settings_table(text)
    for key, value in rows.items():  # module constants (UPPER_CASE) shown in a table
        if key.isupper() and isinstance(getattr(module, key, None), (int, float, str, tuple)):
            constant = getattr(module, key)
            assert _same(value, constant), f"{page.name}: `{key}` is {value!r} on the page, {constant!r} in the code"
    if settings is None:
        assert rows, f"{page.name}: expected a table of the settings (| `NAME` | value | unit | ...)"
        return
    assert rows, f"{page.name}: expected a settings table (| `name` | value | unit | ...)"
    for key, value in rows.items():
        if key in settings:
            assert _same(value, settings[key]), f"{page.name}: `{key}` is {value!r} on the page, {settings[key]!r} in the code"
    missing = set(settings) - set(rows)
    assert not missing, f"{page.name}: settings missing from the table: {sorted(missing)}"


def settings_table(text: str) -> dict[str, str]:
    """Rows ``| `key` | value | ...`` of the page's settings table(s)."""
    rows = {}
    for line in text.splitlines():
        match = re.match(r"^\|\s*`(\w+)`\s*\|\s*([^|]*?)\s*\|", line)
        if match:
            rows[match.group(1)] = match.group(2).strip("` ")
    return rows


def _same(text: str, value) -> bool:
    if isinstance(value, str):
        return text.strip("\"'") == value
    if isinstance(value, (list, tuple)):
        parts = [p for p in re.split(r"[\s,\[\]()]+", text) if p]
        return len(parts) == len(value) and all(_same(p, v) for p, v in zip(parts, value))
    try:
        number = float(eval(text, {"__builtins__": {}}, {"exp": __import__("math").exp, "e": __import__("math").e}))
    except Exception:
        return False
    return abs(number - float(value)) <= 1e-3 * abs(float(value)) + 1e-12


def test_pages_linked_from_index():
    index = (DOCS / "index.md").read_text()
    for page in PAGES:
        if page.name != "index.md" and page.parent == DOCS:
            assert f"({page.name}" in index, f"docs/index.md does not link {page.name}"
    assert "reproduce.md" in index
