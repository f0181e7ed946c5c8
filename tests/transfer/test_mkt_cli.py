"""The transfer commands: CliRunner against an in-process server, and a real `mapkit serve`
subprocess (SIGKILLed mid-transfer, then resumed)."""

from __future__ import annotations

import hashlib
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from mkt_helpers import SECRET, client_options, listing, make_map

from mapkit.cli.main import cli
from mapkit.errors import TransferError
from mapkit.transfer import send_file


@pytest.fixture
def secret_file(tmp_path: Path) -> Path:
    f = tmp_path / "secret"
    f.write_bytes(SECRET + b"\n")
    return f


def addr(srv) -> str:
    return f"{srv.address[0]}:{srv.address[1]}"


def test_send_maps_load_fetch_json(
    tmp_path, runner, robot_dir, make_server, secret_file, monkeypatch
) -> None:
    srv = make_server()
    m = tmp_path / "office.map"
    m.write_bytes(make_map(300))
    md5 = hashlib.md5(m.read_bytes()).hexdigest()
    sf = ["--secret-file", str(secret_file)]
    r = runner.invoke(cli, ["send", str(m), addr(srv), "--json", *sf])
    assert r.exit_code == 0, r.output
    sent = json.loads(r.stdout)
    assert sent["name"] == "office.map" and sent["md5"] == md5 and sent["chunks_sent"] == 1

    r = runner.invoke(cli, ["load", addr(srv), "office.map", "--json", *sf])
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["md5"] == md5

    r = runner.invoke(cli, ["maps", addr(srv), "--json", *sf])
    maps = json.loads(r.stdout)
    assert maps["active"] == "office.map" and maps["maps"][0]["active"] is True

    r = runner.invoke(cli, ["maps", addr(srv), *sf])
    assert r.exit_code == 0 and re.search(r"^\* office\.map .* " + md5, r.stdout, re.M)

    out = tmp_path / "got.map"
    r = runner.invoke(cli, ["fetch", addr(srv), "office.map", "-o", str(out), *sf])
    assert r.exit_code == 0, r.output
    assert out.read_bytes() == m.read_bytes() and "SHA-256 verified" in r.stdout
    r = runner.invoke(
        cli, ["fetch", addr(srv), "office.map", "-o", str(out), "--if-changed", "--json", *sf]
    )
    assert json.loads(r.stdout)["modified"] is False
    (tmp_path / "into").mkdir()
    r = runner.invoke(cli, ["fetch", addr(srv), "office.map", "-o", str(tmp_path / "into"), *sf])
    assert r.exit_code == 0 and (tmp_path / "into" / "office.map").read_bytes() == m.read_bytes()
    # the file is named as the user knows it: relative to where they are, when inside it
    monkeypatch.chdir(tmp_path)
    r = runner.invoke(cli, ["fetch", addr(srv), "office.map", "-o", "here.map", *sf])
    assert r.exit_code == 0 and " into here.map: " in r.stdout, r.stdout
    r = runner.invoke(
        cli, ["fetch", addr(srv), "office.map", "-o", "here.map", "--if-changed", *sf]
    )
    assert r.stdout.startswith("here.map is up to date"), r.stdout


def test_send_with_load_and_rollback_human_output(
    tmp_path, runner, robot_dir, make_server, secret_file, monkeypatch
) -> None:
    srv = make_server()
    monkeypatch.setenv("MAPKIT_SECRET", SECRET.decode())
    a, b = tmp_path / "a.map", tmp_path / "b.map"
    a.write_bytes(make_map(10, 1))
    b.write_bytes(make_map(10, 2))
    assert runner.invoke(cli, ["send", str(a), addr(srv), "--load"]).exit_code == 0
    r = runner.invoke(cli, ["send", str(b), addr(srv), "--load"])
    assert r.exit_code == 0 and "active map on" in r.stdout and "is now b.map" in r.stdout
    r = runner.invoke(cli, ["load", addr(srv), "--rollback"])
    assert r.exit_code == 0 and "is now a.map" in r.stdout and "previous: b.map" in r.stdout


def test_cli_over_tls(tmp_path, runner, robot_dir, make_server, secret_file, cert) -> None:
    from mapkit.transfer import server_tls_context

    crt, key = cert
    srv = make_server(tls=server_tls_context(str(crt), str(key)))
    m = tmp_path / "office.map"
    m.write_bytes(make_map(200))
    sf = ["--secret-file", str(secret_file)]
    r = runner.invoke(cli, ["send", str(m), addr(srv), "--tls-ca", str(crt), *sf])
    assert r.exit_code == 0, r.output
    r = runner.invoke(cli, ["maps", addr(srv), "--tls-no-verify", "--json", *sf])
    assert json.loads(r.stdout)["maps"][0]["name"] == "office.map"
    r = runner.invoke(cli, ["maps", addr(srv), *sf])  # plain TCP to a TLS server
    assert r.exit_code == 1


def test_cli_default_port_is_the_protocol_default() -> None:
    import mapkit.cli.transfer as cli_transfer
    from mapkit.transfer import DEFAULT_PORT

    assert cli_transfer.DEFAULT_PORT == DEFAULT_PORT == 7373


