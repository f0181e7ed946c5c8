"""ARIA's own ArNetworking server (``run-mapserver``) and client (``run-probe``) for the tests.

They come from ``../shared/aria-peer`` (ARIA 2.9.1 built from its GPL source). When they are
missing the tests fail under ``CI=true`` and skip elsewhere.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import signal
import socket
import subprocess
import time
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.conftest import IN_CI, SHARED

PEER = Path(os.environ.get("MAPKIT_ARIA_PEER", SHARED / "aria-peer"))
USERS = """UserInfoVersion1
user admin secret1 all
user mapper map2pw Map
"""
ADMIN = ("admin", "secret1")
MAPPER = ("mapper", "map2pw")


def require_peer() -> Path:
    """The aria-peer folder; fails in CI, skips elsewhere, when it is missing or does not run."""
    problem = None
    if not (PEER / "run-mapserver").exists() or not (PEER / "run-probe").exists():
        problem = (
            f"ARIA's ArNetworking peer not found at {PEER} (set MAPKIT_ARIA_PEER or MAPKIT_SHARED)"
        )
    if problem:
        if IN_CI:
            pytest.fail(problem)
        pytest.skip(problem)
    return PEER


def free_port() -> int:
    """A port free for TCP and UDP on 127.0.0.1 right now."""
    for _ in range(50):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = int(s.getsockname()[1])
        try:
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as u:
                u.bind(("127.0.0.1", port))
        except OSError:
            continue
        return port
    raise AssertionError("no free port")


@dataclass
class Peer:
    """A running ``run-mapserver`` with its map folder ``root``."""

    proc: subprocess.Popen[bytes]
    port: int
    root: Path
    log: Path
    login: tuple[str, str] | None

    @property
    def address(self) -> str:
        return f"127.0.0.1:{self.port}"

    def probe(
        self,
        *args: str,
        login: tuple[str, str] | None = None,
        cwd: Path | None = None,
        timeout: float = 60,
    ) -> subprocess.CompletedProcess[str]:
        """Run ARIA's client ``run-probe`` against this server."""
        who = login or self.login
        auth = ["-user", who[0], "-password", who[1]] if who else []
        return subprocess.run(
            [
                str(PEER / "run-probe"),
                "-quiet",
                "-host",
                "127.0.0.1",
                "-port",
                str(self.port),
                *auth,
                *args,
            ],
            capture_output=True,
            text=True,
            timeout=timeout,
            cwd=cwd or self.root.parent,
        )

    def mapname(self) -> str:
        """The active map as ARIA's client sees it."""
        out = self.probe("mapname").stdout
        m = re.search(r"mapname: '(.*)'", out)
        assert m, out
        return m.group(1)

    def probe_get(self, remote: str, local: Path) -> bytes:
        """Download ``remote`` with ARIA's own client; its bytes."""
        folder, _, name = remote.rpartition("/")
        res = self.probe("get", folder or ".", name, str(local))
        assert res.returncode == 0, res.stdout + res.stderr
        return local.read_bytes()

    def stop(self, sig: int = signal.SIGTERM) -> None:
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                self.proc.send_signal(sig)
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(10)


def _answers(port: int) -> bool:
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=1) as s:
            s.settimeout(2)
            return s.recv(2) == b"\x0f\x0c"
    except OSError:
        return False


def start_peer(
    tmp: Path,
    maps: Iterable[Path],
    active: str | None = None,
    login: tuple[str, str] | None = ADMIN,
) -> Peer:
    """Start ``run-mapserver`` on a free port, serving a copy of ``maps`` (logins from USERS)."""
    require_peer()
    root = tmp / "root"
    root.mkdir(parents=True, exist_ok=True)
    for m in maps:
        shutil.copyfile(m, root / m.name)
    (tmp / "stage").mkdir(exist_ok=True)
    users = tmp / "users.txt"
    users.write_text(USERS)
    for _ in range(3):
        port = free_port()
        log = tmp / f"mapserver-{port}.log"
        cmd = [
            str(PEER / "run-mapserver"),
            "-serverPort",
            str(port),
            "-fileDir",
            str(root),
            "-config",
            str(tmp / "server.cfg"),
            "-tempDir",
            str(tmp / "stage"),
        ]
        if active:
            cmd += ["-map", active]
        if login:
            cmd += ["-userInfo", str(users)]
        with open(log, "wb") as fh:
            proc = subprocess.Popen(
                cmd, stdout=fh, stderr=subprocess.STDOUT, cwd=tmp, stdin=subprocess.DEVNULL
            )
        deadline = time.monotonic() + 20
        while proc.poll() is None and time.monotonic() < deadline and not _answers(port):
            time.sleep(0.05)
        if proc.poll() is None and _answers(port):
            return Peer(proc, port, root, log, login)
        proc.kill()
        proc.wait()
    raise AssertionError(f"run-mapserver did not start:\n{log.read_text(errors='replace')}")


def leftovers(folder: Path) -> list[str]:
    """Files in ``folder`` (temp files of a broken download included)."""
    return sorted(p.name for p in folder.iterdir())
