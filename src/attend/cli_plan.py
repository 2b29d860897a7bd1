"""``attend plan``: the next flight plan of a search mission on your own ground."""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

from attend._validation import AttendInputError

EPILOG_PLAN = """\
try it:
  attend plan --example ex && attend plan ex/mission.toml --simulate --seed 1 --out ex/dry

the loop a team runs in the field:
  attend plan mission.toml --out plan1                       first plan, from the homes
  (fly plan1/plan.plan, collect images.csv and detections.csv)
  attend plan mission.toml --images images.csv --detections detections.csv --out plan2
  (every call rebuilds the map from the whole logs: a laptop can die between flights)

a dry run with the built-in simulator (people placed by the seed):
  attend plan mission.toml --simulate --seed 3 --out dry
  attend plan mission.toml --simulate --seed 3 --planner lawnmower --out dry_lawnmower

files:
  mission.toml     [area] boundary (GeoJSON, KML or QGroundControl .plan), exclude, cell_size_m;
                   [search] people, flight_time_s, prior_map; [[uav]] name, home [lon, lat],
                   speed_m_s, altitude_m [min, max], camera_fov_deg [across, along],
                   image_interval_s; [detector] altitude_m, detection_probability,
                   false_detections_per_image, position_std_m (docs/mission.md)
  images.csv       t_s,uav,lon,lat,alt_m,yaw_deg
  detections.csv   t_s,uav,lon,lat,score
  out: plan.csv (uav,seq,t_s,lon,lat,alt_m), plan.plan, plan.waypoints, plan.geojson,
       targets.csv (lon,lat,probability,detections), map.png, map.tif, summary.json
Units: seconds, metres, degrees (lon/lat WGS84; altitudes above home)."""


