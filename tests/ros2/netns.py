"""A private network namespace with only ``lo`` (multicast on), so DDS discovery stays local.

A holder process (``unshare -n``, ``-rn`` when not root) keeps the namespace alive; commands
run inside it through ``nsenter``. Shared by the tests and benchmarks/bench_ros2.py.
"""

from __future__ import annotations

import os
import shutil
import subprocess

SETUP = (
    "ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo "
    "&& echo ready && exec sleep 100000"
)


class NetNs:
    """Start with :meth:`start`; :meth:`wrap` prefixes a command to run it inside."""

    def __init__(self) -> None:
        self.proc: subprocess.Popen[str] | None = None
        self.root = os.geteuid() == 0

    def start(self) -> NetNs:
        for tool in ("unshare", "nsenter", "ip"):
            if shutil.which(tool) is None:
                raise RuntimeError(f"{tool} not found (Debian: util-linux, iproute2)")
        cmd = ["unshare", "-n" if self.root else "-rn", "sh", "-c", SETUP]
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        if line.strip() != "ready":
            self.proc.kill()
            raise RuntimeError(f"cannot make a network namespace: {self.proc.stderr.read()}")  # type: ignore[union-attr]
        return self

    def wrap(self, cmd: list[str]) -> list[str]:
        assert self.proc is not None
        user = [] if self.root else ["-U", "--preserve-credentials"]
        return ["nsenter", "-t", str(self.proc.pid), *user, "-n", *cmd]

    def stop(self) -> None:
        if self.proc is not None:
            self.proc.kill()
            self.proc.wait()
