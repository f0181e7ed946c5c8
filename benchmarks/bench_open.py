"""Benchmark: ``mapkit open`` in headless Chromium on the 1,000,000-point benchmark map.

Measures, for the big map and (as the baseline, in the same run) the small bundled office map:

* open: reading the file and indexing it for tiles (server side);
* first full paint: from navigation start to the moment every visible tile of the first view
  has loaded (Leaflet's tile layer ``load`` event, ``performance.now()``);
* frames per second (``requestAnimationFrame`` counting) while the real mouse drags the map
  about (strokes of 20 steps of 10 px, new tiles coming from the server as the view moves) and
  while the real wheel zooms in and out (Leaflet's animated zoom);
* the same, scripted, in the worst case for the page: ``panBy`` every frame (each frame is a
  whole move, so Leaflet re-lays tiles and vectors every frame) and ``setZoom`` every 15 frames.

Targets: first paint < 2 s, panning >= 30 fps.

    python benchmarks/bench_open.py [--seconds S] [--keep DIR] [--screenshot PNG]
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bigmap import write_big_map  # noqa: E402

from mapkit.open.server import Editor  # noqa: E402
from tests.open.browser import chromium, console_errors, missing  # noqa: E402

# Runs in the page: move the view every frame for `seconds`, count frames; return fps.
MOTION = """
const [kind, seconds, done] = arguments;
const map = mapkit.map;
let frames = 0, t0 = null, k = 0;
function step(now) {
  if (t0 === null) t0 = now;
  if (now - t0 >= seconds * 1000) { done([frames / ((now - t0) / 1000), frames]); return; }
  frames++; k++;
  if (kind === 'pan') {
    const a = k / 90;
    map.panBy([12 * Math.cos(a), 12 * Math.sin(a)], {animate: false});
  } else if (k % 15 === 0) {
    const z = map.getZoom();
    map.setZoom(((k / 15) % 4) < 2 ? z + 1 : z - 1, {animate: false});
  }
  requestAnimationFrame(step);
}
requestAnimationFrame(step);
"""


COUNT_START = """
window.__frames = 0; window.__t0 = performance.now(); window.__counting = true;
const tick = () => {
  if (window.__counting) { window.__frames++; requestAnimationFrame(tick); }
};
requestAnimationFrame(tick);
"""
COUNT_STOP = """
window.__counting = false;
return window.__frames / ((performance.now() - window.__t0) / 1000);
"""


def by_hand(d: Any, kind: str, seconds: float) -> float:
    """Frames per second while the real mouse drags the map, or the real wheel zooms it."""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.actions.wheel_input import ScrollOrigin
    from selenium.webdriver.common.by import By

    map_el = d.find_element(By.ID, "map")
    d.execute_script(COUNT_START)
    end = time.monotonic() + seconds
    k = 0
    while time.monotonic() < end:
        if kind == "drag":
            chain = ActionChains(d, duration=16).move_to_element(map_el).click_and_hold()
            a = k * 2.0  # a stroke of 20 steps of 10 px from the centre, each in a new direction
            for _ in range(20):
                chain = chain.move_by_offset(round(10 * math.cos(a)), round(10 * math.sin(a)))
            chain.release().perform()
        else:
            origin = ScrollOrigin.from_element(map_el)
            ActionChains(d).scroll_from_origin(origin, 0, -100 if k % 4 < 2 else 100).perform()
            time.sleep(0.35)  # Leaflet animates each zoom step for 0.25 s
        k += 1
    return float(d.execute_script(COUNT_STOP))


def measure(path: Path, seconds: float, screenshot: Path | None = None) -> dict[str, Any]:
    t = time.perf_counter()
    ed = Editor.open(path)
    ed.app.session.describe()
    opened = time.perf_counter() - t
    ed.start()
    try:
        with chromium(1280, 800) as d:
            d.set_script_timeout(seconds * 4 + 30)
            d.get(ed.url("/"))
            end = time.monotonic() + 60
            while not d.execute_script("return window.mapkit && window.mapkit.firstPaint"):
                if time.monotonic() > end:
                    raise SystemExit("the page did not paint within 60 s")
                time.sleep(0.02)
            paint_ms = d.execute_script("return window.mapkit.firstPaint")
            if screenshot is not None:
                d.save_screenshot(str(screenshot))
            d.execute_script("mapkit.map.setZoom(mapkit.map.getZoom() + 2, {animate: false})")
            time.sleep(1.0)
            drag = by_hand(d, "drag", seconds)
            wheel = by_hand(d, "wheel", seconds)
            pan = d.execute_async_script(MOTION, "pan", seconds)
            zoom = d.execute_async_script(MOTION, "zoom", seconds)
            errors = console_errors(d)
    finally:
        ed.stop()
    return {
        "open": opened,
        "paint": paint_ms / 1000.0,
        "drag": drag,
        "wheel": wheel,
        "pan": pan[0],
        "zoom": zoom[0],
        "errors": errors,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=4.0, help="Length of each motion test.")
    ap.add_argument("--keep", type=Path, help="Write the big map here (default: a temp folder).")
    ap.add_argument("--screenshot", type=Path, help="Save the big map's first view as this PNG.")
    args = ap.parse_args()
    why = missing()
    if why:
        raise SystemExit(why)
    out = args.keep or Path(tempfile.mkdtemp(prefix="mapkit-bench-"))
    out.mkdir(parents=True, exist_ok=True)
    big = write_big_map(out / "bigmap.map")
    small = ROOT / "mapkit" / "sample_maps" / "office.map"
    base = measure(small, args.seconds)
    res = measure(big, args.seconds, args.screenshot)
    print(f"{'':30s} {'office.map':>11s} {'1M points':>11s} {'x office':>9s}  target")
    rows = [
        ("open + index (s)", "open", ""),
        ("first full paint (s)", "paint", "< 2 s"),
        ("panning, mouse drag (fps)", "drag", ">= 30 fps"),
        ("zooming, mouse wheel (fps)", "wheel", ""),
        ("panBy every frame (fps)", "pan", ""),
        ("setZoom every 15 (fps)", "zoom", ""),
    ]
    for label, key, target in rows:
        ratio = res[key] / base[key]
        print(f"{label:30s} {base[key]:11.3f} {res[key]:11.3f} {ratio:9.2f}  {target}")
    ok = res["paint"] < 2.0 and res["drag"] >= 30.0
    print(f"targets {'met' if ok else 'NOT met'}; console errors: {len(res['errors'])}")
    for e in res["errors"][:5]:
        print("  ", e)


if __name__ == "__main__":
    main()
