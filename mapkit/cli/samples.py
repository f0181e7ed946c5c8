"""``mapkit samples``: list the bundled sample maps and logs, or copy them out."""

from __future__ import annotations

from pathlib import Path

import click

from mapkit._atomic import atomic_write, write_error
from mapkit.cli.options import echo_json, json_option
from mapkit.samples import list_samples, sample_path


@click.command()
@click.argument("names", nargs=-1)
@click.option(
    "-o",
    "--output",
    "folder",
    type=click.Path(file_okay=False),
    help="Copy the named samples (or all, with --all) into this folder.",
)
@click.option("--all", "copy_all", is_flag=True, help="With -o: copy every sample.")
@json_option
def samples(names: tuple[str, ...], folder: str | None, copy_all: bool, as_json: bool) -> None:
    """List the maps and laser logs bundled with mapkit, or copy some into a folder.

    \b
    Example:
      mapkit samples
      mapkit samples office office-loop.2d -o .
    """
    if folder is None:
        if names or copy_all:
            raise click.UsageError("give -o FOLDER to copy samples")
        rows = [{"name": n, "size": sample_path(n).stat().st_size} for n in list_samples()]
        if as_json:
            echo_json(rows)
        else:
            for r in rows:
                click.echo(f"{r['name']:<24} {r['size']:>9} bytes")
        return
    chosen = list_samples() if copy_all else list(names)
    if not chosen:
        raise click.UsageError("name the samples to copy, or give --all")
    dest = Path(folder)
    try:
        dest.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise write_error(str(dest), e) from e
    copied = []
    for n in chosen:
        src = sample_path(n)
        atomic_write(dest / src.name, src.read_bytes())
        copied.append(str(dest / src.name))
    if as_json:
        echo_json(copied)
    else:
        for c in copied:
            click.echo(f"copied {c}")
