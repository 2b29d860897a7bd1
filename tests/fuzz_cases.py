"""Generated model files and logs for the fuzz campaign of `attend estimate` and `attend identify`.

A case starts from a valid model file and log (random small system, random shapes) and applies
a few mutations: wrong types, NaN/inf/huge values, missing and extra keys and columns, broken
encodings, BOM, CRLF, non-uniform or repeated time stamps, empty files, directories. Each case
runs in-process through ``attend.cli.main`` and is classified by :func:`classify`.

The property: exit 0 with finite output files, or exit 2 with exactly one line
``attend: error: ...`` naming the file or field; never a traceback, never non-finite output with
exit 0, never exit 1 (internal error) from bad input. Used by tests/test_fuzz.py (a fast subset)
and benchmarks/bench_fuzz.py (>= 1000 cases, counts by category).
"""

from __future__ import annotations

import contextlib
import io
import math
import traceback
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import tomli_w
from hypothesis import strategies as st

#: outcome categories, in report order; the first two are the allowed ones
ALLOWED = ("exit 0 finite", "exit 2 clean", "exit 3 not converged")
FAILURES = ("traceback", "non-finite with exit 0", "internal error", "unclean error message", "other exit")

_BAD_NUMBERS = [float("nan"), float("inf"), -float("inf"), 1e300, -1e200, 1e151, "1.0", "abc", True, [], [1.0, 2.0]]
_MATRIX_KEYS = ("A", "B", "C")


@dataclass
class Case:
    """One generated pair of files and the mutations that made it."""

    model: dict | bytes | None  # TOML data, raw bytes, or None: the model path is a directory
    log: list | bytes | None  # rows of cells (header first), raw bytes, or None: a directory
    mutations: list[str] = field(default_factory=list)
    crlf: bool = False
    bom: bool = False
    python: str | None = None  # the text of model.py of a nonlinear model file

    def write(self, folder: Path) -> tuple[Path, Path]:
        model_path, log_path = folder / "model.toml", folder / "log.csv"
        if self.python is not None:
            (folder / "model.py").write_text(self.python)
        if self.model is None:
            model_path.mkdir()
        else:
            model_path.write_bytes(self.model if isinstance(self.model, bytes) else _toml_bytes(self.model))
        if self.log is None:
            log_path.mkdir()
        elif isinstance(self.log, bytes):
            log_path.write_bytes(self.log)
        else:
            text = "\n".join(",".join(_cell(c) for c in row) for row in self.log) + "\n"
            if self.crlf:
                text = text.replace("\n", "\r\n")
            log_path.write_bytes(("\ufeff" if self.bom else "").encode() + text.encode())
        return model_path, log_path


def _toml_bytes(data: dict) -> bytes:
    try:
        return tomli_w.dumps(data).encode()
    except (TypeError, ValueError):  # e.g. an empty list in a spot tomli_w refuses: write it by hand
        return repr(data).encode()


def _cell(value) -> str:
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else {"nan": "nan", "inf": "inf", "-inf": "-inf"}[str(value)]
    return str(value)


# --- a valid starting point ----------------------------------------------------------------

