"""Active-vision benchmark: each figure beside its target.

    python benchmarks/bench_vision.py            # full: 100 scenes, 40 timing scenes (~5-10 min)
    python benchmarks/bench_vision.py --quick    # the quick experiment (16 scenes, < 40 s)

Targets (spec/rhythm.md, use 3): the epistemic policy (salience = expected information gain)
needs fewer saccades than the static-saliency and random policies to reach 90 % identification
accuracy; revisit rates are reported for all (inhibition of return is coded only in the classical
static-saliency model). The timing comparison (oscillator vs fixed fixation durations vs the
precision-driven scheduler) has no target: it is reported as measured.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from attend.experiments import vision  # noqa: E402

LEVEL = 0.9


def per_scene_crossings(accuracy: np.ndarray) -> np.ndarray:
    """Saccades each scene needs to reach LEVEL accuracy (inf if never within the run)."""
    hits = accuracy >= LEVEL
    return np.where(hits.any(axis=1), hits.argmax(axis=1), np.inf)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="the quick experiment settings")
    parser.add_argument("--out", default=None, help="directory for vision.json and the figures")
    args = parser.parse_args()
    start = time.perf_counter()
    result = vision.run(quick=args.quick, progress=True)
    if args.out:
        result.figures = vision.plot(result, args.out)
    elapsed = time.perf_counter() - start
    if args.out:
        result.write(args.out)
    settings = result.settings
    print(f"\nactive vision: {settings['scenes']} scenes ({settings['grid_rows']}x{settings['grid_cols']} letters "
          f"{settings['letters']}), {settings['saccades']} saccades, 4 Hz rhythm; {elapsed:.1f} s\n")

    keys = {"epistemic": "epistemic", "static saliency (IOR coded)": "static_saliency",
            "static saliency, no IOR": "static_saliency_no_IOR", "random": "random"}
    crossings = {name: per_scene_crossings(result.data[f"{key}_accuracy"]) for name, key in keys.items()}
    mean_curve = {name: result.metric(f"{key}: saccades to 90% accuracy (mean curve)").value
                  for name, key in keys.items()}
    print(f"{'figure':60s} {'measured':>10s}   target")
    for name, key in keys.items():
        c = crossings[name]
        finite = c[np.isfinite(c)]
        median = f"{np.median(c):.1f}" if np.isfinite(np.median(c)) else "never"
        print(f"{'saccades to 90% accuracy, ' + name + ' (mean curve)':60s} {mean_curve[name]:10.0f}   "
              + ("fewest" if name == "epistemic" else f"> epistemic ({mean_curve['epistemic']:.0f})"))
        print(f"{'   per scene: median / scenes reaching 90%':60s} {median:>10s}   "
              f"{len(finite)}/{len(c)} scenes")
    for rival in ("static saliency (IOR coded)", "random"):
        earlier = np.mean(crossings["epistemic"] < crossings[rival])
        tie = np.mean(crossings["epistemic"] == crossings[rival])
        verdict = "PASS" if mean_curve["epistemic"] < mean_curve[rival] else "FAIL"
        print(f"{'epistemic vs ' + rival + ': fewer saccades (mean curve)':60s} {verdict:>10s}   "
              f"per scene: earlier in {earlier:.0%}, tie {tie:.0%}")
    print()
    n_half = settings["grid_rows"] * settings["grid_cols"] // 2
    for name, key in keys.items():
        first = result.metric(f"{key}: revisit rate, first {n_half} saccades").value
        whole = result.metric(f"{key}: revisit rate, all {settings['saccades']} saccades").value
        note = {"epistemic": "low without coded IOR", "random": "chance",
                "static saliency (IOR coded)": "0 by construction",
                "static saliency, no IOR": "~1 (stuck)"}[name]
        uncertain = result.metric(f"{key}: revisit rate while summed entropy > 1 nat").value
        print(f"{'revisit rate, ' + name + f' (first {n_half} / all / H>1 nat)':60s} "
              f"{first:4.2f}/{whole:4.2f}/{uncertain:4.2f}   {note}")
    for n in (5, 10):
        row = ", ".join(f"{key} {result.metric(f'{key}: entropy after {n} saccades').value:.1f}"
                        for key in keys.values())
        print(f"entropy after {n:2d} saccades [nats]: {row}")
    print("\ntiming (epistemic policy; oscillator-matched precision budget; no target, measured):")
    print(f"{'scheduler':40s} {'H@0.5s':>8s} {'H@1s':>8s} {'acc@1s':>7s} {'t90%[s]':>8s} {'saccades/s':>10s}")
    labels = [m.name.split(": ")[0][len("timing "):] for m in result.metrics if m.name.startswith("timing ")
              and m.name.endswith("saccade rate")]
    for label in labels:
        def value(suffix):
            return result.metric(f"timing {label}: {suffix}").value
        t90 = value("time to 90% accuracy (mean curve)")
        print(f"{label:40s} {value('entropy at 0.5 s'):8.2f} {value('entropy at 1 s'):8.2f} "
              f"{value('accuracy at 1 s'):7.3f} {(f'{t90:.3f}' if np.isfinite(t90) else '> run'):>8s} "
              f"{value('saccade rate'):10.2f}")


if __name__ == "__main__":
    main()
