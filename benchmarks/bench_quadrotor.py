"""Quadrotor-in-wind benchmark (Bos et al. 2022): every reproduced figure beside the published one.

Run:  python benchmarks/bench_quadrotor.py [--data DIR] [--out DIR] [--repeats 3]

Runs :func:`attend.experiments.quadrotor.run` (published protocol; see that module's docstring)
on the shared flight logs, prints reproduced vs published values with the relative difference
and the number of matching significant digits, the extra metrics without a published value
(attend's default DEM convention, the no-wind p sweep), the UIO note, and the wall time
(best of ``--repeats``, plus a breakdown: data loading, one DEM observer set-up, one slice).
"""

from __future__ import annotations

import os

# small dense algebra: one BLAS thread is faster than oversubscribed threads on a busy machine
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402

from attend.experiments import quadrotor  # noqa: E402


def significant_digits(published: float) -> int:
    """Significant digits as printed (0.74578 -> 5, 43.09 -> 4)."""
    return len(repr(published).replace("-", "").replace(".", "").lstrip("0"))


def matching_digits(value: float, published: float) -> int:
    """How many of the published significant digits ``value`` reproduces when rounded alike."""
    for n in range(significant_digits(published), 0, -1):
        if float(f"{value:.{n}g}") == float(f"{published:.{n}g}"):
            return n
    return 0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=None, help="flight CSV directory (default: shared data)")
    parser.add_argument("--out", default=None, help="write quadrotor.json and the figures here")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    started = time.perf_counter()
    path = quadrotor.data_dir_checked(args.data)
    logs = {f: quadrotor.load_flight(path, f) for f in quadrotor.WIND_FLIGHTS + quadrotor.NO_WIND_FLIGHTS}
    load_time = time.perf_counter() - started
    piece = quadrotor.prepare_slice(logs[quadrotor.WIND_FLIGHTS[0]], 400, 639)
    started = time.perf_counter()
    observer = quadrotor._state_observer(piece)
    setup_time = time.perf_counter() - started
    started = time.perf_counter()
    quadrotor.published_dem(observer, piece.outputs, piece.inputs)
    slice_time = time.perf_counter() - started

    times = []
    for _ in range(max(1, args.repeats)):
        started = time.perf_counter()
        result = quadrotor.run(progress=False, data_dir=path)
        times.append(time.perf_counter() - started)
    if args.out:
        result.figures = quadrotor.plot(result, args.out)
        result.write(args.out)

    print(f"{'metric':32s} {'reproduced':>12s} {'published':>10s} {'rel. diff':>10s}  digits  unit")
    for m in result.metrics:
        if m.published is None:
            continue
        print(f"{m.name:32s} {m.value:12.6g} {m.published:10.6g} {m.relative_difference():10.1e}  "
              f"{matching_digits(m.value, m.published):2d}/{significant_digits(m.published):<2d}   {m.unit}")
    print("\nno published value:")
    for m in result.metrics:
        if m.published is None:
            print(f"{m.name:32s} {m.value:12.6g} {'-':>10s}  {m.unit}")
    print("\nnot reproduced:")
    for name, why in result.settings["not_reproduced"].items():
        print(f"  {name}: {why}")
    worst = max(m.relative_difference() for m in result.metrics if m.published is not None)
    print(f"\nworst relative difference to a published value: {worst:.1e}")
    print(f"time: run() best {min(times):.2f} s of {len(times)} (all {', '.join(f'{t:.2f}' for t in times)} s); "
          f"load 8 logs {load_time:.2f} s; one DEM observer set-up (p = 6) {setup_time * 1e3:.1f} ms; "
          f"one 240-sample slice {slice_time * 1e3:.2f} ms")
    if args.out:
        print(f"wrote {result.write(args.out)} and {', '.join(result.figures)}")


if __name__ == "__main__":
    main()