@st.composite
def valid_case(draw) -> Case:
    """A valid model file and log: n states, r inputs (measured or not), m outputs."""
    n = draw(st.integers(1, 3))
    r = draw(st.sampled_from([0, 1, 1, 2, 2]))
    m = draw(st.integers(1, 2))
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    A = -np.eye(n) + 0.3 * rng.standard_normal((n, n))
    B = rng.standard_normal((n, r))
    C = rng.standard_normal((m, n))
    measured = draw(st.sampled_from([True, True, True, False]))  # identify needs measured inputs
    dt = draw(st.sampled_from([0.01, 0.1, 0.5]))
    samples = draw(st.integers(40, 90))
    inputs = []
    for j in range(r):
        if measured:
            inputs.append({"name": f"u{j + 1}", "column": f"cmd{j + 1}", "operating_point": float(j)})
        else:
            inputs.append({"name": f"u{j + 1}", "prior_mean": 0.0, "prior_precision": 1.0})
    model = {
        "model": {"A": A.tolist(), "B": B.tolist(), "C": C.tolist(), "states": [f"x{i + 1}" for i in range(n)],
                  "dt": dt},
        "outputs": {"columns": [f"y{i + 1}" for i in range(m)]},
        "inputs": inputs,
        "observer": {"kernel_width": 2 * dt, "embedding_order": draw(st.integers(1, 4)), "input_order": 2,
                     "sensor_precision": 100.0, "process_precision": 100.0},
        "learning": {"free": ["A[1,1]"], "max_iterations": 2},
    }
    if r == 0:
        del model["inputs"]
    t = np.arange(samples) * dt
    outputs = np.column_stack([np.sin((i + 1) * t) + 0.1 * rng.standard_normal(samples) for i in range(m)])
    commands = rng.standard_normal((samples, r)) if measured else np.zeros((samples, 0))
    header = ["t"] + [f"y{i + 1}" for i in range(m)] + ([f"cmd{j + 1}" for j in range(r)] if measured else [])
    rows = [header] + [[float(v) for v in row] for row in np.column_stack([t, outputs, commands])]
    return Case(model, rows)


# --- mutations -----------------------------------------------------------------------------

