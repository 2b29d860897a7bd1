"""Gaps in the logs of nonlinear models: `attend estimate` (method "ukf") on logs that drop rows and values.

    PYTHONPATH=src python benchmarks/bench_nonlinear_gaps.py [--quick] [--drop 0.05] [--cells 0.02] [--seeds 2]
                                                             [--keep-inputs] [--jitter 0.05]

The bank of benchmarks/bench_nonlinear_start.py (SPM's Lorenz from 10 points of its attractor, a
double well, van der Pol, a pendulum with an unknown push; SPM's settings as model files, 128
samples; its generators imported, not copied). Each log is estimated twice by `attend estimate`
(in-process, the default: the unscented smoother, the start searched):

- complete: every row;
- gappy: a fraction ``drop`` of the rows (never the first) removed at random (skipped time stamps:
  samples without a measurement; a measured input is then bridged linearly over the gap), and a
  fraction ``cells`` of the remaining output values set missing (an empty cell: no update for that
  output at that sample). --keep-inputs: the dropped rows keep their stamp and measured input, only
  their outputs go missing (what the smoother loses, without what the input's gap loses).
- --jitter J instead: every row kept, at the stamp k + e_k with e_k uniform in +-J/2 (steps within
  +-J of dt); each log read from a simulation 100x finer with the same noises (one seed), its measured
  input switching at its own stamps; the complete one at the stamps k. The smoother integrates each
  step over its own length.

Metric: the state SSE over the rows of the gappy log, gappy / complete, per case and log seed;
target (the linear smoother's, issue 29): median <= 1.1. Beside it the same with initial_state
given (the start search out of the comparison), and the refusals (target 0). ~2-4 minutes
(--quick: every third case).
"""

from __future__ import annotations

import argparse
import contextlib
import io as text_io
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_nonlinear_start import case_inputs, case_settings, cases, simulate_case, write_model  # noqa: E402

from attend.cli import main as cli  # noqa: E402
from attend.io import read_model  # noqa: E402
from attend.models import simulate_nonlinear  # noqa: E402

FINE = 100  # sub-samples per sample of the simulation that jittered logs are read from

TARGET = 1.1


def run(model: Path, log: Path) -> tuple[int, str, np.ndarray | None]:
    """(exit status, last line of standard error, estimated states and inputs (rows, n + r) or None)."""
    out = log.with_name(f"{log.stem}_{model.stem}_out.csv")
    stdout, stderr = text_io.StringIO(), text_io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        status = cli(["estimate", str(model), str(log), "--out", str(out), "--no-progress"])
    if status != 0:
        return status, stderr.getvalue().strip().splitlines()[-1], None
    return status, "", np.loadtxt(out, delimiter=",", skiprows=1, ndmin=2)


def gappy_copy(log: Path, rng, drop: float, cells: float, keep_inputs: bool = False) -> tuple[Path, np.ndarray]:
    """A copy of ``log`` (columns t, y1.., [u]) without a fraction ``drop`` of its rows (never the first)
    and with a fraction ``cells`` of the kept output values empty; returns (its path, the kept rows).
    keep_inputs: the "dropped" rows stay with their time stamp and measured inputs, their outputs empty."""
    header = log.read_text().splitlines()[0]
    columns = header.split(",")
    table = np.loadtxt(log, delimiter=",", skiprows=1, ndmin=2)
    dropped = np.concatenate([[False], rng.random(len(table) - 1) < drop])
    outputs = [j for j, name in enumerate(columns) if name.startswith("y")]
    holes = rng.random((len(table), len(outputs))) < cells
    holes[0] = False
    if keep_inputs:
        kept = np.arange(len(table))
        holes[dropped] = True
    else:
        kept = np.flatnonzero(~dropped)
        table, holes = table[kept], holes[kept]
    lines = [header]
    for row, missing in zip(table, holes):
        values = [f"{value:.12g}" for value in row]
        for j, hole in zip(outputs, missing):
            if hole:
                values[j] = ""
        lines.append(",".join(values))
    path = log.with_name("gappy.csv")
    path.write_text("\n".join(lines) + "\n")
    return path, kept


def jittered_logs(folder: Path, kind: str, x0, samples: int, seed: int, amplitude: float, jitter: float, rng):
    """log.csv (stamps k) and jittered.csv (stamps k + e_k, e_k uniform in +-jitter/2, so every step is
    within +-jitter of dt = 1) of ``kind``, each read from a simulation FINE times finer with the same
    noises (one seed: the same continuous-time process and sensor noise) whose measured input
    switches at its own log's stamps (held from each row to the next, as the estimator assumes);
    returns (the true states at log.csv's rows, at jittered.csv's rows)."""
    model_path, settings = write_model(folder, kind)
    system = read_model(model_path).system
    fine_t = np.arange(samples * FINE) / FINE
    offsets = np.round(rng.uniform(-jitter / 2, jitter / 2, samples) * FINE).astype(int)
    offsets[0] = 0
    known = settings["r"] and settings["known"]
    header = ",".join(["t"] + [f"y{i + 1}" for i in range(settings["m"])] + (["u"] if known else []))
    truths = []
    for name, index in (("log.csv", np.arange(samples) * FINE),
                        ("jittered.csv", np.clip(np.arange(samples) * FINE + offsets, 0, len(fine_t) - 1))):
        row = np.clip(np.searchsorted(index, np.arange(len(fine_t)), side="right") - 1, 0, samples - 1)
        inputs = case_inputs(kind, row.astype(float), amplitude)  # row k's input from its stamp to the next
        log = simulate_nonlinear(system, len(fine_t) if inputs is None else inputs, 1.0 / FINE,
                                 kernel_width=settings["s"], process_std=settings["W"] ** -0.5,
                                 measurement_std=settings["V"] ** -0.5, initial_state=x0, seed=seed)
        columns = [fine_t[index], log.outputs[index]] + ([np.asarray(log.inputs)[index]] if known else [])
        np.savetxt(folder / name, np.column_stack(columns), delimiter=",", header=header, comments="", fmt="%.12g")
        truths.append(log.states[index])
    return truths[0], truths[1]


