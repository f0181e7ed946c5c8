"""``mapkit serve / send / fetch / maps / load / receive``: maps between robot and terminal (MKT/1).

The shared secret comes from ``--secret-file`` or the ``MAPKIT_SECRET`` (or ``MAPKIT_SECRET_FILE``)
environment variable, never from the command line. Without one, both sides must say
``--insecure``.
"""

from __future__ import annotations

import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, TypeVar

import click

from mapkit.cli.options import InputFile, echo_json, err, json_option, plural

if TYPE_CHECKING:
    from mapkit.transfer import Client, MapServer

# mapkit.transfer is imported inside the commands so that `mapkit --help` stays fast.
DEFAULT_PORT = 7373  # == mapkit.transfer.DEFAULT_PORT (a test checks)

F = TypeVar("F", bound=Callable[..., Any])


def _auth_text(secret: bytes | None) -> str:
    from mapkit.transfer.protocol import AUTH_METHODS

    return "|".join(AUTH_METHODS) if secret else "none"


def _secret_options(f: F) -> F:
    f = click.option(
        "--insecure",
        is_flag=True,
        help="Go without authentication (the other side must say so too).",
    )(f)
    f = click.option(
        "--secret-file",
        type=click.Path(dir_okay=False),
        help="File with the shared secret (else $MAPKIT_SECRET).",
    )(f)
    return f


def _client_options(f: F) -> F:
    f = _secret_options(f)
    f = click.option(
        "--tls", "use_tls", is_flag=True, help="Use TLS (the robot runs with --tls-cert)."
    )(f)
    f = click.option(
        "--tls-ca",
        type=InputFile(),
        help="Trust this CA or the robot's own certificate (implies --tls).",
    )(f)
    f = click.option(
        "--tls-no-verify",
        is_flag=True,
        help="TLS without checking the certificate (the secret still authenticates).",
    )(f)
    f = click.option(
        "--timeout",
        type=float,
        default=10.0,
        show_default=True,
        help="Seconds to wait for the robot.",
    )(f)
    return f


def _client(
    address: str,
    secret_file: str | None,
    insecure: bool,
    use_tls: bool,
    tls_ca: str | None,
    tls_no_verify: bool,
    timeout: float,
) -> Client:
    from mapkit.transfer import Client, client_tls_context, load_secret, parse_address

    host, port = parse_address(address, DEFAULT_PORT)
    secret = load_secret(path=secret_file)
    tls = (
        client_tls_context(tls_ca, verify=not tls_no_verify)
        if (use_tls or tls_ca or tls_no_verify)
        else None
    )
    return Client(host, port, secret=secret, insecure=insecure, tls=tls, timeout=timeout)


@contextmanager
def _progress(label: str, quiet: bool) -> Iterator[Callable[[int, int], None] | None]:
    """A progress bar on stderr with rate and ETA; yields the callback (None when quiet)."""
    if quiet or not sys.stderr.isatty():
        yield None
        return
    state: dict[str, Any] = {"bar": None, "t0": time.monotonic()}

    def show(rate: Any) -> str:
        return str(rate) if rate else ""

    def cb(done: int, total: int) -> None:
        bar = state["bar"]
        if bar is None:
            bar = click.progressbar(
                length=max(total, 1),
                label=label,
                file=sys.stderr,
                show_eta=True,
                show_percent=True,
                item_show_func=show,
            )
            bar.__enter__()
            state["bar"] = bar
        dt = time.monotonic() - state["t0"]
        rate = f"{done / dt / 1e6:.1f} MB/s" if dt > 0 else ""
        bar.update(max(0, min(done, total) - bar.pos), rate)

    try:
        yield cb
    finally:
        if state["bar"] is not None:
            state["bar"].__exit__(None, None, None)


def _quiet(as_json: bool) -> bool:
    return logging.getLogger().level > logging.WARNING


def _size(n: int) -> str:
    for unit in ("B", "KB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000  # type: ignore[assignment]
    return str(n)  # pragma: no cover


def _serve(server: MapServer) -> None:
    """Run until SIGINT/SIGTERM."""
    stop = threading.Event()

    def handler(signum: int, frame: Any) -> None:
        stop.set()

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, handler)
        signal.signal(signal.SIGINT, handler)
    server.start()
    try:
        while not stop.wait(0.5):
            pass
    finally:
        server.close()


