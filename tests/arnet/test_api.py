"""``mapkit.aria``: loaded lazily from ``import mapkit``; where the password comes from."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from mapkit import aria
from mapkit.errors import MapkitError, TransferError
from tests.conftest import ROOT


def test_mapkit_aria_is_lazy() -> None:
    code = (
        "import sys, mapkit; assert 'mapkit.arnet' not in sys.modules; "
        "assert mapkit.aria.connect is __import__('mapkit.arnet').arnet.connect"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)


def test_errors_are_mapkit_errors() -> None:
    for cls in (
        aria.AriaError,
        aria.AriaLoginError,
        aria.AriaProtocolError,
        aria.AriaTimeoutError,
        aria.AriaConnectionError,
        aria.AriaPermissionError,
        aria.AriaRemoteError,
        aria.AriaMapRefusedError,
        aria.AriaValueError,
    ):
        assert issubclass(cls, MapkitError) and issubclass(cls, TransferError)


def test_password_sources(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("MAPKIT_ARIA_PASSWORD_FILE", raising=False)
    monkeypatch.delenv("MAPKIT_ARIA_PASSWORD", raising=False)
    assert aria.password_from_env() == ""
    monkeypatch.setenv("MAPKIT_ARIA_PASSWORD", "fromenv")
    assert aria.password_from_env() == "fromenv"
    f = tmp_path / "pw"
    f.write_bytes(b"fromfile\r\n")
    monkeypatch.setenv("MAPKIT_ARIA_PASSWORD_FILE", str(f))
    assert aria.password_from_env() == "fromfile"
    g = tmp_path / "pw2"
    g.write_text("explicit\n\n")
    assert aria.password_from_env(str(g)) == "explicit\n"  # only one newline is dropped
    with pytest.raises(MapkitError, match="cannot read the password file"):
        aria.password_from_env(str(tmp_path / "nope"))
    (tmp_path / "big").write_bytes(b"x" * 5000)
    with pytest.raises(MapkitError, match="too long"):
        aria.password_from_env(str(tmp_path / "big"))


@pytest.mark.parametrize(
    "address,expected",
    [
        ("robot", ("robot", 7272)),
        ("robot:7300", ("robot", 7300)),
        ("10.0.0.2", ("10.0.0.2", 7272)),
        ("[fe80::1]:8000", ("fe80::1", 8000)),
        ("::1", ("::1", 7272)),
    ],
)
def test_addresses(address: str, expected: tuple[str, int]) -> None:
    from mapkit.arnet import parse_host

    assert parse_host(address) == expected


@pytest.mark.parametrize("address", ["", "robot:", "robot:x", "robot:70000"])
def test_bad_addresses(address: str) -> None:
    from mapkit.arnet import parse_host

    with pytest.raises(ValueError):
        parse_host(address)
