"""``mapkit open FILE``: edit a map in the browser (a local editor on 127.0.0.1)."""

from __future__ import annotations

import sys

import click

from mapkit.cli.options import InputFile

__all__ = ["open_cmd"]


@click.command("open")
@click.argument("map_file", metavar="FILE", type=InputFile())
@click.option(
    "--port",
    type=click.IntRange(0, 65535),
    default=0,
    show_default=True,
    help="Port on 127.0.0.1 (0 picks a free one).",
)
@click.option("--no-browser", is_flag=True, help="Print the address only; open no browser.")
@click.option(
    "--keepout",
    type=InputFile(),
    metavar="MASK.yaml",
    help="A ROS map's keepout mask (default: NAME_keepout.yaml beside the map).",
)
def open_cmd(map_file: str, port: int, no_browser: bool, keepout: str | None) -> None:
    """Edit FILE (an ARIA .map, or a ROS map YAML and its keepout zones) in the browser.

    Serves a page on 127.0.0.1 only, with a random token in its address; prints the address
    and runs until Ctrl-C. The page shows the scan, objects and `mapkit validate` findings;
    edits are `mapkit edit --script` operations, saved atomically as the CLI saves them.

    \b
    Example:
      mapkit open office.map
      mapkit open warehouse.yaml --keepout warehouse_keepout.yaml --no-browser
    """
    from mapkit.open.server import Editor

    editor = Editor.open(map_file, port=port, keepout=keepout)
    url = editor.url("/")
    click.echo(f"mapkit open: {url}")
    sys.stdout.flush()
    if not no_browser:
        import webbrowser

        webbrowser.open(url)
    try:
        editor.serve_forever()
    except KeyboardInterrupt:
        click.echo("mapkit open: stopped", err=True)
    finally:
        editor.httpd.server_close()