def _server_setup(
    listen_addr: str,
    secret_file: str | None,
    insecure: bool,
    tls_cert: str | None,
    tls_key: str | None,
) -> tuple[str, int, bytes | None, Any]:
    from mapkit.transfer import load_secret, parse_address, server_tls_context

    host, port = parse_address(listen_addr, DEFAULT_PORT, default_host="0.0.0.0")
    secret = load_secret(path=secret_file)
    if secret is None and not insecure:
        raise click.UsageError(
            "no shared secret: give --secret-file or set MAPKIT_SECRET "
            "(or --insecure to accept anyone)"
        )
    if tls_key and not tls_cert:
        raise click.UsageError("--tls-key needs --tls-cert")
    tls = server_tls_context(tls_cert, tls_key) if tls_cert else None
    if not logging.getLogger().level > logging.WARNING:
        logging.getLogger("mapkit.transfer").setLevel(logging.INFO)
    return host, port, secret, tls


@click.command()
@click.argument("folder", type=click.Path(file_okay=False))
@click.option(
    "--listen",
    "listen_addr",
    default=f"0.0.0.0:{DEFAULT_PORT}",
    show_default=True,
    metavar="HOST:PORT",
    help="Address to listen on (port 0: any free port).",
)
@_secret_options
@click.option("--tls-cert", type=InputFile(), help="TLS certificate (PEM).")
@click.option("--tls-key", type=InputFile(), help="TLS private key (PEM).")
@click.option(
    "--max-size",
    type=int,
    default=1 << 30,
    show_default=True,
    help="Largest file accepted (bytes).",
)
@click.option(
    "--handshake-timeout",
    type=click.FloatRange(min=0.1),
    default=5.0,
    show_default=True,
    help="Seconds a client has from connecting to proving the secret.",
)
@click.option(
    "--partial-ttl",
    type=click.FloatRange(min=0),
    default=24 * 3600.0,
    show_default=True,
    help="Seconds after which an interrupted transfer's partial file is deleted.",
)
def serve(
    folder: str,
    listen_addr: str,
    secret_file: str | None,
    insecure: bool,
    tls_cert: str | None,
    tls_key: str | None,
    max_size: int,
    handshake_timeout: float,
    partial_ttl: float,
) -> None:
    """Serve the maps in FOLDER to terminals: push, pull, list and load (run on the robot).

    Received maps are parsed before they replace anything; `load` makes a map active by writing
    it atomically to FOLDER/active.map (the previous one is kept as previous.map). Runs until
    Ctrl-C or SIGTERM.

    \b
    Example:
      MAPKIT_SECRET_FILE=/etc/mapkit/secret mapkit serve /home/robot/maps
      mapkit serve maps --listen 0.0.0.0:7373 --secret-file secret --tls-cert c.pem --tls-key k.pem
    """
    from mapkit.transfer import MapFolder, MapServer

    host, port, secret, tls = _server_setup(listen_addr, secret_file, insecure, tls_cert, tls_key)
    srv = MapServer(
        MapFolder(folder, max_size=max_size),
        host=host,
        port=port,
        secret=secret,
        insecure=insecure,
        tls=tls,
        handshake_timeout=handshake_timeout,
        partial_ttl=partial_ttl,
    )
    h, p = srv.address
    err(
        f"mapkit serve: serving {srv.folder.root} on {h}:{p} "
        f"(auth {_auth_text(secret)}, tls {'on' if tls else 'off'})"
    )
    _serve(srv)


