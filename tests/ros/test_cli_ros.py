"""``mapkit ros`` options and refusals that come before any ROS node starts (CliRunner)."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from mapkit.cli.main import cli


@pytest.fixture
def no_secret(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("MAPKIT_SECRET", raising=False)
    monkeypatch.delenv("MAPKIT_SECRET_FILE", raising=False)


@pytest.mark.parametrize(
    "args",
    [
        ["send", "{map}"],
        ["receive"],
        ["serve", "{dir}"],
        ["fetch", "x.map"],
        ["maps"],
        ["load", "x.map"],
    ],
)
def test_every_command_wants_a_secret_or_insecure(
    runner: CliRunner, no_secret: None, args: list[str], tmp_path: Path
) -> None:
    (tmp_path / "a.map").write_bytes(b"2D-Map\nDATA\n")
    argv = ["ros", *(a.format(map=tmp_path / "a.map", dir=tmp_path) for a in args)]
    result = runner.invoke(cli, argv)
    assert result.exit_code == 2 and "no shared secret" in result.output


def test_bad_channel_is_a_usage_error(runner: CliRunner, tmp_path: Path) -> None:
    result = runner.invoke(cli, ["ros", "receive", "--channel", "2maps", "--insecure"])
    assert result.exit_code == 2 and "bad channel '2maps'" in result.output


def test_load_needs_a_name_or_rollback(runner: CliRunner) -> None:
    result = runner.invoke(cli, ["ros", "load", "--insecure"])
    assert result.exit_code == 2 and "give a map NAME or --rollback" in result.output


def test_map_server_refuses_a_missing_or_bad_map_before_starting(
    runner: CliRunner, tmp_path: Path
) -> None:
    result = runner.invoke(cli, ["ros", "map-server", str(tmp_path / "none.map")])
    assert result.exit_code == 2 and "cannot read" in result.output  # the rule of every command
    assert "no such file" in result.output
    (tmp_path / "bad.map").write_bytes(b"2D-Map\nMinPos: 1\n")
    result = runner.invoke(cli, ["ros", "map-server", str(tmp_path / "bad.map")])
    assert result.exit_code == 1 and "bad.map:2" in result.output


def test_fault_spec_is_checked() -> None:
    from mapkit.ros.errors import RosError
    from mapkit.ros.transport import Faults

    with pytest.raises(RosError, match=r"bad entry 'loss=0\.1'"):
        Faults.parse("loss=0.1")
    with pytest.raises(RosError, match="bad entry 'drop=x'"):
        Faults.parse("drop=x")
    f = Faults.parse("drop=1")
    assert f.apply(b"MKT1 frame") == [] and f.counts["dropped"] == 1
    f = Faults.parse("dup=1,seed=2")
    assert f.apply(b"abc") == [b"abc", b"abc"]
    f = Faults.parse("stall_after=2")
    data = b"MKT1\x01\x12" + bytes(40)  # a DATA frame's first bytes
    assert [len(f.apply(data)) for _ in range(4)] == [1, 1, 0, 0]
    assert f.apply(b"MKT1\x01\x13" + bytes(40)) != []  # an ACK still passes
    f = Faults.parse("corrupt=1,seed=3")
    (bad,) = f.apply(b"\x00" * 64)
    assert sum(bin(b).count("1") for b in bad) == 1  # exactly one bit flipped
