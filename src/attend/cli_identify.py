"""`attend identify`: the command's run, its report and its exit status (linear models: DEM's
D, E and M steps, :func:`attend.workflows.identify_from_files`; nonlinear models: path-mode
learning, :func:`attend.workflows.identify_nonlinear`)."""

from __future__ import annotations

import sys
import time


def command_identify(args) -> int:
    """`attend identify MODEL LOG`: learn, print the report, write the learned model file (exit 0),
    or say why not (exit 3; args: the parsed command line: model, log, out, no_progress,
    allow_unconverged)."""
    from attend.cli import output_file

    import numpy as np

    from attend import io, workflows

    model = io.read_model(args.model)
    log = io.read_log(args.log, model)  # a CSV, or a ROS bag ([log.columns])
    output_file(args.out, "--out", "learned_model.toml")
    if model.nonlinear:
        return _identify_nonlinear(args, model, log)
    started = time.perf_counter()
    result = workflows.identify_from_files(model, log, progress=not args.no_progress)
    elapsed = time.perf_counter() - started
    print(result.table())
    accepted = ", ".join(f"{step}: {count}" for step, count in result.steps_accepted.items())
    print(f"free energy: {result.free_energy[0]:.6g} -> {result.free_energy[-1]:.6g} over {result.iterations} "
          f"iterations ({result.message}); "
          f"steps accepted {accepted}; {result.settings['state_model']} state model, top order "
          f"{result.settings['top_order']}; {elapsed:.2f} s")
    learned_A = result.system().A
    if np.all(np.isfinite(learned_A)):
        eig = np.linalg.eigvals(learned_A)
        listed = ", ".join(f"{complex(e).real:.4g}" + (f"{complex(e).imag:+.4g}j" if complex(e).imag else "") for e in eig)
        note = ("UNSTABLE (reported, not enforced: learning does not constrain A's stability)"
                if np.max(eig.real) > 0 else "stable")
        print(f"eigenvalues of the learned A [1/s]: {listed}: {note}")
    problems = workflows.check_learned_model(model, log, result)
    if result.converged and not problems:
        path = io.write_learned_model(args.out, model, result)
        print(f"learned model -> {path}")
        return 0
    if problems:
        print(f"attend: error: {model.path}: identify: the learned model is unusable: {'; '.join(problems)}; not written. "
              f"{_advice(result, model)}", file=sys.stderr)
        return 3
    written = "" if args.allow_unconverged else \
        " No learned model written (--allow-unconverged writes the last accepted estimate)."
    print(f"attend: error: {model.path}: identify did not converge on {log.path}: {result.message}. {_advice(result, model)}{written}",
          file=sys.stderr)
    if args.allow_unconverged:
        path = io.write_learned_model(args.out, model, result)
        print(f"learned model (NOT converged, --allow-unconverged) -> {path}")
    return 3


def _identify_nonlinear(args, model, log) -> int:
    """`attend identify` on a nonlinear model file: path-mode learning of [learning] free
    (attend.workflows.identify_nonlinear); exit 3 when it did not converge (the file is then written
    only with --allow-unconverged)."""
    from attend import io
    from attend.workflows.identify_nonlinear import identify_nonlinear, table

    started = time.perf_counter()
    names, result = identify_nonlinear(model, log)
    print(table(names, result))
    print(f"{result.message} (path mode, noise precisions from [observer]); "
          f"std: the estimator's spread (docs/nonlinear.md); {time.perf_counter() - started:.2f} s")
    if result.converged or args.allow_unconverged:
        path = io.write_learned_nonlinear(args.out, model, names, result)
        print(f"learned model{'' if result.converged else ' (NOT converged, --allow-unconverged)'} -> {path}")
    if result.converged:
        return 0
    print(f"attend: error: {model.path}: identify did not converge on {log.path}: {result.message}. Raise "
          "[learning] max_iterations or start nearer ([model] parameters).", file=sys.stderr)
    return 3


def _advice(result, model) -> str:
    """What to change in the [learning] section after a failed identification (one sentence)."""
    learning = model.learning or {}
    if "diverged" in result.message:
        step = result.message.split("the ", 1)[1].split("-step", 1)[0] if "-step" in result.message else "a"
        if step == "M":
            return ("Change: raise noise_prior_precision (now "
                    f"{learning.get('noise_prior_precision', 1.0)}) to keep the noise log-precisions near noise_prior_mean.")
        return ("Change: learn fewer entries (free) or raise free_prior_precision (now "
                f"{learning.get('free_prior_precision', 1.0)}) so the prior holds them.")
    if "known entries moved" in result.message:
        return (f"Change: known_prior_precision (now {learning.get('known_prior_precision', 3.3e6)}) = inf in "
                "[learning] to hold the entries that are not learned at their values in [model].")
    if "max_iterations" in result.message:
        other = "path" if result.settings.get("state_model") == "sample" else "sample"
        return (f"Change: raise max_iterations (now {learning.get('max_iterations', 50)}) or tolerance "
                f"(now {learning.get('tolerance', 1e-3)}) in [learning], or try states = \"{other}\".")
    return "Change: check the log (excitation, units) and the prior means in [model]."