@click.command()
@click.option(
    "--listen",
    "listen_addr",
    default=f"0.0.0.0:{DEFAULT_PORT}",
    show_default=True,
    metavar="HOST:PORT",
    help="Address to listen on.",
)
@click.option(
    "-o",
    "--output",
    "folder",
    type=click.Path(file_okay=False),
    default=".",
    show_default=True,
    help="Folder for received files.",
)
@_secret_options
@click.option("--tls-cert", type=InputFile(), help="TLS certificate (PEM).")
@click.option("--tls-key", type=InputFile(), help="TLS private key (PEM).")
@click.option("--once", is_flag=True, help="Exit after the first file received.")
@json_option
def receive(
    listen_addr: str,
    folder: str,
    secret_file: str | None,
    insecure: bool,
    tls_cert: str | None,
    tls_key: str | None,
    once: bool,
    as_json: bool,
) -> None:
    """Receive maps and .2d logs that a robot sends here (`mapkit send` on the robot).

    Only pushes are accepted. Each file is written atomically into the folder (a .map must
    parse first); an interrupted transfer resumes when the robot sends again.

    \b
    Example:
      mapkit receive --listen 0.0.0.0:7373 -o incoming --secret-file secret
      (on the robot)  mapkit send log.2d laptop:7373 --secret-file secret
    """
    from mapkit.transfer import MapFolder, MapServer, receive_files

    host, port, secret, tls = _server_setup(listen_addr, secret_file, insecure, tls_cert, tls_key)
    root = os.path.abspath(folder)

    def listening(address: tuple[str, int]) -> None:
        err(
            f"mapkit receive: waiting on {address[0]}:{address[1]} for files into {root} "
            f"(auth {_auth_text(secret)}, tls {'on' if tls else 'off'})"
        )

    def show(info: dict[str, Any]) -> None:
        if not as_json:
            click.echo(
                f"received {info['name']} ({_size(info['size'])}, SHA-256 {info['sha256'][:16]}…) "
                f"from {info['peer']}"
            )

    if once:
        first = receive_files(
            folder,
            host,
            port,
            count=1,
            secret=secret,
            insecure=insecure,
            tls=tls,
            on_listening=listening,
        )
        for info in first:
            show(info)
        if as_json:
            echo_json(first[0] if first else None)
        return
    got: list[dict[str, Any]] = []

    def received(info: dict[str, Any]) -> None:
        got.append(info)
        show(info)

    srv = MapServer(
        MapFolder(folder),
        host=host,
        port=port,
        secret=secret,
        insecure=insecure,
        tls=tls,
        push_only=True,
        on_received=received,
    )
    listening(srv.address)
    _serve(srv)
    if as_json:
        echo_json(got)


@click.command()
@click.argument("file", type=InputFile())
@click.argument("address", metavar="HOST[:PORT]")
@click.option("--name", help="Name on the robot (default: the file's name).")
@click.option("--load", "and_load", is_flag=True, help="Then make it the robot's active map.")
@_client_options
@json_option
def send(
    file: str,
    address: str,
    name: str | None,
    and_load: bool,
    secret_file: str | None,
    insecure: bool,
    use_tls: bool,
    tls_ca: str | None,
    tls_no_verify: bool,
    timeout: float,
    as_json: bool,
) -> None:
    """Send FILE (a .map or .2d) to a robot or terminal at HOST[:PORT] (default port 7373).

    The receiver checks it (SHA-256; a .map must parse) before it replaces anything. An
    interrupted send resumes where it stopped when run again.

    \b
    Example:
      mapkit send office.map robot1 --secret-file secret --load
    """
    with (
        _client(address, secret_file, insecure, use_tls, tls_ca, tls_no_verify, timeout) as c,
        _progress(name or file, as_json or _quiet(as_json)) as cb,
    ):
        result = c.send(file, name=name, progress=cb)
        if and_load:
            result["loaded"] = c.load(result["name"], md5=result.get("md5"))
    if as_json:
        echo_json(result)
        return
    resumed = (
        f", {plural(result['chunks_skipped'], 'chunk was', 'chunks were')} already there"
        if result["chunks_skipped"]
        else ""
    )
    click.echo(
        f"sent {result['name']} to {address}: {_size(result['size'])} in "
        f"{result['seconds']:.2f} s ({result['mb_per_s'] or 0:.1f} MB/s), SHA-256 verified{resumed}"
    )
    if and_load:
        click.echo(
            f"active map on {address} is now {result['loaded']['name']} "
            f"(MD5 {result['loaded']['md5']})"
        )


def _shown(path: str) -> str:
    """A written file as the user names it: relative to the current folder when inside it."""
    rel = os.path.relpath(path)
    return path if rel.startswith(os.pardir) else rel


