"""Generate docs/api.md, the API reference, from the docstrings of attend's public modules.

    python docs/gen_api.py            # rewrite docs/api.md
    python docs/gen_api.py --check    # exit 1 if docs/api.md is out of date

tests/test_docs.py runs :func:`render` and compares it with docs/api.md, so the reference cannot
drift from the code: after changing a public signature or docstring, rerun this script.

Documented: every name in ``attend.__all__`` and the public functions and classes of
attend.models, attend.models.problems, attend.perception.learning, attend.perception.references,
attend.io and attend.perception.interop (their ``__all__`` where they define one, else every
public function/class defined in the module).
"""

from __future__ import annotations

import importlib
import inspect
import re
import sys
from pathlib import Path

API_PATH = Path(__file__).resolve().parent / "api.md"

#: (module, heading, introduction)
MODULES = [
    ("attend", "attend: the top-level API",
     "`import attend` gives the systems, simulation, noise, generalised coordinates and the DEM "
     "observer. Times are in seconds throughout (`dt`, `kernel_width`, continuous-time `A` in 1/s)."),
    ("attend.models", "attend.models: systems, noise, generalised coordinates, parameters",
     "What a system is: linear and nonlinear systems and their simulation, coloured noise, "
     "generalised coordinates, the parameter vector theta. Imports nothing from the rest of attend."),
    ("attend.models.problems", "attend.models.problems: the paper's reference problems",
     "The systems of the paper (also at the top level) and the mass-spring-damper identification "
     "bank that the experiments, benchmarks and tests share."),
    ("attend.perception.learning", "attend.perception.learning: parameters and noise precisions",
     "System identification by alternating D (states), E (parameters) and M (noise precisions) "
     "steps; subspace and EM baselines; basis-invariant model errors. See "
     "[Getting started](getting-started.md#identify-the-parameters-of-your-robot)."),
    ("attend.perception.references", "attend.perception.references: Kalman filters and the exact posterior",
     "References on the same data as DEM (Kalman filters and smoothers, the exact posterior) and on "
     "the same logs as `identify` (N4SID, EM, basis-invariant model errors). Arrays are time-major; dt in seconds."),
    ("attend.io", "attend.io: model files, logs and estimate files",
     "The TOML model file and CSV log that `attend estimate` reads, and the CSV it writes. "
     "Format: [Getting started](getting-started.md#the-model-file)."),
    ("attend.perception.interop", "attend.perception.interop: python-control",
     "The DEM observer as a `control.StateSpace` (needs `pip install control`); the other way, "
     "`attend.models.from_statespace`."),
    ("attend.action.mission", "attend.action.mission: a search on your own ground",
     "The mission behind `attend plan`: the area from GeoJSON, KML or a QGroundControl .plan, the "
     "images and detections flown so far, the map, the next plans and the likely people. See "
     "[A search on your own ground](mission.md)."),
    ("attend.control", "attend.control: active inference control",
     "The agent, the world, the closed loop, PID and LQG baselines and metrics. See "
     "[Active inference control](control.md)."),
]


def public_names(module) -> list[str]:
    """``__all__`` if the module defines it, else the functions and classes defined in it."""
    if hasattr(module, "__all__"):
        return list(module.__all__)
    return sorted(
        name for name, value in vars(module).items()
        if not name.startswith("_") and (inspect.isfunction(value) or inspect.isclass(value))
        and getattr(value, "__module__", None) == module.__name__
    )


def _clean(text: str) -> str:
    return re.sub(r" at 0x[0-9a-fA-F]+", "", text)


class _Annotation:
    """A string annotation (``from __future__ import annotations``) shown without quotes."""

    def __init__(self, text: str):
        self.text = text

    def __repr__(self) -> str:
        return self.text


def _unquote(annotation):
    text = getattr(annotation, "__forward_arg__", annotation)  # typing.ForwardRef (NamedTuple fields)
    return _Annotation(text.strip("'\"")) if isinstance(text, str) else annotation


def _signature(name: str, obj) -> str:
    try:
        signature = inspect.signature(obj)
    except (TypeError, ValueError):
        return name
    signature = signature.replace(
        parameters=[p.replace(annotation=_unquote(p.annotation)) for p in signature.parameters.values()],
        return_annotation=_unquote(signature.return_annotation),
    )
    if inspect.isclass(obj):
        parameters = [p for p in signature.parameters.values() if not p.name.startswith("_")]
        signature = signature.replace(parameters=parameters, return_annotation=inspect.Signature.empty)
    return _clean(f"{name}{signature}")


