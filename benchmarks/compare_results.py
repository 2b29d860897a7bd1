"""Compare two results folders (``attend reproduce ... --out DIR``) metric by metric.

Usage: python benchmarks/compare_results.py BEFORE AFTER [--rtol R] [--atol A]

For every NAME.json present in either folder, each metric (by name) is compared: values equal
(bit for bit, or both NaN) are counted as identical; others are printed with both values and
their relative difference, and marked "within tolerance" when |a - b| <= atol + rtol |a| (default
0: any change is a difference). Metrics or experiments present on one side only are listed.
Metrics that measure this machine's clock rather than the method (run times, samples per second,
compute-time ratios) differ from run to run; ``--skip-wall-clock`` leaves them out (they are
counted and named as skipped). Exit status: 0 when nothing differs beyond the tolerance, 1 otherwise.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from pathlib import Path


#: names of wall-clock metrics: run times [s] (planner calls, a first call with its compilation), speeds [samples/s], compute-time ratios
WALL_CLOCK = re.compile(r"(wall_time|_time_(mean|median)$|median_planner_time$|first call$|speed$|_over_best_fixed_compute$)")


def load_metrics(path: Path) -> dict[str, object]:
    """{metric name: value} of one result file (values as stored: numbers, strings, lists or None)."""
    return {m["name"]: m.get("value") for m in json.loads(path.read_text()).get("metrics", [])}


def same(a, b) -> bool:
    """Equal values, NaN equal to NaN, compared elementwise inside lists."""
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return a == b


def close(a, b, rtol: float, atol: float) -> bool:
    """|a - b| <= atol + rtol |a| for numbers (elementwise for lists); else equality."""
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(close(x, y, rtol, atol) for x, y in zip(a, b))
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        if math.isnan(a) or math.isnan(b):
            return math.isnan(a) and math.isnan(b)
        return abs(a - b) <= atol + rtol * abs(a)
    return same(a, b)


def relative(a, b) -> str:
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and a not in (0, 0.0):
        return f"{abs(b - a) / abs(a):.3g}"
    return "-"


def compare(before: Path, after: Path, rtol: float = 0.0, atol: float = 0.0, skip: re.Pattern | None = None) -> int:
    """Print the comparison; return the number of metrics that differ beyond the tolerance.
    Metrics whose name ``skip`` matches are left out (and counted as skipped)."""
    names = sorted({p.stem for p in before.glob("*.json")} | {p.stem for p in after.glob("*.json")})
    failures = 0
    for name in names:
        a_path, b_path = before / f"{name}.json", after / f"{name}.json"
        if not a_path.exists() or not b_path.exists():
            print(f"{name}: only in {'after' if not a_path.exists() else 'before'}")
            failures += 1
            continue
        a, b = load_metrics(a_path), load_metrics(b_path)
        skipped = sorted(m for m in set(a) | set(b) if skip is not None and skip.search(m))
        a = {k: v for k, v in a.items() if k not in skipped}
        b = {k: v for k, v in b.items() if k not in skipped}
        identical, lines = 0, []
        for metric in sorted(set(a) | set(b)):
            if metric not in a or metric not in b:
                lines.append(f"  {metric}: only in {'after' if metric not in a else 'before'}")
                failures += 1
            elif same(a[metric], b[metric]):
                identical += 1
            else:
                ok = close(a[metric], b[metric], rtol, atol)
                failures += not ok
                lines.append(f"  {metric}: {a[metric]!r} -> {b[metric]!r} (relative {relative(a[metric], b[metric])})"
                             + (" within tolerance" if ok else ""))
        print(f"{name}: {identical} of {len(set(a) | set(b))} metrics identical"
              + (f" ({len(skipped)} wall-clock metrics skipped)" if skipped else ""))
        for line in lines:
            print(line)
    print("no differences" if failures == 0 else f"{failures} difference(s) beyond tolerance")
    return failures


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    parser.add_argument("--rtol", type=float, default=0.0, help="relative tolerance (default 0: bit for bit)")
    parser.add_argument("--atol", type=float, default=0.0, help="absolute tolerance (default 0)")
    parser.add_argument("--skip-wall-clock", action="store_true",
                        help="leave out run times, speeds and compute-time ratios (they measure the machine)")
    args = parser.parse_args(argv)
    for folder in (args.before, args.after):
        if not folder.is_dir():
            parser.error(f"{folder}: not a folder")
    return 1 if compare(args.before, args.after, args.rtol, args.atol,
                           WALL_CLOCK if args.skip_wall_clock else None) else 0


if __name__ == "__main__":
    sys.exit(main())
