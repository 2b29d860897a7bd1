"""Nonlinear DEM against its references on the Lorenz and pendulum reproductions.

    PYTHONPATH=src python benchmarks/bench_nonlinear.py [--seeds 20] [--sweep-seeds 10]

Part 1 (the reproductions' settings, s/dt = 2, ``--seeds`` seeds each): state SSE of DEM over the
particle smoother (target: median ratio <= 1.2), over the UKF smoother (target: DEM <= UKF median
where s/dt >= 2), beside the coloured-noise UKS, the UKF filter and the fixed-lag UKF with DEM's
delay (the same data window as DEM); input SSE beside the
augmented UKF (pendulum); samples/s of each method.
Part 2 (``--sweep-seeds`` seeds): DEM / UKF smoother, filter and fixed-lag state SSE as s/dt
varies (1, 2, 4, 8), the noise levels fixed.
Not part of the test run. One BLAS thread (set before numpy is imported).
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy: one BLAS thread

import numpy as np  # noqa: E402

from attend.experiments import lorenz, pendulum  # noqa: E402
from attend.experiments import _nonlinear  # noqa: E402


def _verdict(ok: bool) -> str:
    return "meets target" if ok else "MISSES target"


def part1(seeds: int) -> None:
    for module in (lorenz, pendulum):
        start = time.perf_counter()
        result = module.run(quick=False, seeds=seeds, progress=False)
        elapsed = time.perf_counter() - start
        cfg = result.settings
        value = lambda name: result.metric(name).value  # noqa: E731
        print(f"\n== {result.experiment}: {seeds} seeds, {cfg['duration']:.0f} s at dt = {cfg['dt']} s, "
              f"s = {cfg['kernel_width']} s (s/dt = {cfg['kernel_width'] / cfg['dt']:.0f}), "
              f"{cfg['particles']} particles ({elapsed:.0f} s)")
        for method in _nonlinear.METHODS:
            print(f"  {method:14s} state SSE median {value(f'{method} state SSE (median)'):10.3f}   "
                  f"{value(f'{method} speed'):8.0f} samples/s")
        ratio = value("DEM / particle state SSE (median ratio)")
        print(f"  DEM / particle     state SSE median ratio {ratio:6.3f}   target <= 1.2    {_verdict(ratio <= 1.2)}")
        ratio = value("DEM / UKF state SSE (median ratio)")
        dem, ukf = value("DEM state SSE (median)"), value("UKF state SSE (median)")
        print(f"  DEM / UKF smoother state SSE median ratio {ratio:6.3f}   target DEM median <= UKF median "
              f"({dem:.3f} vs {ukf:.3f})  {_verdict(dem <= ukf)}")
        for other in ("coloured UKS", "UKF filter", "UKF lag"):
            print(f"  DEM / {other:12s} state SSE median ratio {value(f'DEM / {other} state SSE (median ratio)'):6.3f}"
                  "   (no target)")
        if module is pendulum:
            for method in ("DEM", "augmented UKF", "augmented UKF filter", "augmented UKF lag", "coloured UKS",
                           "particle"):
                print(f"  input SSE median {method:22s} {value(f'{method} input SSE (median)'):10.3f}")
            print(f"  DEM / augmented UKF input SSE median ratio "
                  f"{value('DEM / augmented UKF input SSE (median ratio)'):6.3f}   (no target)")
        print(f"  DEM |error| < 2 std: {value('DEM |error| < 2 std (fraction of samples)'):.3f} of samples "
              "(calibrated if in 0.93-0.97)")


def part2(seeds: int) -> None:
    print(f"\n== s/dt sweep ({seeds} seeds; DEM, UKF smoother, UKF filter, UKF fixed-lag with DEM's delay)")
    for module in (lorenz, pendulum):
        for ratio_s in (1, 2, 4, 8):
            cfg = dict(module.SETTINGS)
            cfg.update(kernel_width=ratio_s * cfg["dt"], seeds=seeds, methods=("DEM", "UKF", "UKF filter", "UKF lag"))
            result = _nonlinear.compare(module.__name__.rsplit(".", 1)[-1], cfg, False)
            smoother = result.metric("DEM / UKF state SSE (median ratio)").value
            dem, ukf = result.metric("DEM state SSE (median)").value, result.metric("UKF state SSE (median)").value
            filt = result.metric("DEM / UKF filter state SSE (median ratio)").value
            lag = result.metric("DEM / UKF lag state SSE (median ratio)").value
            target = "" if ratio_s < 2 else f"  target DEM <= UKF: {_verdict(dem <= ukf)}"
            print(f"  {result.experiment:8s} s/dt = {ratio_s}: DEM/UKF smoother {smoother:6.3f}  "
                  f"DEM/UKF filter {filt:6.3f}  DEM/UKF lag {lag:6.3f}{target}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--sweep-seeds", type=int, default=10)
    args = parser.parse_args()
    part1(args.seeds)
    if args.sweep_seeds > 0:
        part2(args.sweep_seeds)


if __name__ == "__main__":
    main()
