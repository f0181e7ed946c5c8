"""Headless Chromium under Selenium for the editor's browser tests and its benchmark."""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

CHROMEDRIVER = os.environ.get("MAPKIT_CHROMEDRIVER", "/usr/bin/chromedriver")
CHROMIUM = os.environ.get("MAPKIT_CHROMIUM", "/usr/bin/chromium")
FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
)
INSTALL_HINT = (
    "headless Chromium is needed: apt-get install chromium chromium-driver "
    "(scripts/setup does) and pip install selenium (the test extra)"
)


def missing() -> str | None:
    """Why the browser cannot run here, or None when it can."""
    try:
        import selenium  # noqa: F401
    except ImportError:
        return INSTALL_HINT
    for f in (CHROMEDRIVER, CHROMIUM):
        if not (os.path.exists(f) or shutil.which(f)):
            return f"{f} not found; {INSTALL_HINT}"
    return None


@contextmanager
def chromium(width: int = 1200, height: int = 800) -> Iterator[Any]:
    """A fresh headless Chromium (own profile folder, browser console log kept)."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    profile = tempfile.mkdtemp(prefix="mapkit-chromium-")
    opts = webdriver.ChromeOptions()
    opts.binary_location = shutil.which(CHROMIUM) or CHROMIUM
    for f in FLAGS:
        opts.add_argument(f)
    opts.add_argument(f"--user-data-dir={profile}")
    opts.add_argument(f"--window-size={width},{height}")
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)
    try:
        yield driver
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


def console_errors(driver: Any) -> list[str]:
    """The browser console's errors since the last call (SEVERE entries)."""
    return [e["message"] for e in driver.get_log("browser") if e.get("level") == "SEVERE"]
