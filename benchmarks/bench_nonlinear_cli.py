"""`attend estimate` with its defaults on random nonlinear model files, as a new user runs it.

    PYTHONPATH=src python benchmarks/bench_nonlinear_cli.py [--cases 36] [--first 0] [--path]

Each case of ``bench_nonlinear_bank.py`` (dx/dt = A x + B v + a tanh(W x), y = C x [+ c sin(H x)],
no input, a measured input or an unknown one, s/dt = 1-4) is written as a user would write it:
``model.py`` with f(x, v) and g(x, v), ``model.toml`` with the true noise settings (sensor and
process precisions, kernel width, the unknown input's prior), and ``log.csv`` (t, outputs, the
measured input). The command line runs on them with its defaults (method "ukf": the unscented
smoother started from DEM's estimate of the first sample, x[0] unknown) and, with ``--path``,
with ``method = "dem"`` and ``states = "path"``. Per case: the exit status, any warning line,
the state SSE (samples p + 1 .. N - p - 2) over that of the library's unscented smoother told
the true prior of x[0] (N(0, I)), and the fraction of those state samples within 2 reported std
of the truth (calibrated: ~0.95). Not part of the test run.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
import bench_nonlinear_bank as bank  # noqa: E402

MODEL_PY = '''import numpy as np

A = np.array({A})
B = np.array({B}).reshape({n}, {r})
C = np.array({C})
W = np.array({W})
H = np.array({H})
a, c = {a!r}, {c!r}


def f(x, v):
    """dx/dt: a stable linear part and a saturating one."""
    return A @ x + B @ v + a * np.tanh(W @ x)


def g(x, v):
    """The outputs: linear, with a sinusoidal part when c > 0."""
    return C @ x + c * np.sin(H @ x)
'''


def write_case(case: dict, folder: Path, path_mode: bool, input_width: bool = True) -> tuple[Path, Path]:
    """model.py, model.toml and log.csv of ``case`` in ``folder``."""
    system, log = case["system"], case["log"]
    closure = {name: cell.cell_contents for name, cell in zip(system.f.__code__.co_freevars, system.f.__closure__)}
    closure.update({name: cell.cell_contents for name, cell in zip(system.g.__code__.co_freevars, system.g.__closure__)})
    n, m = case["n"], case["m"]
    r = 0 if case["input_kind"] == "none" else 1
    (folder / "model.py").write_text(MODEL_PY.format(
        A=closure["A"].tolist(), B=closure["B"].ravel().tolist(), C=closure["C"].tolist(), W=closure["W"].tolist(),
        H=closure["H"].tolist(), a=float(closure["a"]), c=float(closure["c"]), n=n, r=r))
    outputs = [f"y{j + 1}" for j in range(m)]
    lines = ["[model]", 'python = "model.py"', f"n_states = {n}", f"n_inputs = {r}", f"n_outputs = {m}", "",
             "[outputs]", f"columns = {outputs}".replace("'", '"'), ""]
    if case["input_kind"] == "measured":
        lines += ["[[inputs]]", 'name = "u1"', 'column = "u1"', ""]
    elif case["input_kind"] == "unknown":
        lines += ["[[inputs]]", 'name = "u1"', "prior_mean = 0.0", "prior_precision = 1.0", ""]
    lines += ["[observer]", f"kernel_width = {case['s']!r}", f"sensor_precision = {case['sigma_z'] ** -2!r}",
              f"process_precision = {case['sigma_w'] ** -2!r}"]
    if case["input_kind"] == "unknown" and input_width:
        lines.append(f"input_kernel_width = {case['input_width']!r}")
    if path_mode:
        lines += ['method = "dem"', 'states = "path"']
    (folder / "model.toml").write_text("\n".join(lines) + "\n")
    columns = [case["time"], log.outputs] + ([log.inputs] if case["input_kind"] == "measured" else [])
    header = ["t"] + outputs + (["u1"] if case["input_kind"] == "measured" else [])
    np.savetxt(folder / "log.csv", np.column_stack(columns), delimiter=",", header=",".join(header), comments="",
               fmt="%.17g")
    return folder / "model.toml", folder / "log.csv"


def run_cli(case: dict, folder: Path, path_mode: bool, reference: float, input_width: bool = True,
            input_reference: float | None = None) -> tuple[str, float, float]:
    """(one line: exit status, SSE ratio to the library smoother with the true x[0] prior, |error| <
    2 std, warnings; the ratio; the fraction of state samples within 2 std) (NaN on a failure).
    input_width False: the file leaves input_kernel_width out; input_reference: that smoother's input SSE
    (an unknown input: the line gives the ratio of the estimate's to it)."""
    model, log = write_case(case, folder, path_mode, input_width)
    out = folder / "estimates.csv"
    started = time.perf_counter()
    done = subprocess.run([shutil.which("attend") or "attend", "estimate", str(model), str(log), "--out", str(out)],
                          capture_output=True, text=True)
    seconds = time.perf_counter() - started
    if done.returncode != 0:
        return f"exit {done.returncode}: {(done.stderr or done.stdout).strip()[:160]}", np.nan, np.nan
    estimate = np.genfromtxt(out, delimiter=",", names=True)
    states = np.column_stack([estimate[f"x{i + 1}"] for i in range(case["n"])])
    std = np.column_stack([estimate[f"x{i + 1}_std"] for i in range(case["n"])])
    p = case["p"]
    trim = slice(p + 1, bank.SAMPLES - p - 1)
    sse = float(np.sum((states - case["log"].states)[trim] ** 2))
    inside = float(np.mean(np.abs(states - case["log"].states)[trim] < 2 * std[trim]))
    finite = "" if np.all(np.isfinite(states)) else " NON-FINITE"
    warnings = [line for line in done.stderr.strip().splitlines() if line.startswith("attend: warning:")]
    warned = " [warned: " + warnings[0][:100] + "]" if warnings else ""
    chosen = [line for line in done.stderr.splitlines() if "chosen from the log" in line]
    if input_reference is not None:
        input_sse = float(np.sum((estimate["u1"] - case["log"].inputs[:, 0])[trim] ** 2))
        width = chosen[0].split("input prior width ")[1].split(" (")[0] if chosen else "?"
        finite += f"; input SSE {input_sse / input_reference:.3f} x its (width {width})"
    return (f"{sse / reference:7.3f} x the smoother told x[0] ~ N(0, I), |error| < 2 std {inside:.2f} "
            f"({seconds:4.1f} s){finite}{warned}", sse / reference, inside)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=36)
    parser.add_argument("--first", type=int, default=0)
    parser.add_argument("--path", action="store_true", help="also run method = \"dem\", states = \"path\"")
    parser.add_argument("--no-input-width", action="store_true",
                        help="leave input_kernel_width out of the files: the default chooses it from the log")
    args = parser.parse_args()
    from attend.perception.nonlinear_smoothers import input_random_walk_variance, unscented_kalman, \
        white_noise_covariances

    print(f"== attend estimate (defaults) on {args.cases} random nonlinear model files; state SSE over the library's "
          "unscented smoother told the true prior of x[0]")
    ratios = {"ukf": [], "path": []}
    coverage = {"ukf": [], "path": []}
    with tempfile.TemporaryDirectory(prefix="attend-nonlinear-cli-") as work:
        for index in range(args.first, args.first + args.cases):
            case = bank.draw_case(index)
            n, unknown = case["n"], case["input_kind"] == "unknown"
            Q, R = white_noise_covariances(case["system"], bank.DT, kernel_width=case["s"], process_std=case["sigma_w"],
                                           measurement_std=case["sigma_z"])
            options = dict(process_covariance=Q, measurement_covariance=R, initial_mean=np.zeros(n),
                           initial_covariance=1.0)
            if unknown:
                options.update(input_variance=float(input_random_walk_variance(1.0, kernel_width=case["input_width"],
                                                                               dt=bank.DT)))
            inputs = case["log"].inputs if case["input_kind"] == "measured" else None
            smoother = unscented_kalman(case["system"], bank.DT, case["log"].outputs, inputs, **options)
            p = case["p"]
            trim = slice(p + 1, bank.SAMPLES - p - 1)
            reference = float(np.sum((smoother.states - case["log"].states)[trim] ** 2))
            input_reference = float(np.sum((smoother.inputs - case["log"].inputs)[trim] ** 2)) if unknown else None
            for label, path_mode in (("ukf", False), ("path", True)):
                if path_mode and not args.path:
                    continue
                folder = Path(work) / f"{index}-{label}"
                folder.mkdir()
                line, ratio, inside = run_cli(case, folder, path_mode, reference, not args.no_input_width,
                                              input_reference if unknown and not path_mode else None)
                print(f"  {bank.describe(case)} {label:4s}: {line}", flush=True)
                ratios[label].append(ratio)
                coverage[label].append(inside)
    for label, values in ratios.items():
        if values:
            values = np.array(values)
            print(f"  {label}: median {np.nanmedian(values):.3f}, 90th percentile {np.nanpercentile(values, 90):.3f}, "
                  f"worst {np.nanmax(values):.3g}, failed {int(np.sum(np.isnan(values)))} of {len(values)}")
            inside = np.array(coverage[label])
            print(f"  {label}: |error| < 2 std pooled {np.nanmean(inside):.3f} (calibrated: ~0.95), per case "
                  f"{np.nanmin(inside):.2f}-{np.nanmax(inside):.2f}, below 0.85 in {int(np.sum(inside < 0.85))} cases")


if __name__ == "__main__":
    main()
