"""The editor in a real headless Chromium: click, drag and rotate with the mouse, save, and get
the bytes `mapkit edit --script` writes for the same edits. Any console error fails.

Fails (does not skip) under CI=true when Chromium, chromedriver or Selenium is missing.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from mapkit.cli.main import cli
from mapkit.open.server import Editor

from .browser import chromium, console_errors, missing

pytestmark = [pytest.mark.network, pytest.mark.slow]

DOCS_IMG = Path(__file__).resolve().parents[2] / "docs" / "img"
ZOOM = -2  # 4 mm per pixel: pixel offsets are exact millimetres
MM = 2.0**-ZOOM


@pytest.fixture(scope="module")
def driver() -> Iterator[Any]:
    why = missing()
    if why:
        if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
            pytest.fail(why)
        pytest.skip(why)
    with chromium() as d:
        yield d


def wait_for(d: Any, script: str, timeout: float = 20.0) -> Any:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = d.execute_script(script)
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for: {script}")


def test_click_drag_rotate_save_gives_the_clis_bytes(driver: Any, shared_dir: Path,
                                                     tmp_path: Path) -> None:
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    src = shared_dir / "real" / "aria-office.map"
    path = tmp_path / src.name
    shutil.copyfile(src, path)
    ed = Editor.open(path)
    ed.start()
    d = driver
    try:
        d.get(ed.url("/"))
        wait_for(d, "return window.mapkit && window.mapkit.ready && window.mapkit.firstPaint")
        (x0, y0), (x1, y1) = ed.app.session.bounds()
        cx, cy = round((x0 + x1) / 200) * 100, round((y0 + y1) / 200) * 100
        # An 800 x 600 map centred on (cx, cy) at 4 mm/px: pixel (400 + dx, 300 + dy) is
        # (cx + 4 dx, cy - 4 dy) exactly.
        d.execute_script(
            "const el = document.getElementById('map'); el.style.right = 'auto';"
            "el.style.bottom = 'auto'; el.style.width = '800px'; el.style.height = '600px';"
            "mapkit.map.invalidateSize(false);"
            f"mapkit.map.setView([{cy}, {cx}], {ZOOM}, {{animate: false}});")
        map_el = d.find_element(By.ID, "map")

        def at(dx: int, dy: int) -> tuple[float, float]:
            return (cx + MM * dx, cy - MM * dy)

        def tool(name: str) -> None:
            d.find_element(By.CSS_SELECTOR, f'#tools button[data-tool="{name}"]').click()

        def edits_done(n: int) -> None:
            wait_for(d, f"return mapkit.state.doc && mapkit.state.doc.edits.length === {n}")

        # 1. A goal by a click at a known coordinate.
        tool("goal")
        ActionChains(d).move_to_element_with_offset(map_el, 0, 0).click().perform()
        edits_done(1)
        # 2. A dock by click and drag: the drag sets its heading (45 degrees).
        tool("dock")
        (ActionChains(d).move_to_element_with_offset(map_el, -100, 60).click_and_hold()
         .move_by_offset(20, -20).move_by_offset(20, -20).release().perform())
        edits_done(2)
        # 3. A forbidden area by dragging a box.
        tool("area")
        (ActionChains(d).move_to_element_with_offset(map_el, 50, -80).click_and_hold()
         .move_by_offset(50, 25).move_by_offset(50, 25).release().perform())
        edits_done(3)
        # 4. Rotate it with its handle (the new area is selected; the handle is above its centre).
        tool("select")
        handle = d.find_element(By.CSS_SELECTOR, ".handle.rotate")
        hx, hy = d.execute_script(
            "const p = mapkit.map.latLngToContainerPoint("
            "  mapkit.map.layerPointToLatLng(L.DomUtil.getPosition(arguments[0])));"
            "return [p.x, p.y];", handle)
        chain = ActionChains(d).click_and_hold(handle)
        for _ in range(6):
            chain = chain.move_by_offset(10, 4).pause(0.05)
        chain.pause(0.2).release().perform()
        edits_done(4)

        area_c = at(100, -55)  # the box's centre: pixels (50..150, -80..-30)
        new_hx, new_hy = hx + 60 - 400, hy + 24 - 300  # the handle's drop, from the centre pixel
        world = (cx + MM * new_hx, cy - MM * new_hy)
        turn = math.degrees(math.atan2(world[1] - area_c[1], world[0] - area_c[0])) - 90
        n = ed.app.session.describe()["counts"]["objects"]  # the area is the last object
        expected = [
            {"add-goal": {"name": "Goal1", "x": cx, "y": cy}},
            {"add-dock": {"name": "Dock1", "x": round(at(-100, 60)[0]), "y": round(at(-100, 60)[1]),
                          "heading": 45}},
            {"forbid": {"area": [*map(round, at(50, -80)), *map(round, at(150, -30))]}},
            {"move": {"name": f"#{n}", "heading": round(turn)}},
        ]
        assert ed.app.session.edits == expected

        d.find_element(By.ID, "save").click()
        wait_for(d, "return document.getElementById('status').textContent.startsWith('wrote')")
        script = tmp_path / "edits.json"
        script.write_text(json.dumps(expected))
        cli_copy = tmp_path / "cli" / src.name
        cli_copy.parent.mkdir()
        shutil.copyfile(src, cli_copy)
        res = CliRunner().invoke(cli, ["edit", str(cli_copy), "--script", str(script)])
        assert res.exit_code == 0, res.output
        assert path.read_bytes() == cli_copy.read_bytes()

        # The picture for docs/open.md: the whole map, findings shown, the area selected.
        d.execute_script(
            "const el = document.getElementById('map'); el.style.width = ''; el.style.height = '';"
            "el.style.right = ''; el.style.bottom = ''; mapkit.map.invalidateSize(false);")
        d.find_element(By.ID, "validate").click()
        wait_for(d, "return document.getElementById('fcount').textContent !== ''")
        d.execute_script("const [[a, b], [c, e]] = mapkit.state.doc.bounds;"
                         "mapkit.map.fitBounds([[b, a], [e, c]], {animate: false});")
        time.sleep(0.5)
        wait_for(d, "return !mapkit.tiles.isLoading()")
        DOCS_IMG.mkdir(parents=True, exist_ok=True)
        d.save_screenshot(str(DOCS_IMG / "open-editor.png"))
        assert console_errors(d) == []
    finally:
        ed.stop()
