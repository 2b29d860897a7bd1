"""attend's active-inference demos against SPM12's own runs (issue 28).

SPM's numbers are stored in benchmarks/spm/reference/ (spm_ALAP on the attenuation demo, spm_ADEM on the
reaching demo, GNU Octave 7.3; benchmarks/spm/README.md); benchmarks/bench_spm_control.py runs attend the
same way. No Octave is needed.

What agrees and what does not (docs/spm.md, "Active inference"):
- reaching: attend's finger path follows SPM's (RMS gap 2.3 % of the 0.57 arm-length reach, closest
  approach 0.0205 against 0.0208 at the same bin), so the test asserts agreement within 5 %.
  With SPM's conventions (attend.control.reaching.SPM_CONVENTIONS: the attenuation's, plus the action's motion in
  the world's response, no motion error at the top order, SPM's weak prior on the beliefs and the world integrated
  jointly with the agent) the path is SPM's to 5.6e-6 RMS of the reach, the closest approach 0.0207584 against
  0.0207590 at the same bin; two of those conventions (the joint world, the top order) each move the closest
  approach outside 5 %;
- attenuation: with its own conventions attend's force is 63-86 % of SPM's. The difference is the orders of
  sensory motion the agent attends to (attend's default: up to the relative degree, orders 0..1; SPM: all of
  0..4). Stepping once per SPM bin and attending orders 0..3 brings attend within 5.1 % of SPM at every h
  (orders 0..4 are unstable in attend's sampled loop at h >= 3); that is asserted at 6 %.
  With SPM's conventions (attend.control.attenuation.SPM_CONVENTIONS: SPM's step, every order, the world's
  generalised response as data, the intention embedded per bin, integration="spm") both the true and the
  perceived force are within 5 % at every h (observed: true within 1.2 %, perceived within 3.9 %). What carries the
  difference (bench_spm_control.py --diagnose switches each convention back): the cause prior's precision
  (S at p + 1 orders, top-left block: up to 10 % at h = -4) and the data and prior moving within the bin (up to
  8 % at h = 6); sampled data with every order oscillate for h >= 4.
  The default configuration is checked only for the documented shortfall, not for agreement.

Tolerances: the runs are deterministic; changes at the rounding level (e.g. an analytic for a finite-difference
gradient) moved the SPM-conventions ratios by < 1e-8, while each convention moves them by >= 1e-2. The ratios are
pinned at 1e-4, and the 5 % target is asserted on top.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import load_benchmark

bench = load_benchmark("bench_spm_control")


@pytest.fixture(scope="module")
def spm_attenuation():
    return bench.spm_attenuation("attenuation_noiseless")


def test_references_are_complete(spm_attenuation):
    assert spm_attenuation["h"].tolist() == list(range(-4, 7))
    assert all(trace.shape == (32, 7) for trace in spm_attenuation["traces"].values())
    # SPM's own curve: the movement grows with attenuation (the demo's claim)
    assert np.all(np.diff(spm_attenuation["true"]) > 0)
    for tag in ("reaching", "reaching_noiseless", "reaching_nocue_noiseless"):
        run = bench.spm_reaching(tag)
        assert run["finger"].shape == (128, 2)
        assert run["record"]["cpu_seconds"] > 0


def test_attenuation_at_spm_step_and_orders_matches_spm(spm_attenuation):
    """Isolating the sensory orders: attend at dt = 1 s (SPM's step), attending orders 0..3, noiseless world,
    intention at SPM's bin 16 (t = 15 s): peak true force within 6 % of SPM's at every h (observed <= 5.1 %)."""
    own = bench.attend_attenuation(bench.spm_like_attenuation_settings(), sensory_orders=bench.SPM_LIKE_ORDERS)
    ratio = own["true"] / spm_attenuation["true"]
    assert np.all(np.abs(ratio - 1) < 0.06), ratio


#: attend / SPM per h = -4..6 with SPM's conventions (benchmarks/bench_spm_control.py), true and perceived force
SPM_CONVENTIONS_TRUE = [0.99641, 0.99348, 0.99752, 1.00017, 0.9998, 1.00095, 1.00075, 1.01229, 0.99562, 1.00298, 1.00155]
SPM_CONVENTIONS_PERCEIVED = [0.99857, 1.00274, 1.00583, 1.01407, 1.0173, 1.02163, 1.0267, 1.03827, 1.02687, 1.03918,
                             1.03719]


def test_attenuation_with_spm_conventions_matches_spm(spm_attenuation):
    """attend with SPM's conventions: the peak true and perceived force within 5 % of SPM's at every h."""
    own = bench.attend_attenuation_spm_conventions()
    true, perceived = own["true"] / spm_attenuation["true"], own["perceived"] / spm_attenuation["perceived"]
    assert np.all(np.abs(true - 1) <= 0.05) and np.all(np.abs(perceived - 1) <= 0.05), (true, perceived)
    np.testing.assert_allclose(true, SPM_CONVENTIONS_TRUE, atol=1e-4)
    np.testing.assert_allclose(perceived, SPM_CONVENTIONS_PERCEIVED, atol=1e-4)
    # the traces follow SPM's too: the true force peaks within one bin of SPM's at every h
    for h, trace in own["traces"].items():
        assert abs(int(trace[:, 0].argmax()) - int(spm_attenuation["traces"][h][:, 1].argmax())) <= 1


def test_attenuation_spm_conventions_need_spm_integration(spm_attenuation):
    """The same variant with attend's integration (data held within the bin, the cause prior weighed by S(s) at d + 1
    orders): outside 5 % (observed up to 8 % on the perceived force at h = 6)."""
    own = bench.attend_attenuation_spm_conventions(dict(bench.spm_conventions_settings(), integration="attend"))
    perceived = own["perceived"] / spm_attenuation["perceived"]
    assert np.max(np.abs(perceived - 1)) > 0.05


def test_attenuation_default_orders_fall_short_of_spm(spm_attenuation):
    """attend's own conventions (orders up to the relative degree, dt = 1/8 s), matched otherwise: the same
    shape as SPM (force rising with h) at 60-90 % of SPM's size. A documented difference, not agreement."""
    own = bench.attend_attenuation(bench.attenuation_settings(matched=True))
    ratio = own["true"] / spm_attenuation["true"]
    assert np.all(np.diff(own["true"]) > 0)
    assert np.all((ratio > 0.6) & (ratio < 0.9)), ratio


