"""A real ROS 1 master for the ROS tests: ``roscore -p <free port>`` on 127.0.0.1, one per module.

Every test here talks to a real ``roscore`` through real ``rospy`` nodes (each in its own
process: rospy allows one node per process) and checks results with ROS's own ``rostopic`` and
``rosservice``. When ROS is missing the tests fail under ``CI=true`` and skip elsewhere, with the
Debian packages to install.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import xmlrpc.client
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import IN_CI, ROOT

#: What `scripts/setup` installs for the ROS parts.
ROS_APT = (
    "ros-core python3-rospy python3-std-msgs python3-nav-msgs python3-geometry-msgs "
    "python3-std-srvs python3-rostopic python3-rosservice"
)
ROS_MODULES = (
    "rospy",
    "rosgraph",
    "std_msgs.msg",
    "nav_msgs.msg",
    "nav_msgs.srv",
    "geometry_msgs.msg",
    "std_srvs.srv",
)
ROS_TOOLS = ("roscore", "rostopic", "rosservice")


def ros_missing() -> str | None:
    """What of ROS 1 is missing here (``None`` when everything is installed)."""
    import importlib

    missing = [t for t in ROS_TOOLS if shutil.which(t) is None]
    for mod in ROS_MODULES:
        try:
            importlib.import_module(mod)
        except ImportError:
            missing.append(mod)
    return ", ".join(missing) or None


def require_ros() -> None:
    """Fail (CI) or skip (elsewhere) when ROS 1 is not installed."""
    missing = ros_missing()
    if missing:
        message = (
            f"ROS 1 is missing ({missing}): install it with "
            f"`sudo apt-get install {ROS_APT}` (or run ./scripts/setup)"
        )
        if IN_CI:
            pytest.fail(message)
        pytest.skip(message)


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nobody listens on right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class Ros:
    """A running roscore and the environment that points ROS processes at it."""

    uri: str
    env: dict[str, str]
    home: Path
    procs: list[subprocess.Popen[bytes]] = field(default_factory=list)

    def run(
        self, args: Sequence[str], timeout: float = 60, check: bool = True, **kw: Any
    ) -> subprocess.CompletedProcess[str]:
        """Run a command against this master and wait for it (text output)."""
        res = subprocess.run(
            list(args),
            env=kw.pop("env", self.env),
            capture_output=True,
            text=True,
            timeout=timeout,
            cwd=kw.pop("cwd", ROOT),
            **kw,
        )
        if check and res.returncode != 0:
            raise AssertionError(
                f"{' '.join(args)} exited {res.returncode}:\n{res.stdout}\n{res.stderr}"
            )
        return res

    def mapkit(
        self, *args: str, timeout: float = 90, check: bool = True, **kw: Any
    ) -> subprocess.CompletedProcess[str]:
        """Run ``python -m mapkit ARGS`` against this master."""
        return self.run([sys.executable, "-m", "mapkit", *args], timeout=timeout, check=check, **kw)

    def start(self, args: Sequence[str], **kw: Any) -> subprocess.Popen[bytes]:
        """Start a background process (its own process group); stopped at teardown."""
        fd, log_path = tempfile.mkstemp(dir=self.home, prefix="proc-", suffix=".log")
        with os.fdopen(fd, "wb") as log:
            proc = subprocess.Popen(
                list(args),
                env=kw.pop("env", self.env),
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
                cwd=kw.pop("cwd", ROOT),
                **kw,
            )
        proc.log_path = Path(log_path)  # type: ignore[attr-defined]
        self.procs.append(proc)
        return proc

    def start_mapkit(self, *args: str, **kw: Any) -> subprocess.Popen[bytes]:
        """Start ``python -m mapkit ARGS`` in the background."""
        return self.start([sys.executable, "-m", "mapkit", *args], **kw)

    @staticmethod
    def output(proc: subprocess.Popen[bytes]) -> str:
        """What a background process printed so far."""
        return Path(proc.log_path).read_text(errors="replace")  # type: ignore[attr-defined]

    def stop(
        self, proc: subprocess.Popen[bytes], sig: int = signal.SIGINT, timeout: float = 10
    ) -> int:
        """Stop a background process (its whole group); its exit code."""
        stop_group(proc, sig, timeout)
        return int(proc.returncode)

    def wait_for(self, what: str, check: Any, timeout: float = 30, interval: float = 0.1) -> Any:
        """Poll ``check()`` until it returns something true; fail the test after ``timeout``."""
        deadline = time.monotonic() + timeout
        while True:
            value = check()
            if value:
                return value
            if time.monotonic() > deadline:
                raise AssertionError(f"timed out after {timeout} s waiting for {what}")
            time.sleep(interval)

    def topics(self) -> set[str]:
        """Topics the master knows with at least one publisher."""
        state = xmlrpc.client.ServerProxy(self.uri).getSystemState("/pytest")[2]
        return {name for name, nodes in state[0] if nodes}

    def services(self) -> set[str]:
        """Services the master knows."""
        state = xmlrpc.client.ServerProxy(self.uri).getSystemState("/pytest")[2]
        return {name for name, nodes in state[2] if nodes}


def stop_group(
    proc: subprocess.Popen[bytes], sig: int = signal.SIGINT, timeout: float = 10
) -> None:
    """Signal a process group, wait, and kill it when it does not go."""
    if proc.poll() is None:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, sig)
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(10)
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(proc.pid, signal.SIGKILL)  # stragglers of the group (roscore's children)


def master_answers(uri: str) -> bool:
    """True when a ROS master answers XML-RPC at ``uri``."""
    proxy = xmlrpc.client.ServerProxy(uri)
    old = socket.getdefaulttimeout()
    socket.setdefaulttimeout(1.0)
    try:
        code, _, _ = proxy.getPid("/pytest")
        return code == 1
    except (OSError, xmlrpc.client.Error):
        return False
    finally:
        socket.setdefaulttimeout(old)


@contextlib.contextmanager
def running_roscore(tmp: Path) -> Iterator[Ros]:
    """Start ``roscore -p PORT`` in its own process group and stop it afterwards."""
    for _attempt in range(3):
        port = free_port()
        uri = f"http://127.0.0.1:{port}"
        env = dict(os.environ)
        for key in list(env):
            keep = ("ROS_DISTRO", "ROS_VERSION", "ROS_PYTHON_VERSION")
            if key.startswith("ROS_") and key not in keep:
                del env[key]
        env.update(
            ROS_MASTER_URI=uri,
            ROS_HOSTNAME="127.0.0.1",
            ROS_IP="127.0.0.1",
            ROS_HOME=str(tmp),
            ROS_LOG_DIR=str(tmp / "log"),
            PYTHONUNBUFFERED="1",
        )
        log = open(tmp / f"roscore-{port}.log", "wb")  # noqa: SIM115
        proc = subprocess.Popen(
            ["roscore", "-p", str(port)],
            env=env,
            stdout=log,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            start_new_session=True,
        )
        deadline = time.monotonic() + 30
        while proc.poll() is None and time.monotonic() < deadline and not master_answers(uri):
            time.sleep(0.1)
        if proc.poll() is None and master_answers(uri):
            break
        stop_group(proc)
        log.close()
    else:
        text = (tmp / f"roscore-{port}.log").read_text(errors="replace")
        raise AssertionError(f"roscore did not start on {uri}:\n{text}")
    ros = Ros(uri=uri, env=env, home=tmp)
    try:
        yield ros
    finally:
        for p in ros.procs:  # all at once, then wait: each takes a moment to leave the master
            if p.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(p.pid, signal.SIGINT)
        for p in reversed(ros.procs):
            stop_group(p)
        stop_group(proc)
        log.close()


@pytest.fixture(scope="module")
def ros(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Ros]:
    """A real roscore for this test module (fails in CI, skips elsewhere, when ROS is missing)."""
    require_ros()
    with running_roscore(tmp_path_factory.mktemp("roshome")) as r:
        yield r
