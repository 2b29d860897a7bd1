"""Calibration of the probability map over whole missions: targets, expected count and P(all found).

    python benchmarks/bench_map_calibration.py [--missions 600] [--first-seed 1000]

The generator of tests/action/test_probability_map.py::test_whole_missions_are_calibrated: 60 m x
60 m worlds at 1 m, 3-6 people, 20-60 images from random poses at 40-95 m with clutter. At the end
of each mission: targets (mass >= 0.5) holding a person within 3 m, by bins of their mass; the
map's expected number of people over the true number; P(all found) against whether everyone had a
target within 3 m, by bins, and separately in missions where two people stand within 7 m.
About 30 s for 600 missions on one core."""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from attend.action.camera import Camera
from attend.action.detection import DetectionModel
from attend.action.probability_map import ProbabilityMap
from attend.action.world import make_world, simulate_image

sys.path.insert(0, str(Path(__file__).resolve().parent))
from calibration_table import print_calibration_bins  # noqa: E402

FOUND_RADIUS_M = 3.0
CLOSE_PAIR_M = 7.0


def mission(seed: int, model: DetectionModel, camera: Camera) -> dict:
    """One mission of the test's generator: target masses and hits, expected/true count, P(all found),
    everyone found, and whether two people stand within CLOSE_PAIR_M."""
    rng = np.random.default_rng(seed)
    world = make_world(60.0, 1.0, int(rng.integers(3, 7)), seed=seed)
    n_images = int(rng.integers(20, 61))
    poses = np.column_stack([rng.uniform(-30, 30, n_images), rng.uniform(-30, 30, n_images),
                             rng.uniform(40, 95, n_images)])
    belief = ProbabilityMap.uniform(world.grid, float(world.n_people), world.searchable)
    for k, pose in enumerate(poses):
        belief.update(simulate_image(world, pose, float(k), 0.0, model, camera, rng), model, camera)
    positions, masses = belief.targets(0.5)
    near = np.linalg.norm(positions[:, None] - world.people_m[None], axis=-1) <= FOUND_RADIUS_M
    gaps = np.linalg.norm(world.people_m[:, None] - world.people_m[None], axis=-1)
    gaps[np.diag_indices(world.n_people)] = np.inf
    return dict(masses=np.minimum(masses, 1.0), hits=near.any(axis=1),
                ratio=belief.expected_people() / world.n_people, p_all=belief.p_all_found(0.5),
                all_found=bool(near.any(axis=0).all()), close_pair=bool(gaps.min() < CLOSE_PAIR_M))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--missions", type=int, default=600)
    parser.add_argument("--first-seed", type=int, default=1000)
    args = parser.parse_args()
    model = DetectionModel(false_detections_at_best=0.5, false_detections_at_useless=3.0)
    camera = Camera()
    start = time.perf_counter()
    runs = [mission(seed, model, camera) for seed in range(args.first_seed, args.first_seed + args.missions)]
    masses = np.concatenate([r["masses"] for r in runs])
    hits = np.concatenate([r["hits"] for r in runs])
    p_all = np.array([r["p_all"] for r in runs])
    found = np.array([r["all_found"] for r in runs])
    pairs = np.array([r["close_pair"] for r in runs])
    ratios = np.array([r["ratio"] for r in runs])
    print(f"{args.missions} missions, seeds {args.first_seed}..{args.first_seed + args.missions - 1} "
          f"({time.perf_counter() - start:.0f} s)")
    for low, high in ((0.5, 0.9), (0.9, 0.95), (0.95, 1.01)):
        chosen = (masses >= low) & (masses < high)
        if chosen.any():
            print(f"  targets of mass [{low}, {min(high, 1.0)}]: {chosen.sum()}, mean mass {masses[chosen].mean():.3f}, "
                  f"holding a person {hits[chosen].mean():.3f}")
    print(f"  false targets: {int((~hits).sum())} of {len(hits)}")
    print(f"  expected people / true number: {ratios.mean():.4f} +- {ratios.std() / np.sqrt(len(ratios)):.4f}")
    print_calibration_bins(p_all, found, "P(all found)", "missions")
    for label, chosen in ((f"two people within {CLOSE_PAIR_M:g} m", pairs), ("no such pair", ~pairs)):
        print(f"  {label}: {chosen.sum()} missions, mean P(all found) {p_all[chosen].mean():.3f}, "
              f"everyone found {found[chosen].mean():.3f}")


if __name__ == "__main__":
    main()