def _members(cls) -> list[tuple[str, object]]:
    """Public methods and properties defined by the class itself (not inherited)."""
    members = []
    for name, value in vars(cls).items():
        if name.startswith("_"):
            continue
        if isinstance(value, property) or inspect.isfunction(value) or isinstance(value, (staticmethod, classmethod)):
            members.append((name, value))
    return members


def _kind(obj) -> str:
    if inspect.isclass(obj):
        if issubclass(obj, Warning):
            return "warning"
        if issubclass(obj, Exception):
            return "exception"
        if issubclass(obj, tuple) and hasattr(obj, "_fields"):
            return "named tuple"
        return "class"
    return "function"


def _doc(obj) -> str:
    return inspect.cleandoc(obj.__doc__ or "").strip()


def missing_docstrings() -> list[str]:
    """Public objects (and their public methods/properties) without a docstring."""
    missing = []
    for module_name, _, _ in MODULES:
        module = importlib.import_module(module_name)
        for name in public_names(module):
            obj = getattr(module, name)
            if not (inspect.isclass(obj) or callable(obj)):
                continue
            if not _doc(obj):
                missing.append(f"{module_name}.{name}")
            if inspect.isclass(obj):
                for member, value in _members(obj):
                    target = value.fget if isinstance(value, property) else getattr(value, "__func__", value)
                    if not _doc(target):
                        missing.append(f"{module_name}.{name}.{member}")
    return missing


def render() -> str:
    """The text of docs/api.md."""
    lines = [
        "# API reference",
        "",
        "<!-- Generated by docs/gen_api.py from the docstrings: do not edit by hand. -->",
        "",
        "Generated from the docstrings (`python docs/gen_api.py`); `tests/test_docs.py` fails when this",
        "page is out of date. Conventions: times in seconds, arrays time-major `(n_samples, n_channels)`,",
        "generalised coordinates order-major `[x; x'; x''; ...]`, precisions are inverse variances",
        "(units: 1 / unit^2 of the quantity).",
        "",
        "Modules:",
        "",
    ]
    for module_name, heading, _ in MODULES:
        anchor = re.sub(r"[^a-z0-9 -]", "", heading.lower()).replace(" ", "-")
        lines.append(f"- [`{module_name}`](#{anchor})")
    lines.append("")
    for module_name, heading, intro in MODULES:
        module = importlib.import_module(module_name)
        lines += [f"## {heading}", "", intro, ""]
        names = public_names(module)
        lines.append("Contents: " + ", ".join(f"`{name}`" for name in names) + ".")
        lines.append("")
        for name in names:
            obj = getattr(module, name)
            qualified = f"{module_name}.{name}"
            if not (inspect.isclass(obj) or callable(obj)):
                lines += [f"### `{qualified}`", "", f"Constant: `{obj!r}`.", ""]
                continue
            home = getattr(obj, "__module__", module_name)
            lines += [f"### `{qualified}`", ""]
            where = f" (defined in `{home}`)" if home != module_name else ""
            lines += [f"*{_kind(obj)}*{where}", "", "```text", _signature(name, obj), "```", ""]
            doc = _doc(obj)
            if doc:
                lines += ["```text", doc, "```", ""]
            if inspect.isclass(obj):
                for member, value in _members(obj):
                    if isinstance(value, property):
                        title, target = f"{name}.{member}", value.fget
                        label = "property"
                    else:
                        target = getattr(value, "__func__", value)
                        title, label = _signature(f"{name}.{member}", target).replace("(self, ", "(").replace(
                            "(self)", "()"), "method"
                    lines += [f"- *{label}* `{title}`", ""]
                    member_doc = _doc(target)
                    if member_doc:
                        lines += ["  ```text"] + [("  " + line).rstrip() for line in member_doc.splitlines()]
                        lines += ["  ```", ""]
    return "\n".join(lines).rstrip() + "\n"


def main(argv: list[str]) -> int:
    text = render()
    if "--check" in argv:
        if not API_PATH.exists() or API_PATH.read_text() != text:
            print(f"{API_PATH} is out of date: run python docs/gen_api.py", file=sys.stderr)
            return 1
        return 0
    API_PATH.write_text(text)
    print(f"wrote {API_PATH}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