def _model_mutation(draw, case: Case) -> str:
    data = case.model
    kind = draw(st.sampled_from([
        "matrix entry", "matrix shape", "drop key", "extra key", "states", "inputs", "observer", "dt",
        "time column", "learning", "outputs",
    ]))
    model, observer, learning = data["model"], data["observer"], data["learning"]
    if kind == "matrix entry":
        key = draw(st.sampled_from(_MATRIX_KEYS))
        rows = model[key]
        if rows and rows[0]:
            i, j = draw(st.integers(0, len(rows) - 1)), draw(st.integers(0, len(rows[0]) - 1))
            bad = draw(st.sampled_from(_BAD_NUMBERS))
            rows[i][j] = bad
            return f"{key}[{i},{j}] = {bad!r}"
        model[key] = draw(st.sampled_from([[], [[]], "A", 3.0]))
        return f"{key} = {model[key]!r}"
    if kind == "matrix shape":
        key = draw(st.sampled_from(_MATRIX_KEYS))
        how = draw(st.sampled_from(["drop row", "add row", "add column", "drop column", "ragged"]))
        rows = model[key]
        if how == "drop row" and rows:
            rows.pop()
        elif how == "add row":
            rows.append([0.5] * (len(rows[0]) if rows else 1))
        elif how == "add column":
            for row in rows:
                row.append(0.5)
        elif how == "drop column":
            for row in rows:
                if row:
                    row.pop()
        elif how == "ragged" and rows:
            rows[0] = rows[0] + [1.0]
        return f"{key}: {how}"
    if kind == "drop key":
        where, key = draw(st.sampled_from([
            ("model", "A"), ("model", "B"), ("model", "C"), ("outputs", "columns"), ("observer", "kernel_width"),
            ("observer", "sensor_precision"), ("observer", "process_precision"), ("", "inputs"), ("", "outputs"),
            ("", "observer"),
        ]))
        table = data if not where else data[where]
        table.pop(key, None)
        return f"drop {where}.{key}"
    if kind == "extra key":
        where = draw(st.sampled_from(["", "model", "observer", "learning", "outputs"]))
        key = draw(st.sampled_from(["extra", "kernel", "A", "method", "log"]))
        table = data if not where else data[where]
        if key in table:
            return "extra key (exists)"
        table[key] = draw(st.sampled_from([1, "x", [1, 2], {"a": 1}]))
        return f"extra {where}.{key}"
    if kind == "states":
        n = len(model["A"])
        model["states"] = draw(st.sampled_from([
            ["x"] * n, ["x1"], [1] * n, "x1", [f"s{i}" for i in range(n + 1)], [""] * n, ["t"] + [f"s{i}" for i in range(n - 1)],
            ["u1"] + [f"s{i}" for i in range(n - 1)],
        ]))
        return f"states = {model['states']!r}"
    if kind == "inputs":
        inputs = data.setdefault("inputs", [])
        how = draw(st.sampled_from(["remove", "add", "duplicate name", "both", "bad number", "not tables",
                                    "unknown column", "bad name", "single table"]))
        if how == "remove" and inputs:
            inputs.pop()
        elif how == "add":
            inputs.append({"name": "extra_input", "prior_mean": 0.0, "prior_precision": 1.0})
        elif how == "duplicate name" and len(inputs) >= 2:
            inputs[1]["name"] = inputs[0]["name"]
        elif how == "both" and inputs:
            inputs[0].update(column="cmd1", prior_mean=0.0)
        elif how == "bad number" and inputs:
            key = draw(st.sampled_from(["prior_mean", "prior_precision", "operating_point"]))
            inputs[0][key] = draw(st.sampled_from(_BAD_NUMBERS + [-1.0]))
            return f"inputs[0].{key} = {inputs[0][key]!r}"
        elif how == "not tables":
            data["inputs"] = [1, 2][: max(1, len(inputs))]
        elif how == "unknown column" and inputs:
            inputs[0].pop("prior_mean", None)
            inputs[0].pop("prior_precision", None)
            inputs[0]["column"] = draw(st.sampled_from(["nope", 5, ""]))
        elif how == "bad name" and inputs:
            inputs[0]["name"] = draw(st.sampled_from([3, "", "x1", "t"]))
        elif how == "single table" and inputs:
            data["inputs"] = inputs[0]
        return f"inputs: {how}"
    if kind == "observer":
        key = draw(st.sampled_from(["kernel_width", "embedding_order", "input_order", "sensor_precision",
                                    "process_precision", "precision_convention", "known_input_precision"]))
        values = {
            "kernel_width": [0.0, -1.0, 1000.0, 1e-9, "0.1", float("nan"), float("inf"), True, 1e200],
            "embedding_order": [-1, 30, 2.5, "6", 0, 12, True],
            "input_order": [-1, 30, 2.5, "2", 0, 8],
            "sensor_precision": [-5.0, 0.0, "1e8", [1.0], [[1.0, 2.0], [3.0, 4.0]], 1e200, 1e140, 1e-200,
                                 [[1.0, 2.0], [2.0, 1.0]], float("nan"), [1.0, 2.0, 3.0]],
            "process_precision": [-5.0, 0.0, "1e3", [1.0], 1e200, 1e140, 1e-200, float("inf"), [[1.0]]],
            "precision_convention": ["foo", 1, "max", "size"],
            "known_input_precision": [0.0, -1.0, "big", float("inf"), 1e300, 1e-300],
        }[key]
        observer[key] = draw(st.sampled_from(values))
        return f"observer.{key} = {observer[key]!r}"
    if kind == "dt":
        model["dt"] = draw(st.sampled_from([0.0, -0.1, "0.1", 0.123, float("nan"), 1e300, True]))
        return f"dt = {model['dt']!r}"
    if kind == "time column":
        data["log"] = {"time_column": draw(st.sampled_from(["time", 5, "", "y1"]))}
        return f"time_column = {data['log']['time_column']!r}"
    if kind == "outputs":
        m = len(model["C"])
        data["outputs"]["columns"] = draw(st.sampled_from([["y1"] * (m + 1), ["y1"] * m, [1] * m, "y1", [],
                                                           ["t"] * m, ["nope"] * m]))
        return f"outputs.columns = {data['outputs']['columns']!r}"
    # learning
    key = draw(st.sampled_from(["free", "noise_prior_mean", "noise_prior_precision", "max_iterations",
                                "tolerance", "states", "free_prior_precision", "known_prior_precision"]))
    values = {
        "free": [["A[9,9]"], "A[1,1]", [1], ["Q[1,1]"], [], ["A[1,1]", "A[1,1]"]],
        "noise_prior_mean": [[0.0], [0.0, 0.0, 0.0], "0", [float("nan"), 0.0], 0.0, [1e300, 0.0]],
        "noise_prior_precision": [[1.0], 0.0, -1.0, "1", float("inf"), [1.0, 1.0]],
        "max_iterations": [0, -3, 2.5, "5", 10**9, True],
        "tolerance": [-1.0, "0.1", float("nan"), 0.0],
        "states": ["foo", 1, "path"],
        "free_prior_precision": [-1.0, float("inf"), "1", 1e300, 0.0],
        "known_prior_precision": [-1.0, float("inf"), "1", 1e300, 0.0],
    }[key]
    learning[key] = draw(st.sampled_from(values))
    return f"learning.{key} = {learning[key]!r}"


