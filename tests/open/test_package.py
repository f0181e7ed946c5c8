"""The page ships inside the wheel: its scripts, styles, and Leaflet with its licence."""

from __future__ import annotations

import re
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
STATIC = "mapkit/open/static/"


def test_the_page_refers_only_to_files_it_ships() -> None:
    html = (ROOT / STATIC / "index.html").read_text()
    refs = re.findall(r'(?:src|href)="(static/[^"?]+)', html)
    assert len(refs) >= 5 and not re.search(r'(?:src|href)="(?:https?:)?//', html)  # no CDN
    for ref in refs:
        assert (ROOT / "mapkit" / "open" / ref).is_file(), ref


@pytest.mark.slow
def test_the_wheel_holds_the_page_and_leaflet_with_its_licence(tmp_path: Path) -> None:
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(tmp_path), str(ROOT)],
        check=True,
        capture_output=True,
    )
    (wheel,) = tmp_path.glob("mapkit-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    html = (ROOT / STATIC / "index.html").read_text()
    for ref in re.findall(r'(?:src|href)="static/([^"?]+)', html):
        assert STATIC + ref in names, ref
    for f in ("vendor/leaflet/LICENSE", "vendor/leaflet/leaflet.js", "vendor/leaflet/VENDORED.md"):
        assert STATIC + f in names, f
