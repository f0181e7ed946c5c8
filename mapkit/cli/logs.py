"""Laser-log commands: ``mapkit simulate``, ``mapkit build``, ``mapkit turn-error`` and
``mapkit log-info``."""

from __future__ import annotations

import sys
from typing import Any

import click

from mapkit.cli.options import (
    InputFile,
    check_outputs,
    echo_json,
    err,
    force_option,
    json_option,
    output_option,
    plural,
)


def _floats(text: str, n: tuple[int, ...], what: str) -> tuple[float, ...]:
    try:
        vals = tuple(float(v) for v in text.replace(",", " ").split())
    except ValueError:
        raise click.BadParameter(f"{what}: expected numbers, got {text!r}") from None
    if len(vals) not in n:
        raise click.BadParameter(
            f"{what}: expected {' or '.join(map(str, n))} numbers, got {text!r}"
        )
    return vals


def _check_output(path: str, force: bool) -> None:
    check_outputs([path], force)


@click.command()
@click.argument("map_file", required=False, type=InputFile())
@output_option("The .2d log to write.", required=True)
@click.option("--sample", help="Use a bundled sample map by name (e.g. office).")
@click.option(
    "--version",
    "log_version",
    type=click.IntRange(1, 4),
    default=4,
    show_default=True,
    help="Logger version to write (1 to 4).",
)
@click.option(
    "--waypoints", help="Points to visit, 'x,y x,y ...' in mm (default: the map's goals)."
)
@click.option("--start", "start", help="Start pose 'x,y[,th]' (default: RobotHome, else Dock).")
@click.option("--loop", is_flag=True, help="Return to the start and write loop: start/stop tags.")
@click.option(
    "--laps",
    type=click.IntRange(1, 1000),
    default=1,
    show_default=True,
    help="Drive the route this many times.",
)
@click.option(
    "--fov",
    type=click.FloatRange(1, 360),
    default=180.0,
    show_default=True,
    help="Laser field of view (degrees).",
)
@click.option(
    "--readings",
    type=click.IntRange(2, 10000),
    default=361,
    show_default=True,
    help="Readings per sweep.",
)
@click.option(
    "--max-range",
    type=click.FloatRange(100),
    default=16000.0,
    show_default=True,
    help="Laser range (mm).",
)
@click.option(
    "--range-noise",
    type=click.FloatRange(0),
    default=10.0,
    show_default=True,
    help="Range noise, standard deviation (mm).",
)
@click.option(
    "--laser-pose", default="160,0,0", show_default=True, help="Laser mount on the robot 'x,y,th'."
)
@click.option(
    "--second-laser",
    metavar="X,Y,TH",
    help="Mount of a second laser of the same kind, e.g. a rear one '-200,0,180' (version 4).",
)
@click.option(
    "--trans-error",
    type=click.FloatRange(0),
    default=0.01,
    show_default=True,
    help="Odometry distance error (fraction of each step, random).",
)
@click.option(
    "--rot-error",
    type=click.FloatRange(0),
    default=0.02,
    show_default=True,
    help="Odometry turn error (fraction of each turn, random).",
)
@click.option(
    "--drift",
    type=float,
    default=0.05,
    show_default=True,
    help="Systematic heading drift (degrees per metre).",
)
@click.option(
    "--dist-step",
    type=click.FloatRange(1),
    default=300.0,
    show_default=True,
    help="Log a scan after this many mm ...",
)
@click.option(
    "--deg-step",
    type=click.FloatRange(0.1),
    default=25.0,
    show_default=True,
    help="... or this many degrees of turning.",
)
@click.option("--raw-ranges", is_flag=True, help="Also write raw ranges (sick1: lines).")
@click.option(
    "--odometry-origin",
    type=click.Choice(["start", "zero"]),
    default="start",
    show_default=True,
    help="Odometry starts at the true start pose, or at 0 0 0.",
)
@click.option(
    "--goal-names",
    type=click.Choice(["map", "aria"]),
    default="map",
    show_default=True,
    help="Goal events named after the map's goals, or goal1, goal2... as ARIA does.",
)
@click.option(
    "--scale-error",
    type=click.FloatRange(-0.4, 0.4),
    default=0.0,
    show_default=True,
    help="Systematic odometry distance error (fraction, e.g. 0.01).",
)
@click.option(
    "--turn-slip",
    type=click.FloatRange(-0.4, 0.4),
    default=0.0,
    show_default=True,
    help="Extra turn odometry reports while turning on the spot (fraction).",
)
@click.option(
    "--scan-lag",
    type=click.FloatRange(-1.0, 1.0),
    default=0.0,
    show_default=True,
    help="How much older (s) each sweep is than the pose logged with it (negative: newer).",
)
@click.option(
    "--scan-lag-jitter",
    type=click.FloatRange(0.0, 1.0),
    default=0.0,
    show_default=True,
    help="Each sweep's lag varies by up to this much (s) either way.",
)
@click.option(
    "--outliers",
    type=click.FloatRange(0, 0.9),
    default=0.0,
    show_default=True,
    help="Fraction of spurious (short) laser readings.",
)
@click.option(
    "--people",
    type=click.IntRange(0, 100),
    default=0,
    show_default=True,
    help="People walking about in the laser's view.",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")
@click.option("--no-truth", is_flag=True, help="Do not write the NAME.truth.tsv sidecar.")
@force_option
def simulate(
    map_file: str | None,
    output: str,
    sample: str | None,
    log_version: int,
    waypoints: str | None,
    start: str | None,
    loop: bool,
    laps: int,
    fov: float,
    readings: int,
    max_range: float,
    range_noise: float,
    laser_pose: str,
    trans_error: float,
    rot_error: float,
    drift: float,
    dist_step: float,
    deg_step: float,
    raw_ranges: bool,
    odometry_origin: str,
    goal_names: str,
    scale_error: float,
    turn_slip: float,
    scan_lag: float,
    scan_lag_jitter: float,
    second_laser: str | None,
    outliers: float,
    people: int,
    seed: int,
    no_truth: bool,
    force: bool,
) -> None:
    """Drive a simulated robot through MAP_FILE and write the laser log it would record.

    The laser sees the map's lines and points; odometry drifts. The true pose of every scan goes
    to NAME.truth.tsv beside the log (robot: and robotGlobal: hold odometry, as on a robot being
    mapped).

    \b
    Examples:
      mapkit simulate office.map -o office.2d --loop
      mapkit simulate office.map -o noisy.2d --loop --scale-error 0.01 --turn-slip 0.03 --outliers 0.02 --people 3
      mapkit simulate --sample building -o b.2d --version 3 --waypoints "5000,12000 55000,12000"
    """  # noqa: E501 (an example command line, shown whole in --help)
    from mapkit.formats.map import load
    from mapkit.samples import sample_path
    from mapkit.simulate import simulate_log

    if (map_file is None) == (sample is None):
        raise click.UsageError("give a MAP_FILE or --sample NAME")
    _check_output(output, force)
    wps = None
    if waypoints:
        wps = [_floats(w, (2,), "--waypoints") for w in waypoints.split()]
    st = _floats(start, (2, 3), "--start") if start else None
    lp = _floats(laser_pose, (3,), "--laser-pose")
    second = _floats(second_laser, (3,), "--second-laser") if second_laser else None
    m = load(str(sample_path(sample)) if sample else map_file)  # type: ignore[arg-type]
    sim = simulate_log(
        m,
        waypoints=wps,
        start=st,
        loop=loop,
        laps=laps,
        version=log_version,
        fov=fov,
        readings=readings,
        max_range=max_range,
        range_noise=range_noise,
        laser_pose=lp,
        translation_error=trans_error,
        rotation_error=rot_error,
        drift=drift,
        dist_step=dist_step,
        deg_step=deg_step,
        raw_ranges=raw_ranges,
        odometry_origin=odometry_origin,
        goal_names=goal_names,
        scale_error=scale_error,
        turn_slip=turn_slip,
        scan_lag=scan_lag,
        scan_lag_jitter=scan_lag_jitter,
        second_laser=second,
        outliers=outliers,
        people=people,
        seed=seed,
    )
    click.echo(sim.save(output, truth=not no_truth))
    if sim.skipped:
        err(f"mapkit: no path to {', '.join(sim.skipped)}: left out of the route")


def _pose_options(f: Any) -> Any:
    """``--pose`` and ``--max-range``: how ``mapkit build`` and ``mapkit turn-error`` read the
    scans."""
    f = click.option(
        "--max-range",
        type=click.FloatRange(100),
        default=16000.0,
        show_default=True,
        help="Ignore readings this far or farther (mm).",
    )(f)
    return click.option(
        "--pose",
        "pose_source",
        type=click.Choice(["robot", "robotGlobal"]),
        default="robot",
        show_default=True,
        help="Pose of each scan: odometry (robot:) or the corrected one (robotGlobal:).",
    )(f)


_tolerant_option = click.option(
    "--tolerant", is_flag=True, help="Skip bad records (and report them) instead of failing."
)


class _Bar:
    """A click progress bar on stderr, opened on the first report."""

    def __init__(self, label: str, enabled: bool) -> None:
        self.label = label
        self.enabled = enabled
        self.bar: Any = None
        self.done = 0

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        if self.bar is None:
            self.bar = click.progressbar(length=total, label=self.label, file=sys.stderr)
            self.bar.__enter__()
        self.bar.update(done - self.done)
        self.done = done

    def close(self) -> None:
        if self.bar is not None:
            self.bar.__exit__(None, None, None)
            self.bar = None


@click.command()
@click.argument("log_file", type=InputFile())
@output_option("The .map to write.", required=True)
@click.option(
    "--resolution",
    type=click.IntRange(1, 1000),
    default=20,
    show_default=True,
    help="Grid of the map's points (mm).",
)
@click.option("--no-register", is_flag=True, help="No scan matching: the raw odometry map.")
@click.option("--no-loops", is_flag=True, help="Register scans but close no loops.")
@_pose_options
@click.option(
    "--min-hits",
    type=click.IntRange(1),
    default=2,
    show_default=True,
    help="Laser hits a map point needs.",
)
@click.option("--no-lines", is_flag=True, help="Do not fit line segments.")
@_tolerant_option
@click.option(
    "--keep-all-tags",
    is_flag=True,
    help="One goal per cairn: event (default: goals of one name merged at their mean pose).",
)
@click.option(
    "--turn-error",
    type=click.FloatRange(0.0, 1.0, max_open=True),
    default=None,
    help="How far the robot's odometry errs in its turns, as a fraction of each turn (0.001: "
    "0.1 %), when known (a calibration, or several logs' odometry_turn_error in --json); "
    "default: 0.1 % unless this log's turns rule that out or its laser scatters more than "
    "16 mm, then fitted from them.",
)
@click.option(
    "--poses",
    "poses_file",
    type=click.Path(dir_okay=False),
    help="Also write the trajectory here (TSV: scanId x y th odo_x odo_y odo_th).",
)
@click.option(
    "--report",
    "report_file",
    type=click.Path(dir_okay=False),
    help="Also draw a report (PNG): trajectory, loops closed, residual per scan, how far "
    "scans moved from odometry; its figures are printed.",
)
@force_option
@json_option
def build(
    log_file: str,
    output: str,
    resolution: int,
    no_register: bool,
    no_loops: bool,
    pose_source: str,
    max_range: float,
    min_hits: int,
    no_lines: bool,
    tolerant: bool,
    keep_all_tags: bool,
    turn_error: float | None,
    poses_file: str | None,
    report_file: str | None,
    force: bool,
    as_json: bool,
) -> None:
    """Build a map from a .2d laser log, as Mapper3 did.

    Replays odometry, registers each scan against the map so far (ICP), closes loops (loop:
    tags and detected revisits, pose-graph optimisation), thins the points to the resolution,
    fits lines, turns cairn: goals into GoalWithHeading objects and the start into RobotHome.

    \b
    Examples:
      mapkit build office.2d -o office-built.map
      mapkit build office.2d -o raw.map --no-register
      mapkit build office.2d -o office.map --poses office.tsv --report office-report.png
    """
    from mapkit.build import build_map
    from mapkit.build.report import write_poses, write_report
    from mapkit.formats.map import save

    for path in (output, poses_file, report_file):
        if path is not None:
            _check_output(path, force)
    bar = _Bar("registering scans", enabled=not as_json and not no_register)
    try:
        result = build_map(
            log_file,
            resolution=resolution,
            register=not no_register,
            loop_closure=not no_loops,
            pose_source=pose_source,
            max_range=max_range,
            min_hits=min_hits,
            lines=not no_lines,
            strict=not tolerant,
            merge_goals=not keep_all_tags,
            turn_error=turn_error,
            progress=bar,
        )
    finally:
        bar.close()
    md5 = save(result.map, output)
    if poses_file is not None:
        write_poses(result, poses_file)
    figures = write_report(result, report_file) if report_file is not None else None
    s = result.summary
    if as_json:
        extra = {"poses": poses_file, "report": report_file, "report_figures": figures}
        echo_json(
            {
                **s,
                "output": output,
                "md5": md5,
                **extra,
                "issues": [i.to_dict() for i in result.issues],
            }
        )
        return
    for issue in result.issues:
        err(str(issue))
    reg = s["registration"]
    loops = s["loops"]
    click.echo(
        f"wrote {output} (MD5 {md5}): {plural(s['points'], 'point')}, "
        f"{plural(s['lines'], 'line')}, {plural(s['goals'], 'goal')}, RobotHome at the start"
    )
    click.echo(
        f"  scans: {s['scans_used']} used of {s['scans_in_log']}, path {s['path_length_m']} m"
        + (
            f" ({plural(s['sweeps_merged'], 'sweep')} of further lasers merged into their "
            "cycle's scan)"
            if s.get("sweeps_merged")
            else ""
        )
    )
    if s["register"]:
        click.echo(
            f"  registration: {plural(reg['registered'], 'scan')} matched, "
            f"{reg['odometry_only']} on "
            f"odometry alone, median residual {reg['median_residual_mm']} mm"
            + (f"; {reg['refined']} refined against the other passes" if reg.get("refined") else "")
        )
        if reg.get("scan_lag_ms"):
            click.echo(
                f"  scan lag: the sweeps are {abs(reg['scan_lag_ms'])} ms "
                f"{'older' if reg['scan_lag_ms'] > 0 else 'newer'} than the poses logged "
                f"with them (from {plural(reg['scan_lag_pairs'], 'change')} of turn rate); "
                "each was placed where the robot was then"
            )
        if reg.get("odometry_turn_error_ruled_out"):
            click.echo(
                f"  turn error: this log's turns rule out the one stated; fitted as "
                f"{reg['odometry_turn_error']} of each turn instead"
            )
        if reg.get("scan_lag_jitter_ms"):
            click.echo(
                f"  scan lag varies by {reg['scan_lag_jitter_ms']} ms from sweep to sweep: "
                "odometry taken from the calm sweeps on either side of each turn"
            )
        click.echo(
            f"  loops: {plural(loops['tags'], 'loop tag')} ({loops['tags_matched']} matched), "
            f"{plural(loops['revisits'], 'revisit')} closed, "
            + (f"{loops['rejected']} rejected as inconsistent, " if loops.get("rejected") else "")
            + (
                f"{loops['refused']} refused as beyond the odometry's reach, "
                if loops.get("refused")
                else ""
            )
            + f"{plural(loops['optimisations'], 'optimisation')}, "
            f"largest correction {loops['max_correction_mm']} mm / "
            f"{loops['max_correction_deg']} deg; the end moved "
            f"{s['end_shift_from_odometry_mm']} mm from odometry"
        )
    else:
        click.echo("  raw odometry (no registration)")
    sec = s["seconds"]
    click.echo(f"  time: read {sec['read']} s, register {sec['register']} s, map {sec['map']} s")
    if poses_file is not None:
        click.echo(f"wrote {poses_file}: {len(result.poses)} poses")
    if figures is not None:
        r, mv = figures["residual_mm"], figures["moved_from_odometry_mm"]
        click.echo(
            f"wrote {report_file} (PNG): {figures['matched']} of {figures['scans']} scans "
            f"matched, residual median {r['median']} / p90 {r['p90']} / max {r['max']} mm "
            f"(worst scans {', '.join(map(str, figures['worst_scans'])) or 'none'}); "
            f"{figures['loops_closed']} loops closed; moved from odometry median "
            f"{mv['median']} / p90 {mv['p90']} / max {mv['max']} mm"
        )


#: Fewer turning steps than this in all, and ``mapkit turn-error`` says what so few were worth
#: on the benchmark (docs/logs.md, round 20).
_FEW_TURNING_STEPS = 1000


def _alone(fraction: float | None) -> str:
    """A log's own fit of its turn error, as ``mapkit turn-error`` prints it."""
    if fraction is None:
        return "too few turns to fit"
    return f"{100 * fraction:.2g} % of each turn"


@click.command("turn-error")
@click.argument("log_files", nargs=-1, required=True, type=InputFile())
@_pose_options
@_tolerant_option
@json_option
def turn_error(
    log_files: tuple[str, ...], pose_source: str, max_range: float, tolerant: bool, as_json: bool
) -> None:
    """Learn how far a robot's odometry errs in its turns from several of its .2d logs.

    Registers every log as mapkit build does and fits the turns of all of them at once: one
    log's few dozen turns tell a good robot's turns from a slipping one's, but not 0.1 % from
    0.4 %. Give the figure to mapkit build --turn-error for this robot's logs.

    \b
    Examples:
      mapkit turn-error monday.2d tuesday.2d wednesday.2d
      mapkit build monday.2d -o monday.map --turn-error 0.0012
    """
    from mapkit.build import build_map, robot_turn_error
    from mapkit.cli.main import EXIT_FAILED, CommandError

    turns = []  # each log's turning steps (not its map: many long logs stay small)
    logs: list[dict[str, Any]] = []
    for path in log_files:
        bar = _Bar(f"registering {path}", enabled=not as_json)
        try:
            result = build_map(
                path,
                pose_source=pose_source,
                max_range=max_range,
                lines=False,
                strict=not tolerant,
                progress=bar,
            )
        finally:
            bar.close()
        for issue in result.issues:
            err(str(issue))
        turns.append(result.turns)
        logs.append(
            {
                "file": path,
                "turning_steps": len(result.turns.disagreement),
                "turn_error": result.summary["registration"]["odometry_turn_error"],
            }
        )
    pooled = robot_turn_error(turns)
    steps = sum(len(t.disagreement) for t in turns)
    if as_json:
        echo_json(
            {
                "turn_error": None if pooled is None else round(pooled, 5),
                "turning_steps": steps,
                "logs": logs,
            }
        )
    else:
        for entry in logs:
            click.echo(
                f"{entry['file']}: {plural(entry['turning_steps'], 'turning step')}; "
                f"this log alone: {_alone(entry['turn_error'])}"
            )
    if pooled is None:
        raise CommandError(
            f"{plural(steps, 'turning step')} in all (a turn of more than 5 degrees between "
            "scans): too few to learn the turns' error from (10 needed)",
            EXIT_FAILED,
        )
    if not as_json:
        click.echo(
            f"the robot's turns err {100 * pooled:.2g} % of each turn "
            f"({plural(steps, 'turning step')} in {plural(len(logs), 'log')})"
        )
        if steps < _FEW_TURNING_STEPS:
            click.echo(
                "  few turning steps: on the benchmark 300-400 (three logs) did no better than "
                "each log's own fit, 1,800-2,000 did"
            )
        click.echo(f"  build its logs with: mapkit build LOG -o MAP --turn-error {pooled:.2g}")


@click.command("log-info")
@click.argument("log_file", type=InputFile())
@click.option("--tolerant", is_flag=True, help="Count bad records instead of failing on the first.")
@json_option
def log_info(log_file: str, tolerant: bool, as_json: bool) -> None:
    """Show what a .2d laser log holds: version, lasers, scans, events, time, path length.

    Reads the log in one streaming pass, so logs of any length are fine.

    \b
    Example:
      mapkit log-info office.2d
    """
    from mapkit.formats.laser2d import log_summary

    s = log_summary(log_file, strict=not tolerant)
    if as_json:
        echo_json(s)
        return
    click.echo(
        f"{s['file']}: .2d laser log version {s['version']}"
        f"{'' if s['complete'] else ' (no End of log line: truncated or not closed)'}"
    )
    for las in s["lasers"]:
        name = f" {las['name']!r}" if las["name"] else ""
        x, y, th = las["pose"]
        click.echo(
            f"  laser {las['number']}{name}: {las['readings']} readings from "
            f"{las['first_angle']:g} to {las['last_angle']:g} deg, mounted at "
            f"({x:g}, {y:g}, {th:g})"
        )
    click.echo(
        f"  scans: {s['scans']} ({s['readings']} readings, "
        f"{100 * s['valid_fraction']:.1f}% with a return)"
    )
    ev = ", ".join(f"{n} {k}" for k, n in sorted(s["events"].items())) or "none"
    click.echo(f"  events: {ev}")
    if s["goals"]:
        click.echo(f"  goals: {', '.join(s['goals'])}")
    span = f"{s['time_span_s']} s" if s["time_span_s"] is not None else "no times"
    click.echo(f"  time span: {span}; odometry path: {s['path_length_m']} m")
    for issue in s["issues"]:
        loc = issue["location"]
        where = f"{loc.get('source', '')}:{loc['line']}" if "line" in loc else loc.get("source", "")
        click.echo(f"  {where}: {issue['severity']} MK{issue['code']}: {issue['message']}")
