"""Figures of the quadrotor experiment (:mod:`attend.experiments.quadrotor`), drawn from its result."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def figures(result, out_dir, *, published_vs_p, wind_flights, sse_unit: str) -> list[str]:
    """Figures (PNG in out_dir) of a quadrotor result: per-slice SSE bars (DEM vs KF), SSE vs p
    beside the published values ``published_vs_p`` (one per order 0..p), an example slice, and
    the motor-1 estimates. wind_flights: the flights of the bars; sse_unit: the SSE's unit.
    Returns the file names."""
    from attend.plotting import figure

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    data = result.data
    files = []

    fig, axes = figure((9, 6), 2, 1, sharex=True)
    for axis, condition, title in zip(axes, ("wind", "no_wind"), ("with wind", "without wind")):
        index = np.arange(len(data[condition]["DEM"]))
        axis.bar(index - 0.2, data[condition]["DEM"], 0.4, label="DEM")
        axis.bar(index + 0.2, data[condition]["KF"], 0.4, label="KF")
        axis.set_ylabel(f"SSE phi_dot [{sse_unit}]")
        axis.set_title(title)
    axes[0].legend()
    axes[-1].set_xticks(np.arange(20))
    axes[-1].set_xticklabels([f"{f[4:6]}/{s}" for f in wind_flights for s in range(5)], rotation=90, fontsize=7)
    axes[-1].set_xlabel("flight / slice")
    fig.tight_layout()
    files.append(_save(fig, out / "quadrotor_sse_per_slice.png"))

    fig, axis = figure((6, 4))
    orders = np.arange(len(published_vs_p))
    reproduced = [result.metric(f"dem_sse_wind_p{p}").value for p in orders]
    axis.semilogy(orders, reproduced, "o-", label="reproduced, wind")
    axis.semilogy(orders, published_vs_p, "kx", ms=10, label="published, wind")
    axis.semilogy(orders, [result.metric(f"dem_sse_no_wind_p{p}").value for p in orders], "s--",
                  label="reproduced, no wind (not published)")
    axis.set_xlabel("embedding order p")
    axis.set_ylabel(f"mean SSE phi_dot [{sse_unit}]")
    axis.legend()
    fig.tight_layout()
    files.append(_save(fig, out / "quadrotor_sse_vs_p.png"))

    example = data["wind"]["example"]
    fig, axis = figure((9, 4))
    axis.plot(example["time"], example["measured"], "k", lw=1.5, label="measured")
    axis.plot(example["time"], example["dem"], lw=1.0, label="DEM (published protocol)")
    axis.plot(example["time"], example["kf"], lw=1.0, label="KF (authors')")
    axis.plot(example["time"], example["dem_attend_default"], ":", lw=1.0, label="DEM (attend default)")
    axis.set_xlabel("time in slice [s]")
    axis.set_ylabel("phi_dot [rad/s]")
    axis.set_title(f"{example['flight']}, slice {example['slice']} (with wind)")
    axis.legend(fontsize=8)
    fig.tight_layout()
    files.append(_save(fig, out / "quadrotor_example_slice.png"))

    traces = data["inputs"]["traces"]
    fig, axes = figure((9, 2.2 * len(traces)), len(traces), 1, sharex=True)
    for axis, trace, value in zip(axes, traces, data["inputs"]["sse"]):
        axis.plot(trace["time"], trace["measured"], "k", lw=1.0, label="measured (scaled)")
        axis.plot(trace["time"], trace["dem"], lw=1.0, label="DEM estimate")
        axis.set_ylabel("motor 1")
        axis.set_title(f"{trace['flight']}: SSE {value:.2f}", fontsize=9)
    axes[0].legend(fontsize=8)
    axes[-1].set_xlabel("time from sample 400 [s]")
    fig.tight_layout()
    files.append(_save(fig, out / "quadrotor_motor1_estimate.png"))
    return files


def _save(fig, path: Path) -> str:
    fig.savefig(path, dpi=110)
    return path.name
