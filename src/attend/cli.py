"""The ``attend`` command line: estimate, reproduce, and the rest of the paper's pipeline.

Exit status: 0 done; 2 bad input: one line ``attend: error: <file or field>: <what was expected>``
(a malformed file or option, or an operating-system problem with a path the user gave: a
directory, a permission, a full disk); 1 an internal error (a bug: please report it). Tracebacks
are shown only with ``--debug``, which may stand before or after the command. ``main`` returns
the status; argparse's own usage errors and ``--help`` raise SystemExit as usual.
"""

from __future__ import annotations

import argparse
import errno
import inspect
import json
import math
import sys
import tempfile
import time
import warnings
from pathlib import Path

from attend._progress import progress_bars
from attend._validation import AttendInputError
from attend.cli_identify import command_identify

EPILOG_ESTIMATE = """\
The model file (TOML) gives A, B, C (continuous time, seconds), the CSV columns of the outputs
and of the measured inputs, priors of the unknown inputs, and the observer settings (kernel
width [s], embedding orders p and d, precisions). See README.md ("Your own robot") for the
format and a worked example on the bundled quadrotor flight:

    attend estimate --demo --out roll_estimates.csv

Nonlinear models: [model] python = "model.py" (f(x, v) and g(x, v)) with n_states, n_inputs,
n_outputs. Default method "ukf" (unscented RTS smoother; its std is its error spread under the
coloured noise, ~95 % of errors within 2 std on simulated logs); [observer] method = "dem" runs
nonlinear DEM's D-step, and adding states = "path" runs DEM in path mode (one trajectory for
the whole log: a smoother; it warns on logs it does not describe; docs/nonlinear.md);
backend = "jax" compiles the D-step (f, g written with jax.numpy; pip install "attend[jax]").
"""


#: Units of the bundled quadrotor roll model (``attend estimate --demo``), for the figure's axes.
DEMO_UNITS = {"phi": "rad", "phi_dot": "rad/s", **{f"motor_{m}": "command - mean" for m in range(1, 5)}}