def add_plan(add_command) -> None:
    plan = add_command(
        "plan",
        help="the next flight plan of a search on your own ground (area file, logs in, plan out)",
        description="Read a mission file (the area, the UAVs, the detector) and the images and detections flown "
        "so far, rebuild the map of P(person), and write every UAV's next waypoints (CSV, QGroundControl .plan, "
        "WPL, GeoJSON), the likely people (targets.csv), the map (PNG, GeoTIFF) and a summary.",
        epilog=EPILOG_PLAN,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    plan.add_argument("mission", nargs="?", help="mission file (TOML); 'attend plan --example FOLDER' writes one")
    plan.add_argument("--example", metavar="FOLDER",
                      help="write an example mission (a 400 m concave area near Delft with a pond and a no-fly "
                      "zone, one UAV, the detector calibration of docs/mission.md) into FOLDER and stop")
    plan.add_argument("--out", help="output folder (created if missing; replaced files are written "
                      "atomically: on an error nothing in it changes)")
    plan.add_argument("--images", help="images.csv: t_s,uav,lon,lat,alt_m,yaw_deg (default: nothing flown yet)")
    plan.add_argument("--detections", help="detections.csv: t_s,uav,lon,lat,score (needs --images)")
    plan.add_argument("--planner", choices=("efe", "lawnmower"),
                      help="efe: expected free energy per second (default, or the mission's [planner] name); "
                      "lawnmower: a boustrophedon over the area at one altitude (the baseline)")
    plan.add_argument("--horizon", type=float, metavar="S",
                      help="how far ahead each plan reaches [s] (default: the mission's [planner] horizon_s, 120 s)")
    plan.add_argument("--simulate", action="store_true",
                      help="dry run: fly the whole mission with the built-in simulator and the mission's detector, "
                      "write the logs (images.csv, detections.csv, people.csv) and the outputs")
    plan.add_argument("--seed", type=int, default=0, help="with --simulate: places the people (default: %(default)s)")
    plan.add_argument("--replan", type=float, default=30.0, metavar="S",
                      help="with --simulate: time between replans [s] (default: %(default)s)")
    plan.add_argument("--no-plot", action="store_true", help="skip map.png (faster)")


def command_plan(args) -> int:
    """Run ``attend plan`` (module docstring)."""
    from attend.action.mission import Mission, write_outputs

    started = time.perf_counter()
    if args.example:
        from attend.action.mission.examples import write_example_mission

        path = write_example_mission(args.example, seed=1, size_m=400.0, lon_lat=(4.3752, 51.9850))
        print(f"wrote {path} with area.geojson and no_fly.geojson; next: attend plan {path} --out plan1")
        return 0
    if not args.mission:
        raise AttendInputError("mission: expected a mission file (TOML); 'attend plan --example FOLDER' writes one")
    if not args.out:
        raise AttendInputError("--out: expected the output folder")
    if args.detections and not args.images:
        raise AttendInputError("--detections: expected --images too (each detection belongs to an image)")
    if args.horizon is not None and not (math.isfinite(args.horizon) and args.horizon > 0):
        raise AttendInputError(f"--horizon: expected a time > 0 s, got {args.horizon!r}")
    if not (math.isfinite(args.replan) and args.replan > 0):
        raise AttendInputError(f"--replan: expected a time > 0 s, got {args.replan!r}")
    if args.simulate and (args.images or args.detections):
        raise AttendInputError("--simulate: flies its own logs; expected no --images or --detections")
    if Path(args.out).exists() and not Path(args.out).is_dir():
        raise AttendInputError(f"--out: {args.out} is a file; expected a folder")
    if args.simulate:
        return _simulate(Mission.from_file(args.mission), args, started)
    from attend.action.mission.map_painter import MapPainter

    painter = MapPainter()  # loads matplotlib and rasterio in another process meanwhile
    try:
        mission = Mission.from_file(args.mission)
        mission.read_logs(args.images, args.detections)
        plans = mission.plan(args.planner, args.horizon)
        write_outputs(mission, plans, args.out, plot=not args.no_plot, painter=painter)
    finally:
        painter.close()
    summary = mission.summary(plans)
    waypoints = sum(len(p.waypoints) for p in plans)
    print(f"{summary['images']} images, {summary['detections']} detections fused; {summary['targets']} likely "
          f"people, P(all found) = {summary['p_all_found']:.2f}, {100 * summary['area_covered_fraction']:.0f} % of "
          f"the area seen")
    print(f"plan: {waypoints} waypoints for {len(plans)} UAV(s) ({summary['planner']}, {summary['planner_time_s']:.2f} s); "
          f"wrote {args.out}/ in {time.perf_counter() - started:.1f} s")
    return 0


def _simulate(mission, args, started: float) -> int:
    from attend.action.mission import write_outputs
    from attend.action.mission.flight_logs import write_flight_logs
    from attend.action.mission.simulate import simulate_mission

    result = simulate_mission(mission, args.seed, planner=args.planner, replan_s=args.replan)
    plans = mission.plan(args.planner, args.horizon)
    out = Path(args.out)
    write_outputs(mission, plans, out, plot=not args.no_plot)
    names = [u.name for u in mission.config.uavs]
    write_flight_logs(mission.logs, names, out / "images.csv", out / "detections.csv")
    lon, lat = mission.ground.frame.to_lon_lat(result.people_m[:, 0], result.people_m[:, 1])
    lines = ["lon,lat,found_s"] + [f"{a:.9f},{b:.9f},{'' if not math.isfinite(t) else f'{t:.1f}'}"
                                   for a, b, t in zip(lon, lat, result.found_times_s)]
    (out / "people.csv").write_text("\n".join(lines) + "\n")
    found = int(sum(math.isfinite(t) for t in result.found_times_s))
    t90 = result.time_to_fraction_s(0.9)
    summary_path = out / "summary.json"
    summary = json.loads(summary_path.read_text())
    summary["simulation"] = {"seed": args.seed, "people": len(result.people_m), "found": found,
                             "false_targets": result.false_targets,
                             "time_to_90_percent_s": None if not math.isfinite(t90) else t90,
                             "found_radius_m": result.found_radius_m, "replans": result.replans}
    summary_path.write_text(json.dumps(summary, indent=2) + "\n")
    print(f"simulated {mission.config.flight_time_s:.0f} s with {len(names)} UAV(s): found {found} of "
          f"{len(result.people_m)} people (a target within {result.found_radius_m:.1f} m), "
          f"{result.false_targets} false targets, 90 % found at "
          f"{'never' if not math.isfinite(t90) else f'{t90:.0f} s'}; wrote {args.out}/ in "
          f"{time.perf_counter() - started:.1f} s")
    return 0
