"""The time to find 90 % of the people of an ideal sweep: a reference for the search benchmarks
(``bench_mission.py``, ``bench_search_scale.py``), not a bound on every planner.

An ideal sweep flies tracks j per footprint width w(h) over the searchable area A at one altitude
h, all UAVs at once, with no transit from home, no turns and no way back: a sweep every
T = A j / (n_uav v w(h)) seconds, repeated. A person lies at a uniform place u T along the sweep;
after q sweeps they have had L q looks, L = j l(h) / (v dt) (l the footprint's length along the
track, dt the image interval), and are confirmed with the planner's channel
(:func:`attend.action.planners.salience.confirmation_probability`: the disc's prior mass m0
lifted to the target threshold by the detections of those looks; a fractional count of looks
mixes its floor and ceiling). The time to find ceil(0.9 n) of n people past the budget counts as
twice the budget, as in the benchmarks; the figure is the median over draws of the places and the
detections, at the altitude and overlap with the least median (chosen in hindsight).
"""

from __future__ import annotations

import math

import numpy as np

from attend.action.planners.salience import confirmation_probability

#: Sweeps flown at most (a person not confirmed after them is not found).
MAX_SWEEPS = 8


def ideal_sweep_t90(area_m2: float, people: int, prior_mass: float, channels, n_uavs: int, speed_m_s: float,
                    image_interval_s: float, budget_s: float, threshold: float, rng: np.random.Generator,
                    check_s: float = 0.0, draws: int = 4000) -> tuple[float, float, int]:
    """(t90 [s], h [m], j): the ideal sweep's median time to find 90 % and its altitude and overlap.

    area_m2: searchable area A; people: n; prior_mass: m0, a target disc's prior mass; channels:
    (h, across-track width [m], along-track length [m], pd, pf) per altitude tried; n_uavs, speed_m_s
    v, image_interval_s dt: the UAVs; budget_s: flight time; threshold: the target mass that
    confirms; rng: draws; check_s: found times rounded up to multiples of this (the simulator's
    found checks; 0: exact); draws: Monte Carlo draws per altitude and overlap."""
    need = max(1, math.ceil(0.9 * people - 1e-9))

    def confirmed(looks: float, pd: float, pf: float) -> float:
        low = int(np.floor(looks))
        share = looks - low
        values = [float(confirmation_probability(prior_mass, pd, pf, n, threshold)) if n > 0 else 0.0
                  for n in (low, low + 1)]
        return (1 - share) * values[0] + share * values[1]

    best = (math.inf, float("nan"), 0)
    for h, width, length, pd, pf in channels:
        for overlap in (1, 2, 3):
            looks = overlap * length / (speed_m_s * image_interval_s)
            period = area_m2 * overlap / (n_uavs * speed_m_s * width)
            cumulative = np.array([confirmed(looks * q, pd, pf) for q in range(1, MAX_SWEEPS + 1)])
            place = rng.uniform(size=(draws, people))
            sweep = np.searchsorted(cumulative, rng.uniform(size=(draws, people)), side="right")
            found = np.where(sweep < MAX_SWEEPS, (sweep + place) * period, np.inf)
            if check_s > 0:
                found = np.ceil(found / check_s) * check_s
            t90 = np.sort(found, axis=1)[:, need - 1]
            t90 = float(np.median(np.where(t90 <= budget_s, t90, 2 * budget_s)))
            if t90 < best[0]:
                best = (t90, float(h), overlap)
    return best


def binomial_tail(trials: int, probability: float, at_least: int) -> float:
    """P(J >= at_least) for J ~ Binomial(trials, probability)."""
    return float(sum(math.comb(trials, j) * probability**j * (1 - probability) ** (trials - j)
                     for j in range(max(at_least, 0), trials + 1)))


