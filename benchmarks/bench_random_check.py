"""Reading ../shared/tools/random_system_check.py: attend estimate against the exact posterior of that tool's own model.

    python benchmarks/bench_random_check.py [--seeds 20] [--first 20000] [--tool PATH]

The check draws random stable LTI systems, simulates them itself (zero-order hold of the known
inputs, coloured noise w entering as dt w[k-1], x[0] = 0), runs ``attend estimate`` with its
defaults and prints the state SSE over that of a white-noise Kalman filter told the true variances
and x[0] = 0 exactly. Its ratios run from ~0.5 to ~800. On the check's own systems and logs (its
functions, imported) this benchmark splits each ratio into three factors:

    check = (attend, x[0] unknown / attend, x[0] known) x (attend, x[0] known / exact) x (exact / white KF)

- the value of knowing x[0]: ``attend estimate`` treats x[0] as unknown (a broad prior, 100x the
  state scale seen in the first sample) unless the model file sets ``[observer] initial_state``
  (here 0, as the check simulates); the filter is told it. Where a slow mode is weakly observed
  and the process noise is small, that alone is worth 10-1000x;
- attend's quality: its estimate with x[0] known over the exact posterior mean of the check's model
  with x[0] known (dense Gaussian conditioning on the check's simulator: its discretisation, its
  kernel's autocorrelation, its noise entry; Cov(y) is solved on its eigenvectors above 1e-12
  of its largest eigenvalue, since it is near-singular for smooth kernels). The first lines
  validate that posterior against attend's smoother over 40 fresh logs of one system (s/dt = 2):
  the mean SSEs agree where both are the posterior mean, while single logs differ by ~1 % from
  the eigenvalue floor;
- the filter's own loss to that posterior (>= 1 on average; a single log can fall either side).

Per seed it prints the four numbers, then their medians and ranges. ~5-10 s per seed on one core.
Not part of the test run.
"""

from __future__ import annotations

import os

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")  # one core, before numpy loads BLAS

import argparse  # noqa: E402
import importlib.util  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.linalg import expm  # noqa: E402

from attend.perception.references import kalman_filter  # noqa: E402
from attend.perception.references.exact import _transfer_matrix, coloured_noise_correlation  # noqa: E402
from attend.models.linear import LinearSystem  # noqa: E402

TOOL = Path(os.environ.get("ATTEND_SHARED", Path(__file__).resolve().parents[2] / "shared")) / "tools" / \
    "random_system_check.py"
TRIM = slice(10, -10)  # the check's scoring window
EIGEN_FLOOR = 1e-12  # relative eigenvalue below which Cov(y) is taken as singular


