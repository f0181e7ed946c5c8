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
from contextlib import contextmanager
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


def open_page(d: Any, ed: Editor) -> tuple[int, int]:
    """Load the page; make the map 800 x 600 px centred on a round (cx, cy) at 4 mm/px, so that
    pixel (400 + dx, 300 + dy) is (cx + 4 dx, cy - 4 dy) exactly. Returns (cx, cy)."""
    d.get(ed.url("/"))
    wait_for(d, "return window.mapkit && window.mapkit.ready && window.mapkit.firstPaint")
    (x0, y0), (x1, y1) = ed.app.session.bounds()
    cx, cy = round((x0 + x1) / 200) * 100, round((y0 + y1) / 200) * 100
    d.execute_script(
        "const el = document.getElementById('map'); el.style.right = 'auto';"
        "el.style.bottom = 'auto'; el.style.width = '800px'; el.style.height = '600px';"
        "mapkit.map.invalidateSize(false);"
        f"mapkit.map.setView([{cy}, {cx}], {ZOOM}, {{animate: false}});"
    )
    return cx, cy


@contextmanager
def serving(src: Path, folder: Path) -> Iterator[tuple[Path, Editor]]:
    """A copy of ``src`` in ``folder`` and an editor serving it until the block ends."""
    path = folder / src.name
    shutil.copyfile(src, path)
    ed = Editor.open(path)
    ed.start()
    try:
        yield path, ed
    finally:
        ed.stop()


def cli_edit(src: Path, folder: Path, edits: list[dict[str, Any]]) -> bytes:
    """The bytes `mapkit edit COPY --script` writes for these edits."""
    script = folder / "edits.json"
    script.write_text(json.dumps(edits))
    copy = folder / "cli" / src.name
    copy.parent.mkdir()
    shutil.copyfile(src, copy)
    res = CliRunner().invoke(cli, ["edit", str(copy), "--script", str(script)])
    assert res.exit_code == 0, res.output
    return copy.read_bytes()


def test_click_drag_rotate_save_gives_the_clis_bytes(
    driver: Any, shared_dir: Path, tmp_path: Path
) -> None:
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    src = shared_dir / "real" / "aria-office.map"
    d = driver
    with serving(src, tmp_path) as (path, ed):
        cx, cy = open_page(d, ed)
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
        (
            ActionChains(d)
            .move_to_element_with_offset(map_el, -100, 60)
            .click_and_hold()
            .move_by_offset(20, -20)
            .move_by_offset(20, -20)
            .release()
            .perform()
        )
        edits_done(2)
        # 3. A forbidden area by dragging a box.
        tool("area")
        (
            ActionChains(d)
            .move_to_element_with_offset(map_el, 50, -80)
            .click_and_hold()
            .move_by_offset(50, 25)
            .move_by_offset(50, 25)
            .release()
            .perform()
        )
        edits_done(3)
        # 4. Rotate it with its handle (the new area is selected; the handle is above its centre).
        tool("select")
        handle = d.find_element(By.CSS_SELECTOR, ".handle.rotate")
        hx, hy = d.execute_script(
            "const p = mapkit.map.latLngToContainerPoint("
            "  mapkit.map.layerPointToLatLng(L.DomUtil.getPosition(arguments[0])));"
            "return [p.x, p.y];",
            handle,
        )
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
            {
                "add-dock": {
                    "name": "Dock1",
                    "x": round(at(-100, 60)[0]),
                    "y": round(at(-100, 60)[1]),
                    "heading": 45,
                }
            },
            {"forbid": {"area": [*map(round, at(50, -80)), *map(round, at(150, -30))]}},
            {"move": {"name": f"#{n}", "heading": round(turn)}},
        ]
        assert ed.app.session.edits == expected

        d.find_element(By.ID, "save").click()
        wait_for(d, "return document.getElementById('status').textContent.startsWith('wrote')")
        assert path.read_bytes() == cli_edit(src, tmp_path, expected)

        # The picture for docs/open.md: the whole map, findings shown, the area selected.
        d.execute_script(
            "const el = document.getElementById('map'); el.style.width = ''; el.style.height = '';"
            "el.style.right = ''; el.style.bottom = ''; mapkit.map.invalidateSize(false);"
        )
        d.find_element(By.ID, "validate").click()
        wait_for(d, "return document.getElementById('fcount').textContent !== ''")
        d.execute_script(f"mapkit.map.setView([{cy - 300}, {cx + 800}], -3, {{animate: false}});")
        time.sleep(0.5)
        wait_for(d, "return !mapkit.tiles.isLoading()")
        # The docs' screenshot is refreshed only when asked (a test run leaves the checkout alone).
        shot = (
            DOCS_IMG / "open-editor.png"
            if os.environ.get("MAPKIT_UPDATE_DOCS")
            else tmp_path / "open-editor.png"
        )
        d.save_screenshot(str(shot))
        assert shot.stat().st_size > 0
        assert console_errors(d) == []