def _log_mutation(draw, case: Case) -> str:
    rows = case.log
    header, body = rows[0], rows[1:]
    kind = draw(st.sampled_from([
        "bad cell", "huge column", "drop column", "rename column", "duplicate column", "extra column",
        "non-uniform time", "repeated time", "decreasing time", "short", "header only", "ragged row",
        "blank lines", "constant outputs", "crlf", "bom",
    ]))
    if kind == "bad cell" and body:
        i, j = draw(st.integers(0, len(body) - 1)), draw(st.integers(0, len(header) - 1))
        body[i][j] = draw(st.sampled_from(["nan", "inf", "-inf", 1e300, -1e200, "abc", "", "1,5", " 2.0 ", "0x10"]))
        return f"log[{i}][{header[j]}] = {body[i][j]!r}"
    if kind == "huge column":
        j = draw(st.integers(1, len(header) - 1)) if len(header) > 1 else 0
        value = draw(st.sampled_from([1e300, 1e151, -1e160, 1e140]))
        for row in body:
            row[j] = value
        return f"log column {header[j]} = {value!r}"
    if kind == "drop column":
        j = draw(st.integers(0, len(header) - 1))
        for row in rows:
            row.pop(j)
        return f"drop log column {j}"
    if kind == "rename column":
        j = draw(st.integers(0, len(header) - 1))
        header[j] = draw(st.sampled_from(["T", "y 1", "", "x"]))
        return f"rename log column {j}"
    if kind == "duplicate column":
        j = draw(st.integers(0, len(header) - 1))
        for row in rows:
            row.append(row[j])
        return f"duplicate log column {header[j]}"
    if kind == "extra column":
        header.append("comment")
        for row in body:
            row.append(draw(st.sampled_from([1.0, "n/a"])))
        return "extra log column"
    if kind == "non-uniform time" and len(body) > 3:
        i = draw(st.integers(1, len(body) - 1))
        for row in body[i:]:
            row[0] += 0.37 * (body[1][0] - body[0][0])
        return "non-uniform time"
    if kind == "repeated time" and len(body) > 3:
        i = draw(st.integers(1, len(body) - 1))
        body[i][0] = body[i - 1][0]
        return "repeated time stamp"
    if kind == "decreasing time":
        for row in body:
            row[0] = -row[0]
        return "decreasing time"
    if kind == "short":
        keep = draw(st.integers(1, 6))
        del body[keep:]
        case.log = [header] + body
        return f"log of {keep} samples"
    if kind == "header only":
        case.log = [header]
        return "header only"
    if kind == "ragged row" and body:
        body[draw(st.integers(0, len(body) - 1))].append(1.0)
        return "ragged row"
    if kind == "blank lines":
        body.insert(len(body) // 2, [])
        return "blank line"
    if kind == "constant outputs":
        for row in body:
            for j in range(1, len(row)):
                row[j] = 1.0
        return "constant log"
    if kind == "crlf":
        case.crlf = True
        return "CRLF"
    if kind == "bom":
        case.bom = True
        return "BOM"
    return f"{kind} (no-op)"


_RAW_FILES = [
    b"", b"\x00\x01\x02binary\xd0\xff", "t,y1\n0,1\n".encode("utf-16"), "t,y1\n0,caf\xe9\n".encode("latin-1"),
    b"\xef\xbb\xbf", b"[model\n", b"t,y1\n0,1\x00\n", b"\r\n\r\n", b"just text",
]


@st.composite
def fuzz_case(draw) -> Case:
    """A valid case with 0..3 mutations of the model and the log, or a broken file outright."""
    case = draw(valid_case())
    for _ in range(draw(st.integers(0, 3))):
        target = draw(st.sampled_from(["model", "model", "log", "log", "file"]))
        mutate = {"model": _model_mutation, "log": _log_mutation}.get(target)
        if mutate is not None and isinstance(getattr(case, target), (dict, list)):
            try:
                case.mutations.append(mutate(draw, case))
            except (KeyError, IndexError, TypeError, AttributeError):  # an earlier mutation removed the part
                case.mutations.append(f"{target} mutation skipped")
        elif target == "file":
            which = draw(st.sampled_from(["model", "log"]))
            raw = draw(st.sampled_from(_RAW_FILES + [None]))
            setattr(case, which, raw)
            case.mutations.append(f"{which} file = {'a directory' if raw is None else raw[:12]!r}")
    return case


# --- nonlinear model files ([model] python) -----------------------------------------------------

#: f and g of the valid nonlinear cases: (code, n_states, n_inputs, n_outputs)
_PYTHON_MODELS = {
    "pendulum": ("import numpy as np\n\n\ndef f(x, v):\n    return np.array([x[1], -np.sin(x[0]) - 0.2 * x[1]])\n\n\n"
                 "def g(x, v):\n    return np.array([np.sin(x[0]), x[1]])\n", 2, 0, 2),
    "pushed": ("import numpy as np\n\n\ndef f(x, v):\n    return np.array([x[1], -x[0] - 0.3 * x[1] + v[0]])\n\n\n"
               "def g(x, v):\n    return np.array([x[0]])\n", 2, 1, 1),
    "well": ("def f(x, v):\n    return (16.0 * x / (1.0 + x**2) - x / 2.0 + 2.0 * v) / 8.0\n\n\n"
             "def g(x, v):\n    return x**2 / 16.0\n", 1, 1, 1),
}

#: broken versions of f (its return line replaced), each a mistake a user makes
_BROKEN_F = [
    "    return np.array([1.0])  # too few values",
    "    return None",
    "    return 'x'",
    "    return np.array([float('nan')] * len(x))",
    "    return 1 / (x[0] - x[0])",
    "    raise ValueError('model not ready')",
    "    return [x[0], x[1], x[2]]",
    "    return np.full(len(x), 1e308) * 10",
    "    return x if abs(x[0]) < 1 else x * float('inf')",
]


@st.composite
def valid_nonlinear_case(draw) -> Case:
    """A valid nonlinear model file (model.py and model.toml) and a log of 30-60 samples."""
    name = draw(st.sampled_from(sorted(_PYTHON_MODELS)))
    code, n, r, m = _PYTHON_MODELS[name]
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    dt = draw(st.sampled_from([0.05, 0.1, 1.0]))
    samples = draw(st.integers(30, 60))
    measured = draw(st.booleans())
    observer = {"kernel_width": dt * draw(st.sampled_from([0.5, 1.0, 2.0])), "sensor_precision": 100.0,
                "process_precision": draw(st.sampled_from([100.0, 1e4]))}
    if draw(st.booleans()):
        observer["initial_state"] = [0.5] * n
    if draw(st.integers(0, 4)) == 0:
        observer["method"] = "dem"
    inputs = [{"name": "u", "column": "u"} if measured else {"name": "u", "prior_mean": 0.0, "prior_precision": 1.0}
              for _ in range(r)]
    model = {"model": {"python": "model.py", "n_states": n, "n_inputs": r, "n_outputs": m},
             "outputs": {"columns": [f"y{i + 1}" for i in range(m)]}, "observer": observer}
    if inputs:
        model["inputs"] = inputs
    t = np.arange(samples) * dt
    outputs = np.column_stack([0.5 * np.sin((i + 1) * t) + 0.05 * rng.standard_normal(samples) for i in range(m)])
    commands = 0.3 * rng.standard_normal((samples, r)) if measured else np.zeros((samples, 0))
    header = ["t"] + [f"y{i + 1}" for i in range(m)] + (["u"] * r if measured else [])
    rows = [header] + [[float(v) for v in row] for row in np.column_stack([t, outputs, commands])]
    return Case(model, rows, python=code)


def _nonlinear_model_mutation(draw, case: Case) -> str:
    data = case.model
    model, observer = data["model"], data["observer"]
    kind = draw(st.sampled_from(["f", "f", "size", "observer", "observer", "python key", "gaps", "gaps"]))
    if kind == "f":
        lines = case.python.splitlines()
        where = next(i for i, line in enumerate(lines) if line.startswith("    return"))
        broken = draw(st.sampled_from(_BROKEN_F + ["syntax", "no g"]))
        if broken == "syntax":
            case.python = case.python.replace("def f(x, v):", "def f(x, v)")
        elif broken == "no g":
            case.python = case.python.split("def g")[0]
        else:
            lines[where] = broken
            case.python = "import numpy as np\n" + "\n".join(lines) + "\n"
        return f"f: {broken}"
    if kind == "size":
        key = draw(st.sampled_from(["n_states", "n_inputs", "n_outputs"]))
        model[key] = draw(st.sampled_from([0, 3, 7, -1, 2.5, "2"]))
        return f"model.{key} = {model[key]!r}"
    if kind == "python key":
        how = draw(st.sampled_from(["missing file", "directory", "vectorized", "parameters"]))
        if how == "missing file":
            model["python"] = "nowhere.py"
        elif how == "directory":
            model["python"] = "."
        elif how == "vectorized":
            model["vectorized"] = draw(st.sampled_from(["yes", True, 1]))
        else:
            model["parameters"] = draw(st.sampled_from([{"k": 1.0}, [1.0], "k"]))
        return f"python: {how}"
    if kind == "gaps":  # missing values and skipped stamps, which nonlinear models now take
        body = case.log[1:]
        how = draw(st.sampled_from(["empty cells", "skipped rows", "long gap", "all outputs empty"]))
        if how == "empty cells":
            for i in draw(st.lists(st.integers(0, len(body) - 1), min_size=1, max_size=6)):
                body[i][1] = ""
        elif how == "skipped rows":
            for i in sorted(set(draw(st.lists(st.integers(1, len(body) - 1), min_size=1, max_size=5))), reverse=True):
                del body[i]
        elif how == "long gap":
            start = draw(st.integers(1, max(1, len(body) - 12)))
            del body[start:start + 10]
        else:
            for row in body:
                for j in range(1, 1 + len(data["outputs"]["columns"])):
                    row[j] = ""
        case.log = [case.log[0]] + body
        return f"log: {how}"
    key = draw(st.sampled_from(["kernel_width", "sensor_precision", "process_precision", "initial_state",
                                "initial_state_std", "method", "input_kernel_width", "embedding_order"]))
    values = {
        "kernel_width": [0.0, -1.0, 1e200, 1e-9, float("nan"), "0.1"],
        "sensor_precision": [-5.0, 0.0, 1e300, 1e-300, float("nan"), [1.0, 2.0, 3.0]],
        "process_precision": [0.0, 1e300, 1e-300, float("inf"), "big"],
        "initial_state": [[0.0], [float("nan")] * 2, [1e300, 0.0], "0", [0.0, 0.0, 0.0]],
        "initial_state_std": [-1.0, 0.0, float("inf"), [1.0, 2.0, 3.0], 1e300],
        "method": ["kalman", "bogus", "dem", "ukf", 3],
        "input_kernel_width": [0.0, -1.0, 1e200, 1e-9, "1"],
        "embedding_order": [-1, 30, 2.5, "auto", 0],
    }[key]
    observer[key] = draw(st.sampled_from(values))
    return f"observer.{key} = {observer[key]!r}"


@st.composite
def nonlinear_fuzz_case(draw) -> Case:
    """A valid nonlinear case with 0..3 mutations of model.py, the model file and the log."""
    case = draw(valid_nonlinear_case())
    for _ in range(draw(st.integers(0, 3))):
        target = draw(st.sampled_from(["model", "model", "log"]))
        mutate = {"model": _nonlinear_model_mutation, "log": _log_mutation}[target]
        if isinstance(getattr(case, target), (dict, list)):
            try:
                case.mutations.append(mutate(draw, case))
            except (KeyError, IndexError, TypeError, AttributeError, StopIteration, ValueError):
                case.mutations.append(f"{target} mutation skipped")
    return case


# --- running and classifying ---------------------------------------------------------------

@dataclass
class Outcome:
    category: str
    command: str
    exit_code: int | None
    stderr: str
    mutations: list[str]


def run_case(case: Case, folder: Path, command: str) -> Outcome:
    """Write the case to ``folder`` and run ``attend COMMAND model log --out ...`` in-process."""
    from attend.cli import main

    folder.mkdir(parents=True, exist_ok=True)
    model_path, log_path = case.write(folder)
    out = folder / ("estimates.csv" if command == "estimate" else "learned.toml")
    argv = [command, str(model_path), str(log_path), "--out", str(out)]
    if command == "identify":
        argv.append("--no-progress")
    stderr = io.StringIO()
    try:
        with contextlib.redirect_stderr(stderr), contextlib.redirect_stdout(io.StringIO()):
            code = main(argv)
    except BaseException:  # noqa: BLE001 - the harness records every escape as a traceback
        return Outcome("traceback", command, None, stderr.getvalue() + traceback.format_exc(), case.mutations)
    named = (model_path, log_path, out) + ((folder / "model.py",) if case.python is not None else ())
    return Outcome(classify(code, stderr.getvalue(), out, named, command), command, code, stderr.getvalue(),
                   case.mutations)


def classify(code, stderr: str, out: Path, paths, command: str) -> str:
    """The category of one run (see ALLOWED and FAILURES)."""
    if "Traceback" in stderr:
        return "traceback"
    lines = [line for line in stderr.splitlines() if line and not line.startswith("attend: warning:")]
    if code == 0:
        return "exit 0 finite" if _finite_output(out, command) else "non-finite with exit 0"
    if code == 1:
        return "internal error"
    if code in (2, 3):
        names_a_path = len(lines) == 1 and any(str(path) in lines[0] for path in paths)
        if len(lines) == 1 and lines[0].startswith("attend: error: ") and names_a_path:
            return "exit 2 clean" if code == 2 else "exit 3 not converged"
        return "unclean error message"
    return "other exit"


def _finite_output(out: Path, command: str) -> bool:
    if not out.is_file():
        return False
    if command == "estimate":
        table = np.loadtxt(out, delimiter=",", skiprows=1, ndmin=2)
        return table.size > 0 and bool(np.all(np.isfinite(table)))
    from attend import io as attend_io

    try:
        learned = attend_io.read_model(out)
    except Exception:  # noqa: BLE001 - an unreadable learned model is a failure
        return False
    system = learned.system
    precisions = [learned.sensor_precision, learned.process_precision]
    return all(np.all(np.isfinite(np.asarray(v, dtype=float))) for v in (system.A, system.B, system.C, *precisions))