def _build_parser(argv=None) -> argparse.ArgumentParser:
    """The ``attend`` parser: global options and one sub-parser per command. argv: the arguments
    it will parse (None: build every command in full); a command other than ``search`` skips
    the search options, whose help lists the planners (importing them costs about a second)."""
    # --debug is accepted after the command too; SUPPRESS keeps a subcommand from resetting it
    debug_anywhere = argparse.ArgumentParser(add_help=False)
    debug_anywhere.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                                help="show full tracebacks on errors")
    parser = argparse.ArgumentParser(
        prog="attend",
        description=(
            "Precision-modulated perception and action for robots (Anil Meera et al., "
            "'Reclaiming saliency'). DEM state and input estimation in generalised coordinates, "
            "precision learning, informative path planning and rhythmic scheduling."
        ),
        epilog=(
            "examples:\n"
            "  attend reproduce all --out results       every result of the paper + results/index.html\n"
            "  attend reproduce list                    the experiments\n"
            "  attend report results                    redraw the figures and index.html from the JSON\n"
            "  attend estimate --demo --out roll.csv    states of a real quadrotor from its log\n"
            "  attend estimate model.toml log.csv       your own robot (formats: README.md)\n"
            "  attend identify model.toml log.csv       learn its parameters and noise precisions\n"
            "  attend search --out run1                 a UAV searching the paper's field for people\n"
            "  attend search --area-size 500 --uavs 2   two UAVs on a 500 m x 500 m area\n"
            "  attend plan mission.toml --out plan1     the next flight plan on your own ground\n"
            "Units: seconds, metres, radians; precisions are inverse variances.\n"
            "'attend COMMAND --help' explains each option."
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--debug", action="store_true", help="show full tracebacks on errors")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")

    def add_command(name, **options):
        return commands.add_parser(name, parents=[debug_anywhere], **options)

    _add_estimate(add_command)
    _add_reproduce(add_command)
    _add_report(add_command)
    _add_identify(add_command)
    words = [a for a in (argv or []) if not a.startswith("-")]
    if argv is None or not words or words[0] == "search":
        _add_search(add_command)
    else:
        add_command("search", help=SEARCH_HELP)
    from attend.cli_plan import add_plan

    add_plan(add_command)
    return parser


def _add_estimate(add_command) -> None:
    estimate = add_command(
        "estimate",
        help="estimate states and inputs of your own system from a CSV log",
        description="Estimate the states (and unknown inputs) of a model file's system from a CSV log and "
        "write them with their standard deviations (CSV; units of the log). Default method: the "
        "Kalman smoother under the coloured-noise model (the exact Gaussian posterior up to ~1 %; for "
        "nonlinear models the unscented smoother, its std the error spread under the coloured noise); "
        "[observer] method = \"dem\" runs the paper's DEM observer instead.",
        epilog=EPILOG_ESTIMATE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    estimate.add_argument("model", nargs="?", help="model file (TOML), see README for the format")
    estimate.add_argument("log", nargs="?", help="log file (CSV with a header and a time column in seconds; missing "
                          "values, skipped and jittered time stamps are accepted: docs/command-line.md), or a ROS bag (.bag, .mcap, .db3 "
                          "or a ROS 2 bag folder) with topics and fields named in the model's [log.columns]")
    estimate.add_argument("--demo", action="store_true",
                          help="use the bundled quadrotor roll model and flight (exp_21, wind on) instead of MODEL and LOG")
    estimate.add_argument("--out", default="estimates.csv",
                          help="output CSV: t [s], each state and input, and <name>_std columns (default: %(default)s)")
    estimate.add_argument("--plot", metavar="PNG",
                          help="also plot the estimates to this PNG file: one row per state and input, the "
                          "estimate with its +-2 std band (left) and the band's half-width 2 std on its own "
                          "scale (right); measured inputs are drawn as measured. Default: no plot")
    estimate.add_argument("--no-progress", action="store_true",
                          help="hide the progress bars of the slower estimators (nonlinear models: the unscented "
                          "smoother, DEM), which a terminal shows once a run takes over a second")


def _add_reproduce(add_command) -> None:
    reproduce = add_command(
        "reproduce",
        help="reproduce a result of the paper (or all of them)",
        description="Run a reproduction experiment and write OUT/NAME.json (reproduced beside published "
        "values, and the tables its figures are drawn from) and PNG figures. 'all' runs every experiment "
        "and writes the self-contained HTML report OUT/index.html. Results are cached by configuration: a "
        "rerun only redoes what changed.",
    )
    reproduce.add_argument("name", help="experiment name, or 'all'; 'attend reproduce list' shows them")
    reproduce.add_argument("--out", default="results", help="output directory, created if missing (default: %(default)s)")
    reproduce.add_argument("--full", action="store_true",
                           help="paper-size settings (more seeds and trials; minutes to hours). Default: quick "
                           "settings (seconds to a few minutes per experiment)")
    reproduce.add_argument("--no-progress", action="store_true", help="hide progress bars (default: shown)")
    reproduce.add_argument("--cluster", metavar="ADDRESS", default=None,
                           help="run the sweeps (fig4, fig5, rhythm-ipp, rhythm-tradeoff) on a running Dask cluster, e.g. tcp://host:8786 "
                           "(needs: pip install 'attend[distributed]'); same numbers as a local run. Default: run here")
    reproduce.add_argument("--force", action="store_true",
                           help="rerun even when OUT/NAME.json holds a result for the same code and mode (cache)")
    reproduce.add_argument("--report", action="store_true",
                           help="also write OUT/index.html for a single experiment (always written for 'all')")


def _add_report(add_command) -> None:
    report = add_command(
        "report",
        help="redraw every figure and DIR/index.html from the JSON results in DIR",
        description="Rebuild the figures and the HTML report of a results folder from its JSON files alone "
        "(nothing is recomputed: seconds). The page opens with the paper's claims (measured, published, "
        "verdict), then each experiment's figures with captions; the full metric table is folded away.",
        epilog="exit status: 0 written; 2 a JSON is missing or corrupt (the message names the file).",
    )
    report.add_argument("dir", metavar="DIR", help="the --out folder of 'attend reproduce' (holds NAME.json files)")
    report.add_argument("names", nargs="*", metavar="NAME",
                        help="only these experiments (default: every experiment with a DIR/NAME.json)")


def _add_identify(add_command) -> None:
    identify = add_command(
        "identify",
        help="learn the parameters and noise precisions of your model from a CSV log",
        description="System identification with precision learning (DEM's D, E and M steps): the model "
        "file's A, B, C are the prior means, its [learning] section says which entries are free and how "
        "precise the priors are. Writes a learned model file (posterior means and precisions of the "
        "parameters, learned noise precisions) and prints the convergence report.",
        epilog="See README.md ('Identify your model') for the [learning] section.\n\n"
        "Nonlinear models ([model] python): [learning] free names entries of the model's parameters dict\n"
        "(e.g. free = [\"damping\"]), free_prior_precision their prior precision (default 0: flat); they are\n"
        "learned with the trajectory by DEM's path mode, unknown inputs estimated under their priors, the\n"
        "noise precisions taken from [observer]; the learned file holds them in [model] parameters and\n"
        "their error bars in [learned] (docs/nonlinear.md).\n\n"
        "exit status: 0 converged and the learned model written; 2 bad input (e.g. no [learning] section);\n"
        "3 the learning did not converge (max_iterations reached or a step diverged) or the learned model\n"
        "would give non-finite estimates: nothing is written unless --allow-unconverged (a model that\n"
        "gives non-finite estimates is never written).",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    identify.add_argument("model", help="model file (TOML) with a [learning] section; all inputs measured "
                          "(nonlinear models: unknown inputs allowed)")
    identify.add_argument("log", help="log file (CSV, uniform time column in seconds), or a ROS bag "
                          "([log.columns] in the model file)")
    identify.add_argument("--out", default="learned_model.toml",
                          help="learned model file, usable by 'attend estimate' (default: %(default)s)")
    identify.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    identify.add_argument("--allow-unconverged", action="store_true",
                          help="write the last accepted estimate even when the learning did not converge "
                          "(the exit status is still 3)")


#: What each planner of ``attend search --planner`` does on the Gaussian map (``--map gp``).
PLANNER_HELP = {
    "precision_gain": "trace(P) reduction per second of flight",
    "adaptive": "gain weighted by optimistic occupancy and an altitude preference",
    "efe": "expected free energy (epistemic + preference for observing people)",
    "efe_confirm": "EFE search at 14 m, then confirmation views at 8 m of the uncertain detections",
    "cover_confirm": "two coverage passes at 13 m, then the views that most advance the least certain cell of "
    "every detection (finds the most people)",
    "lawnmower": "baseline: lawnmower sweep at 10 m",
    "random": "baseline: random views",
}
#: Options of ``attend search`` that only the Gaussian map (``--map gp``) reads: dest -> option.
GP_ONLY_OPTIONS = {"fov": "--fov", "altitude_limits": "--altitude-limits", "clutter": "--clutter",
                   "diagonal": "--diagonal", "no_gif": "--no-gif"}
#: Options of ``attend search`` that only the probability map reads: dest -> option.
PROBABILITY_ONLY_OPTIONS = {"area_size": "--area-size", "cell_size": "--cell-size", "uavs": "--uavs",
                            "buildings": "--buildings", "prior_map": "--prior-map", "image_rate": "--image-rate"}
SEARCH_EPILOG = """\
examples:
  attend search --out run1                       EFE planner on the paper's 30 m field (7 people, 150 s)
  attend search --planner lawnmower --out run2   the same field swept by a lawnmower at 10 m
  attend search --area-size 500 --cell-size 1 --people 10 --uavs 2 --out big
                                                 two UAVs on a 500 m x 500 m area (250 000 cells)
  attend search --area-size 300 --prior-map likely.png --out prior
                                                 people more likely where the picture is brighter
  attend search --map gp --planner cover_confirm --out paper
                                                 the paper's Gaussian occupancy map and its planners

outputs (in --out): search_metrics.json (summary: people_total, people_found, found_times_s,
time_to_find_all_s (null unless all were found), false_targets, p_all_found_end, area_covered_m2,
distance_flown_m, median/max_planner_time_s, median_map_update_ms; per-image series), search_map.png
(P(person) per cell, paths, people, targets), search_found.png (people found and P(all found) vs time).
A person counts as found when a reported target (a cluster of cells holding >= 0.5 expected
people) lies within 3 m of them; a target with nobody within 3 m is a false target.
"""


SEARCH_HELP = "fly a UAV search-and-rescue mission: probability map, expected-free-energy planner"


def _add_search(add_command) -> None:
    from attend.action.planners import PLANNERS
    from attend.action.search_run import SEARCH_PLANNERS

    search = add_command(
        "search",
        help=SEARCH_HELP,
        description="A search for people lying on the ground: plan, fly, fuse every image into a map of "
        "P(person) per cell (Bayes' rule with the detector's detection probability, clutter and "
        "position error by altitude), replan, until the flight time is spent. Without --area-size, the "
        "paper's 30 m x 30 m field (0.75 m cells, 7 people, 150 s, one image every 6.7 s); with it, a "
        "square area at field scale (1 m cells, 10 m/s, 1 image/s). --map gp flies the paper's Gaussian "
        "occupancy map and its planners instead.",
        epilog=SEARCH_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    gp_planners = "; ".join(f"{name}: {PLANNER_HELP[name]}" if name in PLANNER_HELP else name for name in PLANNERS)
    probability_planners = "; ".join(f"{name}: {text}" for name, text in SEARCH_PLANNERS.items())
    search.add_argument("--map", default="probability", choices=["probability", "gp"],
                        help="probability: P(person) per cell as log-odds, scales to 10^6 cells; gp: the paper's "
                        "Gaussian occupancy map with its full covariance (30 m field only) (default: %(default)s)")
    search.add_argument("--planner", default="efe", choices=sorted(set(PLANNERS) | set(SEARCH_PLANNERS)),
                        help=f"on the probability map: {probability_planners}. With --map gp: {gp_planners} "
                        "(default: %(default)s)")
    search.add_argument("--seed", type=int, default=0,
                        help="seed of the people placement, detector and planner (default: %(default)s)")
    search.add_argument("--area-size", type=float, default=None, metavar="M",
                        help="side of a square search area [m] (default: the paper's 30 m field)")
    search.add_argument("--cell-size", type=float, default=None, metavar="M",
                        help="map cell side [m] (default: 1 with --area-size; 0.75 on the paper's field)")
    search.add_argument("--people", type=int, default=None, metavar="N",
                        help="people in the area; the map's prior expects this many (default: 7 on the paper's "
                        "field, 10 with --area-size)")
    search.add_argument("--uavs", type=int, default=None, metavar="K",
                        help="UAVs sharing the map, planned one after another (default: 1)")
    search.add_argument("--buildings", type=int, default=None, metavar="N",
                        help="random buildings in the area (with --area-size; they hide the ground and block "
                        "flight) (default: 0)")
    search.add_argument("--prior-map", default=None, metavar="FILE",
                        help="relative likelihood of a person over the area, row 0 north: a CSV table of numbers "
                        ">= 0 or a PNG (brighter = more likely); people are drawn from it (with --area-size)")
    search.add_argument("--obstacles", default="none", choices=["none", "buildings"],
                        help="paper's field: a 4x4x26 m tower and a 4x4x13 m block that block flight and hide the "
                        "ground (default: %(default)s)")
    search.add_argument("--people-region", default="all", choices=["all", "lower_half"],
                        help="paper's field: people anywhere, or only at y < 0 (the paper's Fig. 9 case; "
                        "default: %(default)s)")
    search.add_argument("--budget", type=float, default=None, metavar="S",
                        help="flight time of each UAV [s] (default: 150 on the paper's field; with --area-size, "
                        "1.25 x one lawnmower pass at the detector's best altitude, shared among the UAVs)")
    search.add_argument("--speed", type=float, default=None, metavar="M_S",
                        help="flight speed [m/s] (default: 5 on the paper's field, 10 with --area-size)")
    search.add_argument("--image-rate", type=float, default=None, metavar="HZ",
                        help="camera rate [1/s] (default: 0.15 on the paper's field, 1 with --area-size)")
    search.add_argument("--start", type=float, nargs=3, metavar=("X", "Y", "Z"), default=None,
                        help="take-off pose [m] (default: 10 0 7 on the paper's field, whose centre is 0 0; "
                        "the south-west corner at 30 m with --area-size)")
    search.add_argument("--fov", type=float, nargs=2, metavar=("X_DEG", "Y_DEG"), default=None,
                        help="--map gp: camera field of view [degrees], each in (0, 180) (default: 45 60)")
    search.add_argument("--altitude-limits", type=float, nargs=2, metavar=("MIN", "MAX"), default=None,
                        help="--map gp: flight altitude limits [m] (default: 2 26)")
    search.add_argument("--clutter", type=float, default=None,
                        help="--map gp: mean clutter false positives per image [1/image] (default: 0)")
    search.add_argument("--diagonal", action="store_true", default=None,
                        help="--map gp: fast per-cell (diagonal) Kalman map instead of the full 1600x1600 covariance")
    search.add_argument("--no-gif", action="store_true", default=None, help="--map gp: skip the animated GIF (faster)")
    search.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    search.add_argument("--out", default="search_out", help="output directory (default: %(default)s)")


def output_file(path: str, option: str, example: str) -> Path:
    """An output file the user named: not a directory; its missing parent folders are created.
    path: the file; option: the command-line option that named it (for errors); example: a file
    name to suggest when path is a folder."""
    path = Path(path)
    if path.is_dir():
        raise AttendInputError(f"{option} {path}: is a directory; expected a file name, e.g. {path / example}")
    _require_folders(path.parent, option, path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def _require_folders(folder: Path, option: str, target: Path) -> None:
    """Every existing part of ``folder`` must be a folder, not a file."""
    for part in (folder, *folder.parents):
        if part.exists():
            if not part.is_dir():
                raise AttendInputError(f"{option} {target}: {part} is a file; expected a folder there")
            return


def _output_directory(path: str, option: str) -> Path:
    """An output directory the user named: created with its parents, and writable."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise AttendInputError(f"{option} {path}: is a file; expected a directory")
    _require_folders(path.parent, option, path)
    path.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryFile(dir=path):
        pass  # raises an OSError naming the folder when it is not writable
    return path


#: The library's argument names in search errors -> the option of ``attend search`` that sets them.
SEARCH_OPTION_OF = {"start_pose_m": "--start", "n_people": "--people", "people": "--people", "uavs": "--uavs",
                    "n_uavs": "--uavs", "area_m": "--area-size", "area_size_m": "--area-size",
                    "cell_size_m": "--cell-size", "budget_s": "--budget", "speed_m_s": "--speed",
                    "image_rate_hz": "--image-rate", "n_buildings": "--buildings", "buildings": "--buildings",
                    "prior_map": "--prior-map", "altitude_limits_m": "--altitude-limits", "fov_x_deg": "--fov",
                    "fov_y_deg": "--fov", "clutter_rate_per_image": "--clutter"}


def _command_search(args) -> int:
    from attend.action.errors import ActionInputError

    _output_directory(args.out, "--out")
    _check_search_options(args)
    try:
        return _fly_search_command(args)
    except ActionInputError as error:
        name, _, rest = str(error).partition(":")
        if name in SEARCH_OPTION_OF and rest:
            raise AttendInputError(f"{SEARCH_OPTION_OF[name]}:{rest}") from None
        raise


def _fly_search_command(args) -> int:
    started = time.perf_counter()
    if args.map == "gp":
        from attend.action.paper_search import run_search

        paths = run_search(
            planner=args.planner, seed=args.seed, obstacles=args.obstacles, people_region=args.people_region,
            budget_s=args.budget or 150.0, out_dir=args.out, n_people=args.people or 7,
            start_pose_m=tuple(args.start or (10.0, 0.0, 7.0)), fov_deg=tuple(args.fov or (45.0, 60.0)),
            altitude_limits_m=tuple(args.altitude_limits or (2.0, 26.0)), speed_m_s=args.speed or 5.0,
            clutter_rate_per_image=args.clutter or 0.0, diagonal=bool(args.diagonal), gif=not args.no_gif,
            progress=not args.no_progress,
        )
    else:
        from attend.action.search_run import run_probability_search

        prior_map = None
        if args.prior_map is not None:
            from attend.io.prior_maps import read_prior_map

            try:
                prior_map = read_prior_map(args.prior_map)
            except AttendInputError as error:
                raise AttendInputError(f"--prior-map {error}") from None
        paths = run_probability_search(
            planner=args.planner, seed=args.seed, out_dir=args.out, progress=not args.no_progress,
            area_size_m=args.area_size, cell_size_m=args.cell_size, people=args.people, uavs=args.uavs or 1,
            buildings=args.buildings or 0, obstacles=args.obstacles, people_region=args.people_region,
            prior_map=prior_map, budget_s=args.budget, speed_m_s=args.speed, image_rate_hz=args.image_rate,
            start_pose_m=None if args.start is None else tuple(args.start),
        )
        summary = json.loads(Path(paths["metrics"]).read_text())["summary"]
        found_all = summary["time_to_find_all_s"]
        print(f"found {summary['people_found']} of {summary['people_total']} people"
              + (f", all by {found_all:.0f} s" if found_all is not None else "")
              + f"; {summary['false_targets']} false targets; P(all found) = {summary['p_all_found_end']:.2f}")
    print(f"mission with the {args.planner} planner done in {time.perf_counter() - started:.1f} s")
    for name, path in paths.items():
        print(f"  {name:13s} -> {path}")
    return 0


def _check_search_options(args) -> None:
    """Options of ``attend search`` that do not fit the chosen map, and numbers out of range,
    as one-line errors naming the option."""
    from attend.action.planners import PLANNERS
    from attend.action.search_run import SEARCH_PLANNERS

    given = {dest for dest in (*GP_ONLY_OPTIONS, *PROBABILITY_ONLY_OPTIONS) if getattr(args, dest) is not None}
    if args.map == "gp":
        wrong = [PROBABILITY_ONLY_OPTIONS[d] for d in PROBABILITY_ONLY_OPTIONS if d in given]
        if wrong:
            raise AttendInputError(f"{wrong[0]}: only with the probability map (drop --map gp)")
        if args.planner not in PLANNERS:
            raise AttendInputError(f"--planner: expected one of {sorted(PLANNERS)} with --map gp, got {args.planner!r}")
    else:
        wrong = [GP_ONLY_OPTIONS[d] for d in GP_ONLY_OPTIONS if d in given]
        if wrong:
            raise AttendInputError(f"{wrong[0]}: only with --map gp (the paper's Gaussian map)")
        if args.planner not in SEARCH_PLANNERS:
            raise AttendInputError(f"--planner: expected one of {sorted(SEARCH_PLANNERS)} on the probability map "
                                   f"(the others fly with --map gp), got {args.planner!r}")
    for option, value in (("--area-size", args.area_size), ("--cell-size", args.cell_size), ("--budget", args.budget),
                          ("--speed", args.speed), ("--image-rate", args.image_rate)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise AttendInputError(f"{option}: expected a number > 0, got {value:g}")
    for option, value, least in (("--people", args.people, 1), ("--uavs", args.uavs, 1), ("--buildings", args.buildings, 0)):
        if value is not None and value < least:
            raise AttendInputError(f"{option}: expected a whole number >= {least}, got {value}")
    if args.area_size is not None:
        cell = args.cell_size if args.cell_size is not None else 1.0
        if cell > args.area_size:
            raise AttendInputError(f"--cell-size: expected a cell no larger than --area-size {args.area_size:g} m, got {cell:g}")
        cells = round(args.area_size / cell) ** 2
        if args.people is not None and args.people > cells:
            raise AttendInputError(f"--people: expected at most the {cells} cells of the area, got {args.people}")
    if args.start is not None and not all(math.isfinite(v) for v in args.start):
        raise AttendInputError(f"--start: expected three finite numbers X Y Z [m], got {args.start}")


def _command_estimate(args) -> int:
    from attend import io, workflows
    from attend.data import demo_paths

    if args.demo:
        model_path, log_path = demo_paths()
    elif args.model and args.log:
        model_path, log_path = args.model, args.log
    else:
        raise AttendInputError("estimate: expected MODEL and LOG paths (or --demo)")
    model = io.read_model(model_path)
    log = io.read_log(log_path, model, gaps=True)  # a CSV, or a ROS bag ([log.columns])
    if not model.nonlinear:
        model.system.check()
    output_file(args.out, "--out", "estimates.csv")
    if args.plot:
        output_file(args.plot, "--plot", "estimates.png")
    started = time.perf_counter()
    gaps = None
    with progress_bars(not args.no_progress and sys.stderr.isatty()):
        if workflows.has_gaps(model, log):  # missing values, skipped or jittered time stamps
            observer, estimate, gaps = workflows.estimate_with_gaps(model, log)
        else:
            observer, estimate = workflows.estimate_from_files(model, log)
    elapsed = time.perf_counter() - started
    choice = getattr(observer, "input_width_choice", None)  # the unknown inputs' width, chosen from the log
    _warn_if_spread_implausible(model, log, estimate, None if choice is None else choice.width,
                                None if choice is None else choice.noise_scale)
    out = io.write_estimates(args.out, log, model.system, estimate)
    duration = log.time[-1] - log.time[0] + log.dt
    print(f"estimated {len(log.time)} samples ({duration:.2f} s of log) in {elapsed * 1e3:.1f} ms -> {out}")
    print("  " + _describe_estimator(observer))
    if log.origin:  # a bag: its grid, resampling rule and time stamps
        print("  " + log.origin)
    if gaps:
        print("  " + gaps)
    if model.nonlinear and not model.system.vectorized and model.dem_backend != "jax" and elapsed > 5.0:
        from attend.io.python_model import takes_columns

        if takes_columns(model.system, model.initial_state, model.inputs):
            print(f"  hint: f and g in {model.python_path} also work on (n, K) columns; [model] vectorized = true "
                  "lets the estimator evaluate many points per call (2-4x faster)")
    if args.plot:
        from attend.plotting import plot_estimates

        measured = [j for j, spec in enumerate(model.inputs) if spec.known]
        path = plot_estimates(args.plot, log.time, model.system, estimate, measured, DEMO_UNITS if args.demo else None)
        print(f"  figure -> {path}")
    if choice is not None and not choice.flat:  # how, once everything is written (a flat likelihood was a warning)
        print(f"attend: {choice.describe()}", file=sys.stderr)
    return 0


def _warn_if_spread_implausible(model, log, estimate, input_kernel_width=None, noise_scale=None) -> None:
    """One warning per state or unknown input whose estimate swings far beyond what the data and the
    model support (:mod:`attend.perception.spread_check`), whatever the estimator; input_kernel_width:
    the inputs' prior width chosen from the log when the file gives none [s]; noise_scale: lambda* there."""
    import numpy as np

    from attend.models.linear import ModelWarning
    from attend.perception.spread_check import check_estimate, describe

    with np.errstate(all="ignore"):
        findings = check_estimate(model, log, estimate, input_kernel_width=input_kernel_width,
                                  noise_scale=noise_scale)
    for finding in findings:
        warnings.warn(f"{model.path}: {describe(finding)}", ModelWarning, stacklevel=2)


def _describe_estimator(estimator) -> str:
    """One line: which estimator ran, with its settings."""
    import numpy as np

    from attend.perception.dem import DEMObserver
    from attend.perception.file_estimators import NonlinearFileEstimator
    from attend.perception.kalman import NOISE_WHITE_FLOOR

    if isinstance(estimator, NonlinearFileEstimator):
        model = estimator.model
        if estimator.method == "dem":
            chosen = " (automatic)" if estimator.automatic_order else ""
            input_width = (f", input prior width {estimator.input_kernel_width:g} s" if estimator.system.n_inputs
                           and not estimator.known.all() else "")
            mode = ("path mode (one trajectory for the whole log)" if model.dem_states == "path"
                    else f"D-step, delay {estimator.dem().delay} samples")
            return (f"method dem (nonlinear DEM, model {model.python_path}): embedding order p = "
                    f"{estimator.embedding_order}{chosen}, input order d = {model.input_order}, kernel width "
                    f"{model.kernel_width:g} s{input_width}, {mode}; "
                    f"[observer] method = \"ukf\" (the default) runs the unscented Kalman smoother")
        unknown = estimator.system.n_inputs and not estimator.known.all()
        how = ", chosen from the log" if estimator.input_width_choice is not None else ""
        inputs = (f"; unknown inputs as random walks matching their prior (width {estimator.input_kernel_width:g} s"
                  f"{how})" if unknown else "")
        start = ("[observer] initial_state" if model.initial_state is not None
                 else "the best of a search over x[0] (several starts, ranked by how well they explain the log)")
        return (f"method ukf (unscented Kalman smoother, the default for nonlinear models; model "
                f"{model.python_path}): white-noise model with the per-sample variance of the coloured noise "
                f"(kernel width {model.kernel_width:g} s){inputs}; start: {start}; std: the smoother's error "
                "spread under the coloured noise (exact through its linearisation, no draws); "
                "[observer] method = \"dem\" runs the nonlinear DEM")
    if isinstance(estimator, DEMObserver):
        analysis = estimator.analysis()
        chosen = " (automatic)" if analysis.automatic else ""
        return (f"method dem (DEM observer): embedding order p = {estimator.embedding_order}{chosen}, input order "
                f"d = {estimator.input_order}, kernel widths {estimator.process_kernel_width:g} s (process), "
                f"{estimator.sensor_kernel_width:g} s (sensor), spectral radius {analysis.spectral_radius:.6f}, "
                f"delay of the online observer: {estimator.delay} samples")
    orders = estimator.noise_orders
    noise = ", ".join(f"{name} {'white' if order == 0 else f'order {order}'}"
                      for name, order in orders.items() if order is not None)
    if estimator.initial_state is None and estimator.initial_state_std is None:
        start = ("initial state unknown (a broad prior; if the log starts from a known state, e.g. at rest, "
                 "set [observer] initial_state: it can matter a lot when the process noise is small)")
    elif estimator.initial_state_std is None or not np.any(estimator.initial_state_std):
        start = "initial state known ([observer] initial_state)"
    else:
        start = "initial state from [observer] initial_state and initial_state_std"
    inputs = ""
    if estimator.input_kernel_width is not None:
        how = "chosen from the log" if estimator.input_width_choice is not None else "[observer] input_kernel_width"
        if estimator.input_width_choice is not None and estimator.input_width_choice.flat:
            how = "the process width: the log does not decide it"
        inputs = f", input prior width {estimator.input_kernel_width:g} s ({how})"
    if estimator.noise_white_floor != NOISE_WHITE_FLOOR:
        noise += f"; white part of w and z {estimator.noise_white_floor:g} of their variance (chosen from the log)"
    return (f"method kalman (Kalman smoother under the coloured-noise model): process width "
            f"{estimator.process_kernel_width:g} s, sensor width {estimator.sensor_kernel_width:g} s{inputs}; "
            f"noise models: {noise}; {start}; [observer] method = \"dem\" selects the paper's DEM observer")


def _command_reproduce(args) -> int:
    from attend import experiments, report

    available = experiments.available()
    if args.name == "list":
        for name, description in available.items():
            print(f"{name:16s} {description}")
        return 0
    names = list(available) if args.name == "all" else [args.name]
    for name in names:
        if name not in available:
            raise AttendInputError(
                f"reproduce: unknown experiment {name!r}; expected one of {', '.join(available)} or 'all'"
            )
    out = _output_directory(args.out, "--out")
    quick = not args.full
    code_hash = report.source_hash()
    results, failures = [], []
    started_all = time.perf_counter()
    for name in names:
        key = report.cache_key(name, quick, code_hash)
        cached = None if args.force else report.cached_result(out, name, key)
        if cached is not None:
            print(f"== {name}: cached ({out / (name + '.json')}; --force reruns it)")
            results.append(cached)
            continue
        print(f"== {name}: {available[name]}", flush=True)
        started = time.perf_counter()
        module = experiments.load(name)
        try:
            result = _run_experiment(module, quick, out, not args.no_progress, args.cluster)
        except Exception as error:  # one failing experiment must not hide the others' results
            if len(names) == 1 or args.debug or (isinstance(error, OSError) and _user_path_problem(error)):
                raise  # a full disk or a read-only folder stops every experiment
            bad_input = isinstance(error, AttendInputError)
            failures.append((name, bad_input))
            if bad_input:
                print(f"attend: error: experiment {name}: {_one_line(error)}", file=sys.stderr)
            else:
                _report_internal(error, f"experiment {name} failed: ")
            continue
        result.settings.setdefault("quick", quick)
        result.runtime_s = time.perf_counter() - started
        result.cache_key = key
        path = result.write(out)
        results.append(result)
        print(result.table())
        print(f"-> {path} ({result.runtime_s:.1f} s)\n", flush=True)
    if args.name == "all" or args.report:
        command = "attend " + " ".join(sys.argv[1:]) if sys.argv[1:] else "attend reproduce all"
        page = report.write_report(out, results, available, command, time.perf_counter() - started_all)
        print(f"report -> {page} ({time.perf_counter() - started_all:.1f} s in all)")
    if failures:
        print(f"attend: {len(failures)} experiment(s) failed: {', '.join(name for name, _ in failures)}",
              file=sys.stderr)
        return 2 if all(bad_input for _, bad_input in failures) else 1
    return 0


def _run_experiment(module, quick: bool, out: Path, progress: bool, cluster):
    """Run one experiment module (the contract of :mod:`attend.experiments`): ``run`` computes,
    then ``plot(result, out)`` draws the figures into ``out``. quick: quick settings; out: the output folder; progress: progress bars; cluster: a Dask
    scheduler address for the modules whose ``run`` takes ``cluster`` (None: run here)."""
    options = dict(quick=quick, progress=progress)
    if cluster is not None and "cluster" in inspect.signature(module.run).parameters:
        options["cluster"] = cluster
    result = module.run(**options)
    result.figures = [str(figure) for figure in module.plot(result, out)]
    return result


def _command_report(args) -> int:
    from attend import experiments, report

    folder = Path(args.dir)
    if not folder.is_dir():
        raise AttendInputError(f"report {folder}: no such folder; expected the --out folder of 'attend reproduce'")
    known = experiments.available()
    for name in args.names:
        if name not in known:
            raise AttendInputError(f"report: unknown experiment {name!r}; expected one of {', '.join(known)}")
    started = time.perf_counter()
    results = report.rebuild(folder, args.names or None)
    command = "attend " + " ".join(sys.argv[1:]) if sys.argv[1:] else f"attend report {folder}"
    page = report.write_report(folder, results, known, command, time.perf_counter() - started)
    for result in results:
        print(f"{result.experiment}: {', '.join(result.figures) or 'no figures'}")
    print(f"report -> {page} ({time.perf_counter() - started:.1f} s)")
    return 0


_USER_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EISDIR,
                errno.ENOTDIR, errno.ENOENT, errno.EEXIST, errno.ENAMETOOLONG}
_ERRNO_MEANING = {
    errno.ENOSPC: "no space left on the device (disk full)",
    errno.EDQUOT: "disk quota exceeded",
    errno.EROFS: "read-only file system; expected a writable location",
    errno.EACCES: "permission denied; expected a location you may write to",
    errno.EPERM: "operation not permitted",
    errno.EISDIR: "is a directory; expected a file",
    errno.ENOTDIR: "a part of the path is a file; expected folders",
    errno.ENOENT: "does not exist, or cannot be created there",
    errno.EEXIST: "already exists",
    errno.ENAMETOOLONG: "the name is too long",
}
_PACKAGE = Path(__file__).resolve().parent


def _user_path_problem(error: OSError) -> bool:
    """An OSError about the user's files or disk (not one inside attend's own package)."""
    if error.errno not in _USER_ERRNOS:
        return False
    if error.filename is None:
        return error.errno in (errno.ENOSPC, errno.EDQUOT, errno.EROFS)
    try:
        return _PACKAGE not in Path(error.filename).resolve().parents
    except (OSError, RuntimeError, TypeError, ValueError):
        return True


def _describe_os_error(error: OSError) -> str:
    meaning = _ERRNO_MEANING.get(error.errno, error.strerror or str(error))
    return f"{error.filename}: {meaning}" if error.filename is not None else meaning


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def main(argv=None) -> int:
    """Run the command line with the arguments ``argv`` (default: sys.argv[1:]); returns the exit
    status (0 done, 1 internal error, 2 bad input)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = _build_parser(argv)
    args = parser.parse_args(argv)
    debug = getattr(args, "debug", False)
    if args.command is None:
        parser.print_help()
        return 0
    handlers = {"estimate": _command_estimate, "reproduce": _command_reproduce, "search": _command_search,
                "identify": command_identify, "report": _command_report, "plan": _command_plan}
    args.debug = debug
    with warnings.catch_warnings():  # the command's warning style, restored when it returns
        warnings.simplefilter("default")
        warnings.showwarning = _show_warning
        return _run_handler(handlers[args.command], args, debug)


def _command_plan(args) -> int:
    from attend.cli_plan import command_plan

    return command_plan(args)


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Warnings of a command: one line ``attend: warning: ...`` on standard error."""
    print(f"attend: warning: {_one_line(message)}", file=sys.stderr if file is None else file)


def _run_handler(handler, args, debug: bool) -> int:
    """Run one command, mapping errors to exit statuses (0 done, 1 internal, 2 bad input)."""
    try:
        return handler(args)
    except AttendInputError as error:
        if debug:
            raise
        print(f"attend: error: {_one_line(error)}", file=sys.stderr)
        return 2
    except OSError as error:
        if debug:
            raise
        if _user_path_problem(error):
            print(f"attend: error: {_one_line(_describe_os_error(error))}", file=sys.stderr)
            return 2
        _report_internal(error)
        return 1
    except KeyboardInterrupt:
        print("attend: interrupted", file=sys.stderr)
        return 130
    except Exception as error:  # a bug in attend, not the user's input
        if debug:
            raise
        _report_internal(error)
        return 1


def _report_internal(error: BaseException, context: str = "") -> None:
    print(f"attend: internal error: {context}{type(error).__name__}: {_one_line(error)}; please report it "
          "(run with --debug for the traceback)", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
