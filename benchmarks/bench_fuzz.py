"""Fuzz campaign of the user's path: generated model files and logs through `attend estimate`
and `attend identify` (in-process), counted by outcome.

    python benchmarks/bench_fuzz.py [--cases 1000] [--seed 0] [--nonlinear]

Each case (see tests/fuzz_cases.py) runs both commands. Allowed outcomes: exit 0 with finite
output files, exit 2 with one line ``attend: error: ...`` naming the file or field (and exit 3,
"identification did not converge"). Everything else is listed with its mutations and stderr;
the exit status is 1 when any failure was found. --nonlinear: nonlinear model files instead
(tests/fuzz_cases.py's nonlinear_fuzz_case: f broken in the ways users break it, wrong sizes,
bad settings, gaps in the log) through `attend estimate` only; ~1 s per case.
"""

from __future__ import annotations

import os

for variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[variable] = "1"  # before numpy loads BLAS

import argparse  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from collections import Counter  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from hypothesis import HealthCheck, Phase, given, settings  # noqa: E402
from hypothesis import seed as seed_of  # noqa: E402

from fuzz_cases import ALLOWED, FAILURES, fuzz_case, nonlinear_fuzz_case, run_case  # noqa: E402


def campaign(cases: int, seed: int, folder: Path, nonlinear: bool = False) -> tuple[Counter, list]:
    counts, failures, number = Counter(), [], [0]
    commands = ("estimate",) if nonlinear else ("estimate", "identify")

    @settings(max_examples=cases, database=None, deadline=None, phases=[Phase.generate],
              suppress_health_check=list(HealthCheck))
    @given(case=nonlinear_fuzz_case() if nonlinear else fuzz_case())
    def one(case):
        number[0] += 1
        for command in commands:
            outcome = run_case(case, folder / f"{number[0]}-{command}", command)
            counts[outcome.category] += 1
            if outcome.category not in ALLOWED:
                failures.append(outcome)

    seed_of(seed)(one)()
    return counts, failures


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=1000, help="generated cases (each runs estimate and identify)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--nonlinear", action="store_true",
                        help="nonlinear model files (model.py: broken f and g, sizes, settings, gaps in the log) "
                             "through attend estimate")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        counts, failures = campaign(args.cases, args.seed, Path(folder), args.nonlinear)
    elapsed = time.perf_counter() - started
    runs = sum(counts.values())
    commands = 1 if args.nonlinear else 2
    print(f"{args.cases} {'nonlinear ' if args.nonlinear else ''}cases x {commands} command{'s' * (commands > 1)} "
          f"= {runs} runs in {elapsed:.1f} s")
    for category in ALLOWED + FAILURES:
        print(f"  {category:24s} {counts.get(category, 0):6d}")
    for outcome in failures:
        print(f"\n[{outcome.category}] attend {outcome.command} (exit {outcome.exit_code}); mutations: "
              f"{'; '.join(outcome.mutations) or 'none'}")
        print("  " + outcome.stderr.strip().replace("\n", "\n  ")[-1500:])
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