def test_reaching_path_matches_spm():
    spm = bench.spm_reaching("reaching_noiseless")
    cfg = bench.reaching_settings(matched=True)
    own = bench.attend_reaching(cfg)
    target = np.asarray(cfg["target"])
    scale = np.linalg.norm(spm["finger"][0] - target)
    gap = bench.path_gap(own["finger"], spm["finger"])
    assert np.sqrt(np.mean(gap**2)) / scale < 0.05  # observed 0.024
    d_spm, d_own = (np.linalg.norm(path - target, axis=1) for path in (spm["finger"], own["finger"]))
    assert d_own.min() == pytest.approx(d_spm.min(), rel=0.05)  # observed 0.0205 vs 0.0208
    assert abs(int(d_own.argmin()) - int(d_spm.argmin())) <= 2
    # the joint angles along the path (observed max gap 0.048 rad)
    assert np.abs(own["angles"] - spm["states"][:, :2]).max() < 0.1


def test_reaching_without_cue_stays_like_spm():
    spm = bench.spm_reaching("reaching_nocue_noiseless")
    own = bench.attend_reaching(bench.reaching_settings(matched=True), cued=False)
    for path in (spm["finger"], own["finger"]):
        assert np.linalg.norm(path - path[0], axis=1).max() < 0.01


@pytest.fixture(scope="module")
def spm_reach():
    return bench.spm_reaching("reaching_noiseless")


def test_reaching_with_spm_conventions_matches_spm(spm_reach):
    """attend with SPM's conventions (attend.control.reaching.SPM_CONVENTIONS) reproduces spm_ADEM's reach.

    Observed: RMS finger gap 5.6e-6 of the reach, largest 2.3e-5 (bin 29, during the fast part), joint angles within
    1.6e-5 rad, closest approach 0.0207584 against 0.0207590 at the same bin 46; the uncued run agrees to 3e-13. The
    smallest effect of one convention is SPM's weak prior on the beliefs (RMS gap 6.1e-5, largest 1.2e-4, angles
    6.7e-5 rad, distance at bin 128 -1.4e-3 relative without it), so the bounds sit between: RMS 2e-5, largest 6e-5,
    angles 4e-5 rad, the distances to the target 3e-4 relative (observed <= 6e-5)."""
    cfg = bench.reaching_spm_conventions_settings()
    fig = bench.reaching_figures(bench.attend_reaching(cfg), spm_reach, cfg["target"])
    spm = bench.reaching_figures(dict(finger=spm_reach["finger"], angles=spm_reach["states"][:, :2]), spm_reach,
                                 cfg["target"])
    assert fig["rms"] < 2e-5 and fig["max"] < 6e-5, fig
    assert fig["angles"] < 4e-5, fig
    assert fig["closest_bin"] == spm["closest_bin"] == 46
    for key in ("closest", "bin64", "bin128"):
        assert fig[key] == pytest.approx(spm[key], rel=3e-4), key
    # the target, on top: path and closest approach within 5 %
    assert fig["rms"] < 0.05 and abs(fig["closest"] / spm["closest"] - 1) < 0.05


def test_reaching_with_spm_conventions_drifts_like_spm_without_cue():
    """No cue: SPM's arm drifts 1.3e-4 arm lengths over the 128 bins, pulled by its weak prior on the beliefs (centred
    at 0); attend's with SPM's conventions follows it to 3e-13 (bounded at 1e-9, far below the drift)."""
    spm = bench.spm_reaching("reaching_nocue_noiseless")
    own = bench.attend_reaching(bench.reaching_spm_conventions_settings(), cued=False)
    assert np.linalg.norm(spm["finger"] - spm["finger"][0], axis=1).max() > 1e-4
    assert np.abs(own["finger"] - spm["finger"]).max() < 1e-9


@pytest.mark.parametrize("label", ["motion error at the top order kept", "world stepped apart (action held)"])
def test_reaching_spm_conventions_matter(spm_reach, label):
    """Switching back one convention of spm_ADEM's D-step moves the closest approach outside the 5 % target
    (observed: 0.0166 at bin 48 with the top order's motion error; 0.0073 at bin 101 with the world stepped apart
    from the agent, against SPM's 0.0208 at bin 46)."""
    cfg = dict(bench.reaching_spm_conventions_settings(), **bench.REACHING_ABLATION[label])
    fig = bench.reaching_figures(bench.attend_reaching(cfg), spm_reach, cfg["target"])
    spm_closest = np.linalg.norm(spm_reach["finger"] - np.asarray(cfg["target"]), axis=1).min()
    assert abs(fig["closest"] / spm_closest - 1) > 0.05, fig