def test_cli_errors_are_one_line(tmp_path, runner, robot_dir, make_server, secret_file) -> None:
    srv = make_server()
    bad = tmp_path / "bad.map"
    bad.write_bytes(b"2D-Map\nMinPos: x\nDATA\n")
    r = runner.invoke(cli, ["send", str(bad), addr(srv), "--secret-file", str(secret_file)])
    assert r.exit_code == 1
    assert "parse_error: not a valid map: bad.map:2" in r.output
    r = runner.invoke(cli, ["send", str(bad), addr(srv)], env={"MAPKIT_SECRET": ""})
    assert r.exit_code == 1 and "no shared secret" in r.output
    r = runner.invoke(cli, ["load", addr(srv)], env={"MAPKIT_SECRET": SECRET.decode()})
    assert r.exit_code == 2 and "give a map NAME or --rollback" in r.output
    r = runner.invoke(cli, ["maps", "127.0.0.1:1", "--insecure", "--timeout", "2"])
    assert r.exit_code == 1 and "cannot connect to 127.0.0.1:1" in r.output
    r = runner.invoke(cli, ["serve", str(tmp_path)], env={"MAPKIT_SECRET": ""})
    assert r.exit_code == 2 and "no shared secret" in r.output
    assert listing(robot_dir) == []


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_receive_once_gets_what_the_robot_sends(tmp_path, runner, secret_file) -> None:
    port = _free_port()
    inbox = tmp_path / "inbox"
    log = tmp_path / "scan.2d"
    log.write_bytes(os.urandom(300_000))
    result: dict = {}

    def terminal() -> None:
        result["r"] = runner.invoke(
            cli,
            [
                "receive",
                "--listen",
                f"127.0.0.1:{port}",
                "-o",
                str(inbox),
                "--once",
                "--json",
                "--secret-file",
                str(secret_file),
            ],
        )

    t = threading.Thread(target=terminal)
    t.start()
    for _ in range(100):  # wait for the terminal to listen
        try:
            send_file(log, "127.0.0.1", port, **client_options())
            break
        except TransferError:
            time.sleep(0.05)
    t.join(10)
    r = result["r"]
    assert r.exit_code == 0, r.output
    got = json.loads(r.stdout[r.stdout.index("{") :])
    assert (
        got["name"] == "scan.2d" and got["sha256"] == hashlib.sha256(log.read_bytes()).hexdigest()
    )
    assert (inbox / "scan.2d").read_bytes() == log.read_bytes()


# -- a real `mapkit serve` process -----------------------------------------------------------------


def start_serve(folder: Path, secret_file: Path) -> tuple[subprocess.Popen, int]:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    env.pop("MAPKIT_SECRET", None)
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "mapkit",
            "serve",
            str(folder),
            "--listen",
            "127.0.0.1:0",
            "--secret-file",
            str(secret_file),
        ],
        stderr=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        text=True,
        env=env,
    )
    assert proc.stderr is not None
    line = proc.stderr.readline()
    m = re.search(r"on 127\.0\.0\.1:(\d+) \(auth blake2b\|hmac-sha256", line)
    assert m, line
    threading.Thread(target=proc.stderr.read, daemon=True).start()  # keep draining the log
    return proc, int(m.group(1))


def test_serve_process_killed_mid_transfer_then_resumed(tmp_path, robot_dir, secret_file) -> None:
    chunk = 16 * 1024
    data = make_map(150_000, 3)  # ~1.8 MB, ~110 chunks
    src = tmp_path / "site.map"
    src.write_bytes(data)
    old = make_map(100, 4)
    (robot_dir / "site.map").write_bytes(old)
    proc, port = start_serve(robot_dir, secret_file)
    state = {"phase": 0, "at": 0}

    def progress(done: int, total: int) -> None:  # called after every frame
        if state["phase"] == 0 and done > total * 0.2:
            state["phase"], state["at"] = 1, done
            time.sleep(0.8)  # the robot's next write saves a checkpoint of its journal
        elif state["phase"] == 1 and done > state["at"]:
            state["phase"] = 2
            journal = robot_dir / ".site.map.mkpart.json"
            for _ in range(500):  # it got new chunks after the pause: wait for its checkpoint
                if journal.exists():
                    break
                time.sleep(0.02)
            proc.send_signal(signal.SIGKILL)
            proc.wait()

    try:
        with pytest.raises(TransferError):
            send_file(
                src,
                "127.0.0.1",
                port,
                chunk_size=chunk,
                window=4,
                progress=progress,
                **client_options(rto=2.0, progress_interval=0),
            )
        assert proc.wait(10) == -signal.SIGKILL
        # no partial file under the final name: the old map is intact
        assert (robot_dir / "site.map").read_bytes() == old
        proc, port = start_serve(robot_dir, secret_file)
        r = send_file(src, "127.0.0.1", port, chunk_size=chunk, **client_options(rto=2.0))
        assert (robot_dir / "site.map").read_bytes() == data
        # only the chunks the killed robot had not saved crossed again
        assert 0 < r["chunks_skipped"] < r["chunks"]
        assert r["chunks_distinct"] == r["chunks"] - r["chunks_skipped"]
        assert listing(robot_dir) == ["site.map"]
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            proc.wait(10)
    assert proc.returncode == 0  # SIGTERM ends the server cleanly


def test_cli_send_to_a_serve_process(tmp_path, runner, robot_dir, secret_file, shared_dir) -> None:
    real_sample = shared_dir / "real" / "aria-office.map"
    proc, port = start_serve(robot_dir, secret_file)
    try:
        r = runner.invoke(
            cli,
            [
                "send",
                str(real_sample),
                f"127.0.0.1:{port}",
                "--load",
                "--secret-file",
                str(secret_file),
                "--json",
            ],
        )
        assert r.exit_code == 0, r.output
        assert json.loads(r.stdout)["loaded"]["name"] == real_sample.name
        assert (robot_dir / "active.map").read_bytes() == real_sample.read_bytes()
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(10)
