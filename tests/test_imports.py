"""Importing attend and every submodule changes no process-wide state: matplotlib's backend,
``warnings.formatwarning``, ``warnings.showwarning`` and ``os.environ`` are as they were.
(The warning filters are not compared: scipy adds its own at import.)

The imports run in a fresh interpreter (this process has already imported attend and set its
own environment in conftest.py), with matplotlib's backend preset to "svg" so that a module that
selects Agg at import would show. ``attend.__main__`` is left out: running it is the CLI.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"

SCRIPT = r"""
import json, os, pkgutil, importlib, warnings
import matplotlib
before = dict(backend=matplotlib.get_backend(), formatwarning=repr(warnings.formatwarning),
              showwarning=repr(warnings.showwarning), environ=dict(os.environ))
import attend
names = ["attend"]
for info in pkgutil.walk_packages(attend.__path__, "attend."):
    if info.name != "attend.__main__":
        importlib.import_module(info.name)
        names.append(info.name)
after = dict(backend=matplotlib.get_backend(), formatwarning=repr(warnings.formatwarning),
             showwarning=repr(warnings.showwarning), environ=dict(os.environ))
print(json.dumps(dict(before=before, after=after, modules=names)))
"""


def _run() -> dict:
    env = dict(os.environ, MPLBACKEND="svg", PYTHONPATH=str(SRC) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    done = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_importing_attend_and_every_submodule_changes_no_global_state():
    result = _run()
    before, after = result["before"], result["after"]
    assert len(result["modules"]) > 40  # every package and module was imported
    assert after["backend"] == before["backend"] == "svg"
    assert after["formatwarning"] == before["formatwarning"]
    assert after["showwarning"] == before["showwarning"]
    changed = {k for k in set(before["environ"]) | set(after["environ"])
               if before["environ"].get(k) != after["environ"].get(k)}
    assert not changed, f"os.environ changed at import: {sorted(changed)}"


def test_import_attend_is_lazy():
    """``import attend`` loads no subpackage, nor NumPy or SciPy (only the small module that makes
    the lazy exports): public names are imported at their first use (PEP 562), so a command or a
    script pays only for what it uses."""
    import subprocess
    import sys

    code = ("import sys, attend; loaded = sorted(m for m in sys.modules if m.split('.')[0] in ('numpy', 'scipy') "
            "or (m.startswith('attend.') and m != 'attend._lazy')); print(loaded); attend.KalmanEstimator; attend.action.ProbabilityMap")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