def test_every_tool_undo_redo_and_the_external_change(
    driver: Any, shared_dir: Path, tmp_path: Path
) -> None:
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select

    src = shared_dir / "real" / "amrisim-AMROffice.map"  # declares Sim.BoxObstacle (a sector)
    d = driver
    with serving(src, tmp_path) as (path, ed):
        cx, cy = open_page(d, ed)
        n0 = len(ed.app.session.map.objects)
        map_el = d.find_element(By.ID, "map")
        done = [0]

        def px(dx: int, dy: int) -> list[int]:
            return [round(cx + MM * dx), round(cy - MM * dy)]

        def tool(name: str) -> None:
            d.find_element(By.CSS_SELECTOR, f'#tools button[data-tool="{name}"]').click()

        def step(n: int = 1) -> None:
            done[0] += n
            wait_for(d, f"return mapkit.state.doc.edits.length === {done[0]}")

        def drag(a: tuple[int, int], b: tuple[int, int]) -> None:
            mid = ((b[0] - a[0]) // 2, (b[1] - a[1]) // 2)
            (
                ActionChains(d)
                .move_to_element_with_offset(map_el, *a)
                .click_and_hold()
                .move_by_offset(*mid)
                .move_by_offset(b[0] - a[0] - mid[0], b[1] - a[1] - mid[1])
                .release()
                .perform()
            )

        def button(id_: str) -> None:
            d.find_element(By.ID, id_).click()

        expected: list[dict[str, Any]] = []
        tool("goal")
        ActionChains(d).move_to_element_with_offset(map_el, 0, 0).click().perform()
        step()
        expected.append({"add-goal": {"name": "Goal1", "x": cx, "y": cy}})
        goal = f"#{n0 + 1}"
        # Select it by a click, move it with the centre handle, rename and turn it in the panel.
        tool("select")
        ActionChains(d).move_to_element_with_offset(map_el, 0, 0).click().perform()
        wait_for(d, "return !document.getElementById('selection').hidden")
        handle = d.find_element(By.CSS_SELECTOR, ".handle.move")
        chain = ActionChains(d).click_and_hold(handle)
        for _ in range(5):
            chain = chain.move_by_offset(5, 2).pause(0.05)
        chain.pause(0.2).release().perform()
        step()
        expected.append({"move": {"name": goal, "x": px(25, 10)[0], "y": px(25, 10)[1]}})
        name = d.find_element(By.ID, "sel-name")
        name.clear()
        name.send_keys("Coffee")
        button("sel-rename")
        step()
        expected.append({"rename": {"name": goal, "new-name": "Coffee"}})
        heading = d.find_element(By.ID, "sel-heading")
        heading.clear()
        heading.send_keys("90")
        button("sel-turn")
        step()
        expected.append({"move": {"name": goal, "heading": 90}})
        d.find_element(By.ID, "search").send_keys("coff")
        rows = d.find_elements(By.CSS_SELECTOR, "#objects li")
        assert [r.text for r in rows] == [f"{goal} GoalWithHeading Coffee"]
        # The drawing tools.
        tool("fline")
        drag((-150, 100), (-50, 120))
        step()
        expected.append({"forbid": {"line": [*px(-150, 100), *px(-50, 120)]}})
        tool("wall")
        drag((-150, -100), (150, -100))
        step()
        expected.append({"draw-line": {"line": [*px(-150, -100), *px(150, -100)]}})
        tool("erasebox")
        drag((-300, -250), (-100, -150))
        step()
        expected.append({"erase": {"box": [*px(-300, -250), *px(-100, -150)]}})
        tool("erasepoly")
        chain = ActionChains(d)
        for corner in ((100, 100), (300, 100), (300, 250)):
            chain = chain.move_to_element_with_offset(map_el, *corner).click().pause(0.1)
        chain.move_to_element_with_offset(map_el, 102, 101).click().perform()  # the first again
        step()
        expected.append({"erase": {"polygon": [px(100, 100), px(300, 100), px(300, 250)]}})
        tool("object")
        Select(d.find_element(By.ID, "type")).select_by_value("Sim.BoxObstacle")
        drag((200, -250), (260, -200))
        step()
        expected.append(
            {
                "add-object": {
                    "type": "Sim.BoxObstacle",
                    "name": "Sim.BoxObstacle1",
                    "params": {},
                    "area": [*px(200, -250), *px(260, -200)],
                }
            }
        )
        # Undo and redo with the buttons, then delete the goal with the Delete button.
        button("undo")
        wait_for(d, f"return mapkit.state.doc.edits.length === {done[0] - 1}")
        button("redo")
        wait_for(d, f"return mapkit.state.doc.edits.length === {done[0]}")
        tool("select")
        d.find_element(By.ID, "search").clear()
        d.find_element(By.ID, "search").send_keys("Coffee")
        d.find_element(By.CSS_SELECTOR, "#objects li").click()
        button("sel-delete")
        step()
        expected.append({"remove": {"names": [goal]}})
        assert ed.app.session.edits == expected

        # Another program changes the file: saving is refused and the page offers a reload.
        theirs = tmp_path / "theirs" / src.name
        theirs.parent.mkdir()
        theirs.write_bytes(src.read_bytes().replace(b"\nDATA\n", b"\nDATA\n0 0\n", 1))
        shutil.copyfile(theirs, path)
        button("save")
        wait_for(d, "return !document.getElementById('reload').hidden")
        assert "changed on disk" in d.find_element(By.ID, "status").text
        assert path.read_bytes() == theirs.read_bytes()  # untouched
        errors = console_errors(d)
        assert len(errors) == 1 and "409" in errors[0], errors  # the refused save, nothing else
        button("reload")
        wait_for(d, "return mapkit.state.doc.edits.length === 0 && !mapkit.state.doc.dirty")
        assert d.find_element(By.ID, "reload").get_attribute("hidden") is not None
        # Replay the same edits through the API and save with Ctrl+S: the CLI's bytes.
        ed.app.session.edit(expected)
        d.execute_script("mapkit.refresh()")
        wait_for(d, f"return mapkit.state.doc.edits.length === {len(expected)}")
        ActionChains(d).key_down("\ue009").send_keys("s").key_up("\ue009").perform()
        wait_for(d, "return document.getElementById('status').textContent.startsWith('wrote')")
        assert path.read_bytes() == cli_edit(theirs, tmp_path, expected)
        assert console_errors(d) == []


def test_declared_type_with_a_parameter_from_the_form(
    driver: Any, shared_dir: Path, tmp_path: Path
) -> None:
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select

    src = shared_dir / "real" / "omron-ld-showroom-ex4.map"
    d = driver
    with serving(src, tmp_path) as (path, ed):
        cx, cy = open_page(d, ed)
        d.find_element(By.CSS_SELECTOR, '#tools button[data-tool="object"]').click()
        Select(d.find_element(By.ID, "type")).select_by_value("MovementParametersSector")
        d.find_element(By.CSS_SELECTOR, '#params input[data-param="TransVelMax"]').send_keys("300")
        map_el = d.find_element(By.ID, "map")
        (
            ActionChains(d)
            .move_to_element_with_offset(map_el, -50, -50)
            .click_and_hold()
            .move_by_offset(50, 25)
            .move_by_offset(50, 25)
            .release()
            .perform()
        )
        wait_for(d, "return mapkit.state.doc.edits.length === 1")
        box = [round(cx - 50 * MM), round(cy + 50 * MM), round(cx + 50 * MM), round(cy)]
        expected = [
            {
                "add-object": {
                    "type": "MovementParametersSector",
                    "name": "MovementParametersSector1",
                    "params": {"TransVelMax": "300"},
                    "area": box,
                }
            }
        ]
        assert ed.app.session.edits == expected
        d.find_element(By.ID, "save").click()
        wait_for(d, "return document.getElementById('status').textContent.startsWith('wrote')")
        assert path.read_bytes() == cli_edit(src, tmp_path, expected)
        assert console_errors(d) == []
