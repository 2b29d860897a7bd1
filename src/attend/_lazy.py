"""Public names of a package imported on first use (PEP 562), so that ``import attend`` and its
subpackages load only what a command needs."""

from __future__ import annotations

import importlib
import importlib.util


def lazy_exports(package: str, exports: dict[str, str], namespace: dict, subpackages: bool = True):
    """(__getattr__, __dir__) for ``package``: a name of ``exports`` (name -> module defining it)
    is imported from its module on first use and bound in ``namespace`` (the package's
    globals()); with ``subpackages``, any other public name that is a submodule of the package
    is imported as that submodule."""

    def __getattr__(name: str):
        if name not in exports:
            if subpackages and not name.startswith("_") and importlib.util.find_spec(f"{package}.{name}") is not None:
                return importlib.import_module(f"{package}.{name}")  # the import binds it in the namespace
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(exports[name]), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(exports))

    return __getattr__, __dir__