@click.command()
@click.argument("address", metavar="HOST[:PORT]")
@click.argument("name")
@click.option(
    "-o", "--output", type=click.Path(), help="Local file or folder (default: NAME here)."
)
@click.option("--if-changed", is_flag=True, help="Skip when the local file already matches (MD5).")
@_client_options
@json_option
def fetch(
    address: str,
    name: str,
    output: str | None,
    if_changed: bool,
    secret_file: str | None,
    insecure: bool,
    use_tls: bool,
    tls_ca: str | None,
    tls_no_verify: bool,
    timeout: float,
    as_json: bool,
) -> None:
    """Fetch the map NAME from a robot (`mapkit maps` lists them; `active.map` is the active one).

    \b
    Example:
      mapkit fetch robot1 office.map -o office.map --if-changed
    """
    with (
        _client(address, secret_file, insecure, use_tls, tls_ca, tls_no_verify, timeout) as c,
        _progress(name, as_json or _quiet(as_json)) as cb,
    ):
        result = c.fetch(name, output or name, if_changed=if_changed, progress=cb)
    if as_json:
        echo_json(result)
    elif not result["modified"]:
        click.echo(
            f"{_shown(result['path'])} is up to date (MD5 {result.get('md5') or '-'}), "
            "nothing fetched"
        )
    else:
        resumed = (
            f", {plural(result['chunks_resumed'], 'chunk')} resumed"
            if result["chunks_resumed"]
            else ""
        )
        click.echo(
            f"fetched {name} from {address} into {_shown(result['path'])}: "
            f"{_size(result['size'])} in "
            f"{result['seconds']:.2f} s, SHA-256 verified{resumed}"
        )


@click.command()
@click.argument("address", metavar="HOST[:PORT]")
@_client_options
@json_option
def maps(
    address: str,
    secret_file: str | None,
    insecure: bool,
    use_tls: bool,
    tls_ca: str | None,
    tls_no_verify: bool,
    timeout: float,
    as_json: bool,
) -> None:
    """List the maps on a robot: name, size, MD5 and which one is active.

    \b
    Example:
      mapkit maps robot1 --secret-file secret
    """
    with _client(address, secret_file, insecure, use_tls, tls_ca, tls_no_verify, timeout) as c:
        listing = c.list()
    if as_json:
        echo_json(listing)
        return
    print_listing(listing, address)


def print_listing(listing: dict[str, Any], where: str) -> None:
    """Print a robot's listing (LISTING payload): one line per map, then the active one."""
    rows = listing.get("maps", [])
    if not rows:
        click.echo(f"no maps on {where}")
        return
    width = max(len(m["name"]) for m in rows)
    for m in rows:
        mark = "*" if m.get("active") else " "
        click.echo(
            f"{mark} {m['name']:<{width}}  {_size(m['size']):>9}  {m['md5']}  "
            f"{time.strftime('%Y-%m-%d %H:%M', time.localtime(m['mtime']))}"
        )
    if listing.get("active"):
        click.echo(
            f"active: {listing['active']} (MD5 {listing.get('active_md5')})"
            + (f", previous: {listing['previous']}" if listing.get("previous") else "")
        )


@click.command()
@click.argument("address", metavar="HOST[:PORT]")
@click.argument("name", required=False)
@click.option(
    "--md5", help="Only load if the robot's file has this MD5 (default: the MD5 it lists now)."
)
@click.option("--rollback", is_flag=True, help="Re-activate the previous map.")
@_client_options
@json_option
def load(
    address: str,
    name: str | None,
    md5: str | None,
    rollback: bool,
    secret_file: str | None,
    insecure: bool,
    use_tls: bool,
    tls_ca: str | None,
    tls_no_verify: bool,
    timeout: float,
    as_json: bool,
) -> None:
    """Make the map NAME on the robot its active map (checked: MD5, then parsed).

    \b
    Example:
      mapkit load robot1 office.map
      mapkit load robot1 --rollback
    """
    if not rollback and not name:
        raise click.UsageError("give a map NAME or --rollback")
    with _client(address, secret_file, insecure, use_tls, tls_ca, tls_no_verify, timeout) as c:
        state = c.load(name, md5=md5, rollback=rollback)
    if as_json:
        echo_json(state)
        return
    prev = (state.get("previous") or {}).get("name")
    click.echo(
        f"active map on {address} is now {state['name']} (MD5 {state['md5']})"
        + (f"; previous: {prev}" if prev else "")
    )


COMMANDS = [serve, receive, send, fetch, maps, load]