def sse(estimate, truth, n: int) -> float:
    return float("nan") if estimate is None else float(np.sum((estimate[:, 1:1 + n] - truth) ** 2))


def inside(estimate, truth, n: int, r: int) -> np.ndarray:
    """|error| < 2 std per state value (columns t, states, inputs, state std, input std), flattened."""
    if estimate is None:
        return np.zeros(0, dtype=bool)
    return (np.abs(estimate[:, 1:1 + n] - truth) < 2 * estimate[:, 1 + n + r:1 + 2 * n + r]).ravel()


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="every third case")
    parser.add_argument("--drop", type=float, default=0.05, help="fraction of rows removed (default 0.05)")
    parser.add_argument("--cells", type=float, default=0.02, help="fraction of output values emptied (default 0.02)")
    parser.add_argument("--seeds", type=int, default=2, help="gappy logs per case (default 2)")
    parser.add_argument("--samples", type=int, default=128)
    parser.add_argument("--jitter", type=float, default=0.0,
                        help="instead of drops: every stamp jittered by up to +-jitter/2 dt (e.g. 0.05), both logs "
                             "read from a simulation 100x finer")
    parser.add_argument("--keep-inputs", action="store_true",
                        help="a dropped row keeps its stamp and measured inputs (only its outputs go missing)")
    args = parser.parse_args(argv)
    print(f"{'case':30s} {'seed':>4s} {'rows':>5s} {'searched: complete':>18s} {'gappy':>9s} {'ratio':>6s} "
          f"{'x0 known: complete':>18s} {'gappy':>9s} {'ratio':>6s}")
    ratios, known_ratios, refusals = [], [], 0
    covered = {"searched": [], "known": [], "searched complete": [], "known complete": []}
    for index, (label, kind, x0, amplitude, seed) in enumerate(cases(10, args.quick)):
        with tempfile.TemporaryDirectory() as name:
            folder = Path(name)
            if args.jitter:
                truth, jittered_truth = jittered_logs(folder, kind, x0, args.samples, seed, amplitude, args.jitter,
                                                      np.random.default_rng([2912, index]))
            else:
                truth = simulate_case(folder, kind, x0, args.samples, seed, amplitude)
            n = truth.shape[1]
            r = case_settings(kind)["r"]
            searched = write_model(folder, kind)[0]
            known = write_model(folder, kind, f"initial_state = {list(map(float, x0))}\n", "known.toml")[0]
            complete = {model: run(model, folder / "log.csv") for model in (searched, known)}
            for log_seed in range(1 if args.jitter else args.seeds):
                rng = np.random.default_rng([2911, index, log_seed])
                if args.jitter:  # every row, at its jittered stamp (the truth there)
                    gappy, kept = folder / "jittered.csv", np.arange(args.samples)
                else:
                    gappy, kept = gappy_copy(folder / "log.csv", rng, args.drop, args.cells, args.keep_inputs)
                target = jittered_truth if args.jitter else truth[kept]
                line = [f"{label:30s} {log_seed:4d} {len(kept):5d}"]
                for model, store, which in ((searched, ratios, "searched"), (known, known_ratios, "known")):
                    status, message, estimate = run(model, gappy)
                    covered[which].append(inside(estimate, target, n, r))
                    full = complete[model][2]
                    covered[f"{which} complete"].append(inside(None if full is None else full[kept], truth[kept], n, r))
                    reference = sse(None if full is None else full[kept], truth[kept], n)
                    value = sse(estimate, target, n)
                    refusals += status != 0
                    store.append(value / reference)
                    line.append(f"{reference:18.4g} {value:9.4g} {value / reference:6.3f}")
                    if status:
                        line.append(f"[{message[:90]}]")
                print(" ".join(line), flush=True)
    for name, values, which in (("start searched", ratios, "searched"), ("initial_state given", known_ratios, "known")):
        values = np.array(values)
        finite = values[np.isfinite(values)]
        print(f"{name}: state SSE gappy / complete over the gappy log's rows: median {np.median(finite):.3f}, "
              f"90th percentile {np.percentile(finite, 90):.3f}, worst {np.max(finite):.3f} ({len(finite)} logs; "
              f"target median <= {TARGET}: {'met' if np.median(finite) <= TARGET else 'NOT met'}); "
              f"|error| < 2 std on the gappy logs {np.mean(np.concatenate(covered[which])):.3f}, on the complete ones "
              f"{np.mean(np.concatenate(covered[which + ' complete'])):.3f} (calibrated: ~0.95)")
    print(f"refusals: {refusals} of {2 * len(ratios)} runs on gappy logs (target 0)")


if __name__ == "__main__":
    main()
