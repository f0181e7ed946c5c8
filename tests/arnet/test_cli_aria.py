"""``mapkit aria ...`` against ARIA 2.9.1's own server, checked with ARIA's own client."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from mapkit.cli.main import cli
from tests.arnet.peer import Peer, leftovers
from tests.conftest import ROOT

pytestmark = pytest.mark.network


@pytest.fixture(scope="module")
def pwfile(tmp_path_factory: pytest.TempPathFactory) -> Path:
    p = tmp_path_factory.mktemp("pw") / "admin.pw"
    p.write_text("secret1\n")
    return p


def mk(pwfile: Path, *args: str, env: dict[str, str] | None = None) -> Result:
    return CliRunner().invoke(
        cli, [*args, "--user", "admin", "--password-file", str(pwfile)], env=env
    )


def ok(res: Result) -> str:
    assert res.exit_code == 0, res.output
    return res.output


def one_error(res: Result) -> str:
    assert res.exit_code == 1, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: "), res.output
    return lines[0]


def test_info(peer: Peer, pwfile: Path) -> None:
    data = json.loads(ok(mk(pwfile, "aria", "info", peer.address, "--json")))
    assert data["map"] == peer.mapname() and data["commands"] == 40
    assert all(data["can"].values())
    assert (
        data["map_id"]["md5"]
        == __import__("hashlib").md5((peer.root / data["map"]).read_bytes()).hexdigest()
    )
    text = ok(mk(pwfile, "aria", "info", peer.address))
    assert f"active map: {data['map']}" in text and "this user can: fetch map" in text
    # the mapper user, password from the environment: map service only
    res = CliRunner().invoke(
        cli,
        ["aria", "info", peer.address, "-u", "mapper"],
        env={"MAPKIT_ARIA_PASSWORD": "map2pw", "MAPKIT_ARIA_PASSWORD_FILE": ""},
    )
    assert "not offered to this user: getDirListingMultiplePackets, getFile" in ok(res)


def test_password_never_on_the_command_line(peer: Peer, pwfile: Path, tmp_path: Path) -> None:
    res = CliRunner().invoke(
        cli, ["aria", "info", peer.address, "--user", "admin", "--password", "secret1"]
    )
    assert res.exit_code == 2 and "No such option" in res.output
    env_file = tmp_path / "pw"
    env_file.write_text("secret1")
    res = CliRunner().invoke(
        cli,
        ["aria", "info", peer.address, "-u", "admin"],
        env={"MAPKIT_ARIA_PASSWORD_FILE": str(env_file), "MAPKIT_ARIA_PASSWORD": "wrong"},
    )
    ok(res)  # the file wins over the variable
    line = one_error(
        CliRunner().invoke(
            cli,
            ["aria", "info", peer.address, "-u", "admin"],
            env={"MAPKIT_ARIA_PASSWORD": "wrong", "MAPKIT_ARIA_PASSWORD_FILE": ""},
        )
    )
    assert "refused the login for user 'admin': wrong user name or password" in line
    assert "wrong" not in line.replace("wrong user", "")
    line = one_error(
        CliRunner().invoke(
            cli,
            [
                "aria",
                "info",
                peer.address,
                "-u",
                "admin",
                "--password-file",
                str(tmp_path / "missing"),
            ],
        )
    )
    assert "missing: cannot read the password file" in line


def test_fetch_get_put_ls_rm(
    peer: Peer, pwfile: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    active = peer.mapname()
    out = ok(mk(pwfile, "aria", "fetch", peer.address))
    assert (tmp_path / active).read_bytes() == (peer.root / active).read_bytes()
    assert "matches the robot's map id" in out
    out = ok(mk(pwfile, "aria", "fetch", peer.address, "--via", "map", "-o", "rebuilt.map"))
    assert "rebuilt by the robot's map service" in out
    got = json.loads(
        ok(
            mk(
                pwfile,
                "aria",
                "fetch",
                peer.address,
                "--name",
                "aria275-columbia.map",
                "-o",
                "c.map",
                "--json",
            )
        )
    )
    assert (
        got["source"] == "file"
        and (tmp_path / "c.map").read_bytes() == (peer.root / "aria275-columbia.map").read_bytes()
    )
    log = tmp_path / "run1.2d"
    log.write_bytes(os.urandom(70_000))
    ok(mk(pwfile, "aria", "put", str(log), peer.address, "run1.2d"))
    assert peer.probe_get("run1.2d", tmp_path / "probe.2d") == log.read_bytes()
    listing = json.loads(ok(mk(pwfile, "aria", "ls", peer.address, "--json")))
    assert {"name": "run1.2d", "type": "file", "size": 70_000} in [
        {k: e[k] for k in ("name", "type", "size")} for e in listing["entries"]
    ]
    assert "run1.2d" in ok(mk(pwfile, "aria", "ls", peer.address))
    ok(mk(pwfile, "aria", "get", peer.address, "run1.2d", "-o", "back.2d"))
    assert (tmp_path / "back.2d").read_bytes() == log.read_bytes()
    ok(mk(pwfile, "aria", "rm", peer.address, "run1.2d"))
    assert not (peer.root / "run1.2d").exists()
    assert "does not exist" in one_error(
        mk(pwfile, "aria", "get", peer.address, "run1.2d", "-o", "gone.2d")
    )
    assert not (tmp_path / "gone.2d").exists()


def test_send_load_and_rollback(peer: Peer, pwfile: Path, shared_dir: Path) -> None:
    before = peer.mapname()
    tri = shared_dir / "real" / "aria-triangle.map"
    out = ok(mk(pwfile, "aria", "send", str(tri), peer.address, "--name", "cli-tri.map", "--load"))
    assert "active map on" in out and peer.mapname() == "cli-tri.map"
    ex4 = shared_dir / "real" / "omron-ld-showroom-ex4.map"
    line = one_error(mk(pwfile, "aria", "send", str(ex4), peer.address, "--load"))
    assert "could not load 'omron-ld-showroom-ex4.map'" in line and "restored" in line
    assert peer.mapname() == "cli-tri.map"
    assert (peer.root / ex4.name).read_bytes() == ex4.read_bytes()  # the robot's own copy is back
    ok(mk(pwfile, "aria", "send", str(peer.root / before), peer.address, "--load"))
    assert peer.mapname() == before


def test_user_without_file_rights_gets_one_line(peer: Peer, tmp_path: Path) -> None:
    env = {"MAPKIT_ARIA_PASSWORD": "map2pw", "MAPKIT_ARIA_PASSWORD_FILE": ""}
    for args in (
        ["get", peer.address, "aria-office.map", "-o", str(tmp_path / "x.map")],
        ["put", str(ROOT / "README.md"), peer.address, "x.md"],
        ["ls", peer.address],
        ["rm", peer.address, "aria-office.map"],
    ):
        res = CliRunner().invoke(cli, ["aria", *args, "-u", "mapper"], env=env)
        assert "does not offer" in one_error(res) and "to user 'mapper'" in res.output
    res = CliRunner().invoke(
        cli, ["aria", "fetch", peer.address, "-u", "mapper", "-o", str(tmp_path / "m.map")], env=env
    )
    assert "rebuilt by the robot's map service" in ok(res)
    assert leftovers(tmp_path) == ["m.map"]


def test_watch_prints_changes_and_keeps_versions(peer: Peer, pwfile: Path, tmp_path: Path) -> None:
    before = peer.mapname()
    env = dict(os.environ, MAPKIT_ARIA_PASSWORD_FILE=str(pwfile))
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "mapkit",
            "aria",
            "watch",
            peer.address,
            "-u",
            "admin",
            "--save-dir",
            str(tmp_path / "v"),
            "--count",
            "1",
            "--json",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        cwd=ROOT,
    )
    try:
        assert proc.stdout is not None
        first = json.loads(proc.stdout.readline())
        assert first["initial"] and first["name"] == before
        other = "aria-triangle.map" if before != "aria-triangle.map" else "aria-office.map"
        assert "save succeeded" in peer.probe("setmap", other, "5").stdout
        second = json.loads(proc.stdout.readline())
        assert proc.wait(30) == 0, proc.stderr.read() if proc.stderr else ""
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert not second["initial"] and second["name"] == other
    assert Path(second["saved"]).read_bytes() == (peer.root / other).read_bytes()
    assert len(list((tmp_path / "v").iterdir())) == 2
    peer.probe("setmap", before, "5")


def test_cli_server_killed_mid_download(tmp_path: Path) -> None:
    """`mapkit aria get` of a 40 MB file; the server is SIGKILLed once 1 MB has arrived."""
    from tests.arnet.peer import start_peer

    big = tmp_path / "big.bin"
    big.write_bytes(os.urandom(40_000_000))
    p = start_peer(tmp_path / "srv", [big], login=None)
    out = tmp_path / "out"
    out.mkdir()
    big.unlink()
    try:
        proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "mapkit",
                "aria",
                "get",
                p.address,
                "big.bin",
                "-o",
                str(out / "big.bin"),
                "--timeout",
                "5",
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            cwd=ROOT,
        )
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and proc.poll() is None:
            if sum(f.stat().st_size for f in out.iterdir()) > 1_000_000:
                p.proc.kill()
                break
            time.sleep(0.002)
        _stdout, stderr = proc.communicate(timeout=60)
    finally:
        p.stop()
    assert proc.returncode == 1, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: "), stderr
    assert "closed the connection" in lines[0] or "broke" in lines[0], stderr
    assert leftovers(out) == []