def detect_and_confirm_t90(area_m2: float, people: int, prior_mass: float, channels, association_m2, n_uavs: int,
                           speed_m_s: float, image_interval_s: float, budget_s: float, threshold: float,
                           confirm_s: float, rng: np.random.Generator, draws: int = 4000) -> tuple[float, float, int]:
    """(t90 [s], h [m], d): the median time to find 90 % of an ideal sweep that stops to confirm.

    As :func:`ideal_sweep_t90` (one altitude h, no transit, turns or way back), but every place
    with at least d of its L = l(h) / (v dt) looks reporting a detection is confirmed at once by
    a detour costing ``confirm_s`` seconds, whatever the planner's channel says: a person is
    found in the first sweep that gives them d reports or lifts their disc to the threshold,
    P = max(P(J >= d), confirmation_probability), J ~ Binomial(L, pd); each sweep lasts
    T = A / (n_uav v w(h)) + confirm_s (n P(J >= d, not confirmed) + (A / a) P(F >= d)),
    F ~ Binomial(L, pf) the false reports of one association area a. With ``confirm_s`` = 0
    this is a bound no sweep at one altitude can beat; with the seconds a real detour costs
    (a turn, a descent, a look and the way back), what is left of the adaptive gain.

    association_m2: a per channel (the area one report supports); the rest as
    :func:`ideal_sweep_t90`; d tried 1, 2, 3 and the best (h, d) kept in hindsight."""
    need = max(1, math.ceil(0.9 * people - 1e-9))
    best = (math.inf, float("nan"), 0)
    for (h, width, length, pd, pf), association in zip(channels, association_m2):
        looks = max(1, int(round(length / (speed_m_s * image_interval_s))))
        by_channel = float(confirmation_probability(prior_mass, pd, pf, looks, threshold))
        for reports in (1, 2, 3):
            by_reports = binomial_tail(looks, pd, reports)
            found = max(by_reports, by_channel)
            if found <= 1e-9:
                continue
            detours = people * max(by_reports - by_channel, 0.0) + area_m2 / association * binomial_tail(looks, pf, reports)
            period = area_m2 / (n_uavs * speed_m_s * width) + confirm_s * detours
            place = rng.uniform(size=(draws, people))
            sweep = rng.geometric(min(found, 1.0), size=(draws, people)) - 1
            t90 = np.sort((sweep + place) * period, axis=1)[:, need - 1]
            t90 = float(np.median(np.where(t90 <= budget_s, t90, 2 * budget_s)))
            if t90 < best[0]:
                best = (t90, float(h), reports)
    return best


def ordered_sweep_t90(area_m2: float, sweep_fractions, prior_masses, channels, n_uavs: int, speed_m_s: float,
                      image_interval_s: float, budget_s: float, threshold: float, rng: np.random.Generator,
                      draws: int = 4000) -> tuple[float, float]:
    """(t90 [s], h [m]): the median time to find 90 % of an ideal sweep in order of prior density.

    As :func:`ideal_sweep_t90` at overlap 1 (one altitude h, no transit, turns or way back), but
    each sweep images the ground in order of decreasing prior density, so person i is first seen a
    fraction u_i of the way through every sweep, at t = (q + u_i) T, T = A / (n_uav v w(h)), in the
    first sweep q = 0, 1, ... whose looks confirm them: P(confirmed within q + 1 sweeps) =
    confirmation_probability(m_i, pd, pf, L (q + 1), theta), m_i their target disc's prior mass.
    A reference for informative priors (what ordering by the prior alone gives), not a bound: a
    planner may re-image the likely ground before finishing a sweep.

    sweep_fractions: u_i per person (searchable area denser than their cell, over A); prior_masses:
    m_i per person; the rest as :func:`ideal_sweep_t90`."""
    fractions = np.asarray(sweep_fractions, dtype=float)
    masses = np.asarray(prior_masses, dtype=float)
    people = len(fractions)
    need = max(1, math.ceil(0.9 * people - 1e-9))
    best = (math.inf, float("nan"))
    for h, width, length, pd, pf in channels:
        looks = length / (speed_m_s * image_interval_s)
        period = area_m2 / (n_uavs * speed_m_s * width)
        cumulative = np.empty((people, MAX_SWEEPS))
        for i, mass in enumerate(masses):
            for q in range(MAX_SWEEPS):
                total = looks * (q + 1)
                low = int(np.floor(total))
                share = total - low
                values = [float(confirmation_probability(mass, pd, pf, n, threshold)) if n > 0 else 0.0
                          for n in (low, low + 1)]
                cumulative[i, q] = (1 - share) * values[0] + share * values[1]
        uniform = rng.uniform(size=(draws, people))
        sweep = (uniform[:, :, None] >= cumulative[None]).sum(axis=2)  # first sweep whose looks confirm
        found = np.where(sweep < MAX_SWEEPS, (sweep + fractions[None]) * period, np.inf)
        t90 = np.sort(found, axis=1)[:, need - 1]
        t90 = float(np.median(np.where(t90 <= budget_s, t90, 2 * budget_s)))
        if t90 < best[0]:
            best = (t90, float(h))
    return best
