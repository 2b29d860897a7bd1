"""attend's active-inference demos against SPM12's own runs (issue 28).

SPM's numbers are stored in benchmarks/spm/reference/ (spm_ALAP on the attenuation demo, spm_ADEM on the
reaching demo, GNU Octave 7.3; benchmarks/spm/README.md); benchmarks/bench_spm_control.py runs attend the
same way. No Octave is needed.

What agrees and what does not (docs/spm.md, "Active inference"):
- reaching: attend's finger path follows SPM's (RMS gap 2.3 % of the 0.57 arm-length reach, closest
  approach 0.0205 against 0.0208 at the same bin), so the test asserts agreement within 5 %.
  With SPM's conventions (attend.control.reaching.SPM_CONVENTIONS: as the attenuation's below, with the seen causes
  embedded per bin and spm_ADEM's weak prior on the beliefs) the path is SPM's to 5.6e-6 RMS of the reach, the closest approach 0.0207584 against
  0.0207590 at the same bin; two of those conventions (the joint world, the top order) each move the closest
  approach outside 5 %;
- attenuation: with its own conventions attend's force is 63-86 % of SPM's. The difference is the orders of
  sensory motion the agent attends to (attend's default: up to the relative degree, orders 0..1; SPM: all of
  0..4). Stepping once per SPM bin and attending orders 0..3 brings attend within 5.1 % of SPM at every h
  (orders 0..4 are unstable in attend's sampled loop at h >= 3); that is asserted at 6 %.
  With SPM's conventions (attend.control.attenuation.SPM_CONVENTIONS: SPM's step, every order, the world's
  generalised response with the action's motion as data, the intention embedded per bin and moving within it as
  spm_ALAP's prior does, integration="spm" without the top order's motion error, the world integrated jointly with the
  agent, the beliefs recorded before each step) the peak true and perceived forces are SPM's to 4.0e-5 at every h,
  and the traces at every bin to 4.1e-5 of SPM's peak. That residual is spm_ALAP's numerics: with SPM's one-sided
  differences (spm_diff, step exp(-8)) for the world's df/da and the precision's gradient in place of attend's
  analytic ones, the peaks agree to 7.4e-9 and the traces to 3.4e-7. The default configuration is checked only for
  the documented shortfall, not for agreement.

Tolerances: the runs are deterministic and SPM's numbers are stored to 17 digits, so the comparison resolves what the
programs compute. With SPM's conventions the peaks and traces are bounded at 1e-4 of SPM's (observed 4.1e-5, the
one-sided differences); the smallest effect of switching back one convention that moves the peaks is the top
order's motion error (3.9e-4 on the peaks, 1.0e-3 on the traces), and the recording time moves the perceived trace by
0.26 of its peak. With SPM's one-sided differences the bounds are 1e-7 on the peaks and 1e-6 on the traces
(observed 7.4e-9 and 3.4e-7).
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


def test_attenuation_with_spm_conventions_matches_spm(spm_attenuation):
    """attend with SPM's conventions reproduces spm_ALAP: the peak true and perceived force at every h and both traces
    at every bin within 1e-4 of SPM's (observed 4.0e-5 on the peaks, 4.1e-5 on the traces, at h = 3)."""
    fig = bench.attenuation_figures(bench.attend_attenuation_spm_conventions(), spm_attenuation)
    assert fig["worst_true"] < 1e-4 and fig["worst_perceived"] < 1e-4, fig
    assert fig["trace_true"] < 1e-4 and fig["trace_perceived"] < 1e-4, fig
    # the target, on top
    assert fig["worst_true"] <= 0.05 and fig["worst_perceived"] <= 0.05


def test_attenuation_residual_is_spm_one_sided_differences(spm_attenuation):
    """What is left is spm_ALAP's numerics: with spm_diff's one-sided differences (step exp(-8)) for the world's
    d tanh(a)/da and the precision's gradient, attend agrees with SPM to 1e-7 on the peaks and 1e-6 on the traces
    (observed 7.4e-9 and 3.4e-7)."""
    fig = bench.attenuation_ablation(spm_attenuation, ["SPM's one-sided differences (numerics)"])[
        "SPM's one-sided differences (numerics)"]
    assert fig["worst_true"] < 1e-7 and fig["worst_perceived"] < 1e-7, fig
    assert fig["trace_true"] < 1e-6 and fig["trace_perceived"] < 1e-6, fig


@pytest.mark.parametrize("label", ["world stepped apart (action held)", "action held in the world's response",
                                   "prior moving with its folded motion", "motion error at the top order kept",
                                   "beliefs recorded after the step"])
def test_attenuation_spm_conventions_matter(spm_attenuation, label):
    """Switching back any one of the conventions added with the joint step moves attend outside the 1e-4 bound
    (observed, worst of the peaks and the traces: 1.1e-1, 2.9e-2, 3.9e-3, 1.0e-3; the recording time moves only the
    traces, 0.26 of the perceived peak)."""
    fig = bench.attenuation_ablation(spm_attenuation, [label])[label]
    assert max(fig["worst_true"], fig["worst_perceived"], fig["trace_true"], fig["trace_perceived"]) > 1e-4, fig


def test_attenuation_spm_conventions_need_spm_integration(spm_attenuation):
    """The same variant with attend's integration (data and prior held within the bin, the cause prior weighed by S(s)
    at d + 1 orders, the world stepped apart): outside 5 % (observed 7.3 % on the perceived force at h = 6)."""
    label = "integration='attend' (world apart)"
    fig = bench.attenuation_ablation(spm_attenuation, [label])[label]
    assert fig["worst_perceived"] > 0.05, fig


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
