"""The one rospy node of this process: import ROS lazily, check the master, start the node.

rospy allows one node per process and :func:`rospy.init_node` would wait forever for a master
that is not there, so :func:`start_node` first asks the master (``ROS_MASTER_URI``) for its pid
with a short timeout and raises :class:`~mapkit.ros.errors.RosError` naming the URI when nobody
answers.
"""

from __future__ import annotations

import importlib
import os
import socket
import xmlrpc.client
from types import ModuleType
from typing import Any

from mapkit.ros.errors import ROS_APT_PACKAGES, RosError, RosUnavailableError

__all__ = [
    "master_uri",
    "ros_import",
    "rospy",
    "shutdown",
    "spin",
    "start_node",
    "stop_on_signals",
    "wait_until",
]


def ros_import(name: str) -> ModuleType:
    """Import a ROS 1 Python module (``rospy``, ``nav_msgs.msg``, ...) with a clear error.

    Raises:
        RosUnavailableError: When it is not installed, naming the Debian packages to install.
    """
    try:
        return importlib.import_module(name)
    except ImportError as err:
        raise RosUnavailableError(
            f"ROS 1 is not installed ({name} cannot be imported): install it with "
            f"`sudo apt-get install {ROS_APT_PACKAGES}`"
        ) from err


def rospy() -> Any:
    """The ``rospy`` module (imported on first use)."""
    return ros_import("rospy")


def master_uri() -> str:
    """``ROS_MASTER_URI`` (ROS's default ``http://localhost:11311`` when unset)."""
    return os.environ.get("ROS_MASTER_URI", "http://localhost:11311")


def _master_answers(uri: str, timeout: float) -> bool:
    old = socket.getdefaulttimeout()
    socket.setdefaulttimeout(timeout)
    try:
        answer: Any = xmlrpc.client.ServerProxy(uri).getPid("/mapkit")
        return bool(answer[0] == 1)
    except (OSError, xmlrpc.client.Error):
        return False
    finally:
        socket.setdefaulttimeout(old)


class _OnlyMapkit:
    """Pass mapkit's records only: rospy's own go to its log file (ROS_LOG_DIR), as usual."""

    def filter(self, record: Any) -> bool:
        return bool(record.name.startswith("mapkit"))


def start_node(name: str, *, anonymous: bool = True, timeout: float = 5.0) -> str:
    """Start this process's rospy node (once); return its full name.

    Args:
        name: Base name of the node (``mapkit_send`` ...); a suffix is added when ``anonymous``.
        anonymous: Let several processes use the same base name.
        timeout: Seconds to wait for the master to answer.

    Raises:
        RosUnavailableError: When rospy is not installed.
        RosError: When no master answers at ``ROS_MASTER_URI``.
    """
    rp = rospy()
    if rp.core.is_initialized():
        return str(rp.get_name())
    uri = master_uri()
    if not _master_answers(uri, timeout):
        raise RosError(f"no ROS master answers at {uri}: start roscore or set ROS_MASTER_URI")
    # Our own signal handling: Ctrl-C is a KeyboardInterrupt; rospy shuts down at exit.
    import logging

    handlers, level = list(logging.root.handlers), logging.root.level
    rp.init_node(name, anonymous=anonymous, disable_signals=True, log_level=rp.WARN)
    # rospy configures logging with fileConfig, which replaces the root's handlers and disables
    # every logger made before it: mapkit's log lines must still reach the CLI's stderr handler.
    for h in handlers:
        if h not in logging.root.handlers:
            h.addFilter(_OnlyMapkit())
            logging.root.addHandler(h)
    logging.root.setLevel(level)
    for lname, logger in logging.root.manager.loggerDict.items():
        if lname.startswith("mapkit") and isinstance(logger, logging.Logger):
            logger.disabled = False
    return str(rp.get_name())


def wait_until(check: Any, timeout: float, interval: float = 0.02) -> bool:
    """Poll ``check()`` until it is true or ``timeout`` seconds pass (or rospy shuts down)."""
    import time

    rp = rospy()
    deadline = time.monotonic() + timeout
    while not rp.is_shutdown():
        if check():
            return True
        if time.monotonic() >= deadline:
            return False
        time.sleep(interval)
    return False


def spin(check: Any = None, interval: float = 0.1) -> None:
    """Block until Ctrl-C, SIGTERM, rospy shutting down or ``check()`` returning true.

    SIGTERM is turned into the same clean stop as Ctrl-C, so the node unregisters its topics and
    services from the master before the process ends.
    """
    import time

    rp = rospy()
    stop_on_signals()
    try:
        while not rp.is_shutdown() and not (check is not None and check()):
            time.sleep(interval)
    except KeyboardInterrupt:
        pass


def stop_on_signals() -> None:
    """Make SIGINT and SIGTERM raise :class:`KeyboardInterrupt` in the main thread.

    Also when SIGINT was ignored (a background job of a non-interactive shell), so that
    ``kill -INT`` stops a node as Ctrl-C does.
    """
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return

    def _stop(_sig: int, _frame: Any) -> None:
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, _stop)
    signal.signal(signal.SIGINT, _stop)


def shutdown(reason: str = "done") -> None:
    """Stop this process's node now (unregisters from the master)."""
    rp = rospy()
    if rp.core.is_initialized():
        rp.signal_shutdown(reason)
