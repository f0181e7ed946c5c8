"""``mapkit demo``: the main job on the bundled samples, in one command."""

from __future__ import annotations

import sys
from typing import Any

import click

from mapkit.cli.options import InputFile, echo_json, json_option, plural


@click.command()
@click.argument("folder", default="mapkit-demo", type=click.Path(file_okay=False))
@click.option(
    "--log",
    "log_path",
    type=InputFile(),
    help="Build from this .2d log instead of the bundled office-loop.2d.",
)
@json_option
def demo(folder: str, log_path: str | None, as_json: bool) -> None:
    """Run the whole job on a bundled sample into FOLDER (default: mapkit-demo).

    Builds a map from the bundled laser log, adds a goal and a forbidden area, validates it,
    renders it to PNG, rasterises it for ROS (PGM + YAML + keepout mask), exports a 3D mesh
    with a Gazebo world, then starts a map server on loopback, sends the map to it and fetches
    it back, verifying the SHA-256. Prints what it made, where, with checksums.

    \b
    Example:
      mapkit demo out/
    """
    from mapkit.demo import DEMO_STEPS, run_demo

    titles = {s.name: s.title for s in DEMO_STEPS}
    order = [s.name for s in DEMO_STEPS]
    state: dict[str, Any] = {"bar": None, "step": None}

    def progress(step: str, done: int, total: int) -> None:
        if step != state["step"]:
            if state["bar"] is not None:
                state["bar"].render_finish()
                state["bar"] = None
            state["step"] = step
            click.echo(f"[{order.index(step) + 1}/{len(order)}] {titles[step]}", err=True)
        if step == "build" and 0 < done < total:
            if state["bar"] is None:
                state["bar"] = bar = click.progressbar(
                    length=total, label="      scans", file=sys.stderr
                )
                bar.render_progress()
            bar = state["bar"]
            bar.update(done - bar.pos)

    result = run_demo(folder, log=log_path, progress=progress)
    if state["bar"] is not None:
        state["bar"].render_finish()
    if as_json:
        echo_json(result.to_dict())
        return
    s = result.summary
    b = s.get("build", {})
    click.echo(
        f"\nmapkit demo: done in {sum(result.seconds.values()):.1f} s; files in {result.folder}"
    )
    click.echo(
        f"  built      {plural(b.get('scans_used', b.get('scans', 0)), 'scan')} -> "
        f"{plural(s['edit']['objects'], 'object')}, MD5 {s['edit']['md5']}"
    )
    v = s["validate"]
    click.echo(f"  validated  {plural(v['errors'], 'error')}, {plural(v['warnings'], 'warning')}")
    r = s["ros"]
    click.echo(f"  ROS map    {r['width']} x {r['height']} cells of {r['resolution_m']} m")
    t = s["transfer"]
    click.echo(
        f"  transfer   sent to {t['server']} as {t['name']!r}, loaded, fetched back: "
        "SHA-256 verified"
    )
    click.echo("\n  file                     size  SHA-256")
    for a in result.artefacts:
        name = a.path.relative_to(result.folder)
        click.echo(f"  {name!s:<20} {a.size:>9}  {a.sha256[:16]}…  {a.what}")