def load_tool(path: Path):
    """The check's module (its random_system, coloured and one)."""
    spec = importlib.util.spec_from_file_location("random_system_check", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def redraw(tool, seed: int) -> dict:
    """The check's system, settings and log for ``seed``: the same draws in the same order as tool.one."""
    rng = np.random.default_rng(seed)
    A, B, C = tool.random_system(rng)
    n, r, m = A.shape[0], B.shape[1], C.shape[0]
    dt = float(rng.choice([0.02, 0.05, 0.1]))
    s = float(rng.choice([0.5, 1, 2, 5])) * dt
    n_samples = 500
    sigma_w, sigma_z = float(np.exp(rng.uniform(-5, -1))), float(np.exp(rng.uniform(-5, -1)))
    t = np.arange(n_samples) * dt
    u = np.stack([np.sin(2 * np.pi * t / rng.uniform(2, 10) + j) for j in range(r)], 1)
    M = np.zeros((n + r, n + r))
    M[:n, :n], M[:n, n:] = A, B
    E = expm(M * dt)
    Ad, Bd = E[:n, :n], E[:n, n:]
    w, z = tool.coloured(rng, n, n_samples, sigma_w, s, dt), tool.coloured(rng, m, n_samples, sigma_z, s, dt)
    x = np.zeros((n_samples, n))
    for k in range(1, n_samples):
        x[k] = Ad @ x[k - 1] + Bd @ u[k - 1] + dt * w[k - 1]
    return dict(system=LinearSystem(A, B, C), Ad=Ad, Bd=Bd, C=C, dt=dt, s=s, sigma_w=sigma_w, sigma_z=sigma_z, u=u, x=x, y=x @ C.T + z)


def posterior_operator(case: dict, start_std: float = 0.0):
    """(estimate(y): the posterior mean (N, n) of x given outputs y (N, m)) under the check's model
    with x[0] ~ N(0, start_std^2 I) (0: known, as the check simulates): x = mu + T0 x[0] + L w
    (T0[k] = Ad^k, L[k, j] = dt Ad^(k-1-j) for j < k), w and z with the covariance of the check's
    kernel (its autocorrelation, exactly), by dense Gaussian conditioning."""
    Ad, C, dt = case["Ad"], case["C"], case["dt"]
    n_samples, n = case["x"].shape
    time_cov = coloured_noise_correlation(n_samples, dt, case["s"])  # the check's kernel: the same samples
    L, start = _transfer_matrix(Ad, n_samples)
    L = dt * L
    mean = np.zeros((n_samples, n))
    for k in range(1, n_samples):
        mean[k] = Ad @ mean[k - 1] + case["Bd"] @ case["u"][k - 1]
    cov_x = case["sigma_w"] ** 2 * (L @ np.kron(time_cov, np.eye(n)) @ L.T) + start_std**2 * start @ start.T
    observe = np.kron(np.eye(n_samples), C)
    cross = cov_x @ observe.T
    cov_y = observe @ cross + case["sigma_z"] ** 2 * np.kron(time_cov, np.eye(C.shape[0]))
    # cov_y is near-singular where the kernel is smooth (its spectrum falls like exp(-(omega s)^2)):
    # solve on its eigenvectors above EIGEN_FLOOR x its largest eigenvalue (a plain solve amplifies
    # rounding into 1e7-fold SSE errors at s/dt = 2)
    values, vectors = np.linalg.eigh(cov_y)
    kept = values > EIGEN_FLOOR * values.max()
    gain = cross @ (vectors[:, kept] / values[kept]) @ vectors[:, kept].T

    def estimate(y):
        return mean + (gain @ (y - mean @ C.T).ravel()).reshape(n_samples, n)

    return estimate


def validate(tool, seed: int, logs: int) -> None:
    """Mean state SSE of attend's Kalman smoother and of the posterior operator over ``logs`` fresh
    logs of the check's system ``seed`` (x[0] known, and x[0] ~ N(0, 0.1^2 I)): equal where both are
    the posterior mean."""
    from attend.perception.kalman import KalmanEstimator

    case = redraw(tool, seed)
    n, m = case["Ad"].shape[0], case["C"].shape[0]
    for start_std in (0.0, 0.1):
        smoother = KalmanEstimator(case["system"], case["dt"], sensor_precision=np.eye(m) / case["sigma_z"] ** 2,
                                   process_precision=np.eye(n) / case["sigma_w"] ** 2, kernel_width=case["s"],
                                   initial_state=np.zeros(n), initial_state_std=start_std)
        posterior = posterior_operator(case, start_std)
        rng = np.random.default_rng(123)
        totals = np.zeros(2)
        for _ in range(logs):
            log = simulate(tool, case, rng, start_std)
            totals += [np.sum((smoother.estimate(log["y"], case["u"]).states - log["x"]) ** 2),
                       np.sum((posterior(log["y"]) - log["x"]) ** 2)]
        print(f"  validation, seed {seed}, x[0] std {start_std:g}, {logs} logs: mean state SSE attend "
              f"{totals[0] / logs:.6g}, exact posterior {totals[1] / logs:.6g}", flush=True)


def simulate(tool, case: dict, rng, start_std: float) -> dict:
    """A fresh log {x, y} of the check's system in ``case`` (its simulator), x[0] ~ N(0, start_std^2 I)."""
    n_samples, n = case["x"].shape
    w = tool.coloured(rng, n, n_samples, case["sigma_w"], case["s"], case["dt"])
    z = tool.coloured(rng, case["C"].shape[0], n_samples, case["sigma_z"], case["s"], case["dt"])
    x = np.zeros((n_samples, n))
    x[0] = start_std * rng.standard_normal(n)
    for k in range(1, n_samples):
        x[k] = case["Ad"] @ x[k - 1] + case["Bd"] @ case["u"][k - 1] + case["dt"] * w[k - 1]
    return dict(x=x, y=x @ case["C"].T + z)


def white_kalman_filter(case: dict) -> np.ndarray:
    """The check's white-noise Kalman filter (N, n): x[0] = 0 with P0 = 1e-9 I, Q = (dt sigma_w)^2 I,
    R = sigma_z^2 I, the true ZOH model (attend's baseline :func:`kalman_filter`)."""
    n, m = case["Ad"].shape[0], case["C"].shape[0]
    return kalman_filter(case["system"], case["dt"], case["y"], case["u"],
                         process_covariance=np.eye(n) * (case["dt"] * case["sigma_w"]) ** 2,
                         measurement_covariance=np.eye(m) * case["sigma_z"] ** 2, initial_mean=np.zeros(n),
                         initial_covariance=np.eye(n) * 1e-9).states


def attend_with_known_start(work: Path, seed: int, n: int, attend: str) -> np.ndarray:
    """attend estimate on the check's files of ``seed`` with ``[observer] initial_state`` = 0 added."""
    text = (work / f"s{seed}.toml").read_text().replace("[observer]\n", f"[observer]\ninitial_state = {[0.0] * n}\n")
    (work / "known.toml").write_text(text)
    subprocess.run([attend, "estimate", str(work / "known.toml"), str(work / f"s{seed}.csv"), "--out",
                    str(work / "known.csv")], check=True, capture_output=True)
    table = np.genfromtxt(work / "known.csv", delimiter=",", names=True)
    return np.column_stack([table[f"x{i + 1}"] for i in range(n)])


def one_seed(tool, seed: int, work: Path, attend: str) -> dict:
    """The four ratios of the module docstring for ``seed``."""
    line = tool.one(seed, work, attend)
    case = redraw(tool, seed)
    n = case["x"].shape[1]
    default = np.genfromtxt(work / f"s{seed}_est.csv", delimiter=",", names=True)
    default = np.column_stack([default[f"x{i + 1}"] for i in range(n)])
    known = attend_with_known_start(work, seed, n, attend)
    exact = sse(case, posterior_operator(case)(case["y"]))
    default, known, white = sse(case, default), sse(case, known), sse(case, white_kalman_filter(case))
    return dict(line=line.split(": attend")[0], check=default / white, start=default / known,
                known_exact=known / exact, kf_exact=white / exact)


def sse(case: dict, estimate: np.ndarray) -> float:
    """State SSE over the check's scoring window."""
    return float(np.sum((estimate - case["x"])[TRIM] ** 2))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--first", type=int, default=20000, help="the first seed (the check's --seed)")
    parser.add_argument("--tool", type=Path, default=TOOL, help="path of random_system_check.py")
    parser.add_argument("--validate", type=int, default=20004, help="the seed whose system validates the "
                        "posterior operator against attend over fresh logs (-1: skip)")
    parser.add_argument("--logs", type=int, default=40, help="fresh logs of the validation")
    args = parser.parse_args()
    attend = shutil.which("attend")
    if not args.tool.is_file() or attend is None:
        print(f"bench_random_check: needs {args.tool} and `attend` on PATH (pip install -e .)")
        return
    tool = load_tool(args.tool)
    if args.validate >= 0:
        validate(tool, args.validate, args.logs)
    print("== random_system_check's systems: attend estimate against the exact posterior of the check's model")
    print("   check = (attend, x[0] unknown / known) x (attend, x[0] known / exact) / (white KF / exact); exact: "
          "the posterior mean of the check's own model, x[0] known")
    rows = []
    with tempfile.TemporaryDirectory(prefix="random-check-") as folder:
        for seed in range(args.first, args.first + args.seeds):
            row = one_seed(tool, seed, Path(folder), attend)
            rows.append(row)
            print(f"  {row['line']}: check {row['check']:8.3g} = x[0] unknown / known {row['start']:8.3g} x "
                  f"attend / exact {row['known_exact']:.4f} / (white KF / exact {row['kf_exact']:.3f})", flush=True)
    for key, label in (("check", "the check's ratio (attend / white KF)"), ("start", "attend, x[0] unknown / known"),
                       ("known_exact", "attend (x[0] known) / exact posterior"),
                       ("kf_exact", "white KF / exact posterior")):
        values = np.array([row[key] for row in rows])
        print(f"  {label:36s}: median {np.median(values):.4g}, range {values.min():.4g} .. {values.max():.4g}")


if __name__ == "__main__":
    main()
