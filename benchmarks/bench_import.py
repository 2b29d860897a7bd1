"""How long ``import attend`` takes, against the target of 0.3 s (median of 7 fresh interpreters).

    python benchmarks/bench_import.py

Also prints what the first use of a few public names costs (they are imported lazily)."""

import statistics
import subprocess
import sys

TARGET_S = 0.3


def fresh(code: str, runs: int = 7) -> float:
    """Median wall time [s] of ``code`` in fresh interpreters, measured inside each."""
    probe = f"import time; t = time.perf_counter(); {code}; print(time.perf_counter() - t)"
    times = [float(subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout)
             for _ in range(runs)]
    return statistics.median(times)


if __name__ == "__main__":
    took = fresh("import attend")
    print(f"import attend: {took:.4f} s (target <= {TARGET_S} s: {'met' if took <= TARGET_S else 'NOT met'})")
    for name in ("KalmanEstimator", "ProbabilityMap", "identify"):
        print(f"import attend; attend.{name}: {fresh(f'import attend; attend.{name}'):.3f} s")
