"""``mapkit validate``: the map linter; ``mapkit codes``: the table of finding codes."""

from __future__ import annotations

import sys
from collections import Counter

import click

from mapkit.cli.options import InputFile, echo_json, json_option, plural
from mapkit.diagnostics import Issue, Severity
from mapkit.errors import MapkitError
from mapkit.validate import DEFAULT_ROBOT_RADIUS, ValidationReport, validate as run_validate
from mapkit.validate.codes import code_rows, codes_markdown

#: Exit code when the file cannot be read at all.
EXIT_UNREADABLE = 2
#: In text output, at most this many findings per code are listed.
TEXT_LIMIT_PER_CODE = 20

_HEADINGS = {Severity.ERROR: "errors", Severity.WARNING: "warnings", Severity.INFO: "info"}


def _plural(n: int, word: str) -> str:
    if word == "info":
        return f"{n} info"
    return f"{n} {word}{'' if n == 1 else 's'}"


def summary_line(report: ValidationReport) -> str:
    """The one-line summary: counts per severity and what was checked."""
    c = report.counts()
    name = report.source or "map"
    facts = [f"robot radius {report.robot_radius:.0f} mm"]
    nav = report.checked.get("navigation")
    if isinstance(nav, dict) and "reachable" in nav:
        facts.append(f"{nav['reachable']} of {nav['targets']} goals/docks reachable")
    if not report.issues:
        return f"{name}: no problems found ({', '.join(facts)})"
    counts = ", ".join(_plural(c[s.value], s.value) for s in Severity if c[s.value])
    return f"{name}: {counts} ({', '.join(facts)})"


def _where(issue: Issue) -> str:
    loc = issue.location
    src = loc.source or "map"
    return f"{src}:{loc.line}" if loc.line is not None else src


def render_text(report: ValidationReport) -> list[str]:
    """The findings grouped by severity, then the summary line."""
    out: list[str] = []
    for sev in Severity:
        group = report.by_severity(sev)
        if not group:
            continue
        out.append(f"{_HEADINGS[sev]} ({len(group)}):")
        shown: Counter[int] = Counter()
        hidden: Counter[int] = Counter()
        for issue in group:
            code = int(issue.code)
            if shown[code] >= TEXT_LIMIT_PER_CODE:
                hidden[code] += 1
                continue
            shown[code] += 1
            out.append(f"  {_where(issue)}: MK{code} {issue.message}")
        for code, n in hidden.items():
            out.append(f"  ... {plural(n, f'more MK{code} finding')} (--json lists them all)")
    out.append(summary_line(report))
    return out


@click.command()
@click.argument("map_file", type=InputFile(check=False))
@json_option
@click.option(
    "--robot-radius",
    type=click.FloatRange(min=0, max=100_000),
    default=DEFAULT_ROBOT_RADIUS,
    show_default=True,
    metavar="MM",
    help="Robot radius for the clearance and reachability checks (0: connectivity only).",
)
@click.option("--strict", is_flag=True, help="Exit 1 on warnings too.")
@click.option("--no-navigation", is_flag=True, help="Skip the reachability checks (5xx).")
@click.pass_context
def validate(
    ctx: click.Context,
    map_file: str,
    as_json: bool,
    robot_radius: float,
    strict: bool,
    no_navigation: bool,
) -> None:
    """Check MAP_FILE and list every finding with a stable code (mapkit codes lists them).

    Findings are grouped by severity. Exit status: 0 no errors, 1 errors (or warnings with
    --strict), 2 the file cannot be read at all.

    \b
    Example:
      mapkit validate office.map
      mapkit validate office.map --robot-radius 350 --strict
      mapkit validate office.map --json > report.json
    """
    try:
        report = run_validate(map_file, robot_radius=robot_radius, navigation=not no_navigation)
    except (MapkitError, OSError) as err:
        from mapkit.cli.main import error_message

        message = error_message(err)[0]
        if as_json:
            echo_json({"file": map_file, "readable": False, "error": message})
        click.echo(
            f"Error: cannot read {map_file}: {message}"
            if map_file not in message
            else f"Error: {message}",
            file=sys.stderr,
        )
        ctx.exit(EXIT_UNREADABLE)
    code = report.exit_code(strict)
    if as_json:
        data = {"readable": True, **report.to_dict(), "strict": strict, "exit_code": code}
        echo_json(data)
    else:
        for line in render_text(report):
            click.echo(line)
    ctx.exit(code)


@click.command()
@click.option("--markdown", is_flag=True, help="Print docs/codes.md (the generated table).")
@json_option
def codes(markdown: bool, as_json: bool) -> None:
    """List every finding code: number, name, default severity, summary.

    \b
    Example:
      mapkit codes
      mapkit codes --markdown > docs/codes.md
    """
    if markdown and as_json:
        raise click.UsageError("give --markdown or --json, not both")
    if markdown:
        click.echo(codes_markdown(), nl=False)
        return
    rows = code_rows()
    if as_json:
        echo_json(rows)
        return
    width = max(len(r["name"]) for r in rows)
    for r in rows:
        click.echo(f"{r['code']}  {r['name']:<{width}}  {r['severity']:<7}  {r['summary']}")
