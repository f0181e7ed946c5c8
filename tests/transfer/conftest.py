"""Fixtures for the transfer tests: a map server on 127.0.0.1, a fault-injecting TCP proxy."""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from mkt_helpers import SECRET, Proxy

from mapkit.transfer import MapServer


@pytest.fixture
def secret() -> bytes:
    """The shared secret used by the tests."""
    return SECRET


@pytest.fixture
def robot_dir(tmp_path: Path) -> Path:
    """An empty maps folder for the server."""
    d = tmp_path / "robot"
    d.mkdir()
    return d


@pytest.fixture
def make_server(robot_dir: Path) -> Iterator[Any]:
    """Start MapServers on a free port with short timeouts; all are closed at the end."""
    servers: list[MapServer] = []

    def make(folder: Any = None, **kw: Any) -> MapServer:
        kw.setdefault("secret", SECRET)
        kw.setdefault("rto", 0.2)
        kw.setdefault("idle_timeout", 5.0)
        srv = MapServer(folder if folder is not None else robot_dir, host="127.0.0.1", port=0, **kw)
        servers.append(srv.start())
        return srv

    yield make
    for s in servers:
        s.close()


@pytest.fixture
def proxy() -> Iterator[Any]:
    """Make :class:`Proxy` objects, closed at the end."""
    made: list[Proxy] = []

    def make(target: tuple[str, int], **kw: Any) -> Proxy:
        p = Proxy(target, **kw)
        made.append(p)
        return p

    yield make
    for p in made:
        p.close()


@pytest.fixture(scope="module")
def cert(tmp_path_factory):
    if shutil.which("openssl") is None:
        pytest.skip("openssl is needed to make a test certificate")
    d = tmp_path_factory.mktemp("tls")
    subprocess.run(
        [
            "openssl",
            "req",
            "-x509",
            "-newkey",
            "ec",
            "-pkeyopt",
            "ec_paramgen_curve:P-256",
            "-nodes",
            "-days",
            "2",
            "-subj",
            "/CN=robot",
            "-addext",
            "subjectAltName=IP:127.0.0.1",
            "-keyout",
            str(d / "key.pem"),
            "-out",
            str(d / "cert.pem"),
        ],
        check=True,
        capture_output=True,
        timeout=30,
    )
    return d / "cert.pem", d / "key.pem"
