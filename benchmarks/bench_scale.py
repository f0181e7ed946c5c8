"""Big-site benchmark (issue 16): time and peak memory on the 415 x 270 m site at 2 cm.

    python benchmarks/bench_scale.py [--dir DIR] [--repeat N] [--import-cap-gb G] [--skip-import]

The site is the 1,000,000-point benchmark map's building scaled out to 415 x 270 m at the same
density (``bigmap.make_site_map``: 10.8 M points, 217,000 lines, 2,220 objects); at 2 cm its grid
is 20,805 x 13,555 = 282 M cells (the issue's 20,768 x 13,612, with a 0.5 m margin). Every
measurement runs in its own process; the figures are its wall time and its peak resident memory
(``ru_maxrss`` of that child, from ``os.wait4``):

* start-up: ``python -c "import numpy"`` (baseline), ``mapkit --help``, ``mapkit info`` of the
  bundled office map (best of ``--repeat``), as ratios to the baseline;
* ``mapkit.load`` of the site (baseline for the rest), ``mapkit info`` of the site;
* ``mapkit rasterize`` at 2 cm to PGM + YAML, and to PNG + YAML with the keepout and speed masks;
* ``mapkit render`` of the site to a 1600 px PNG;
* the map server's load of the site (``served_map``: grid and keepout mask at 2 cm) and the
  serialisation of its ``/map`` message and ``static_map`` answer (no ROS master needed);
* ``mapkit import-ros`` of the site's PGM (run under an address-space cap of ``--import-cap-gb``,
  so a whole-image reader fails with MemoryError instead of taking the machine).

The driver itself imports neither numpy nor mapkit, so a child's peak is its own.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PY = sys.executable
MAPKIT = [PY, "-m", "mapkit"]


#: The map server's work for one map, without a ROS master: what ``mapkit ros map-server`` does
#: before it publishes (rasterise, keepout mask) and what publishing costs (serialisation).
SERVE = """
import io, sys
from mapkit.ros.grids import grid_message, packed_response, served_map
served = served_map(sys.argv[1], 0.02)
msg = grid_message(served.grid)
for m in (msg, packed_response("GetMap", msg)):
    buf = io.BytesIO()
    m.serialize(buf)
    assert len(buf.getvalue()) > served.grid.width * served.grid.height
"""


def measure(
    cmd: list[str], *, cap_bytes: int | None = None, cwd: Path | None = None
) -> tuple[float, float, int, str]:
    """Run ``cmd``: (wall seconds, peak RSS in MB, exit code, last stderr line)."""

    def limit() -> None:
        if cap_bytes is not None:
            resource.setrlimit(resource.RLIMIT_AS, (cap_bytes, cap_bytes))

    t = time.perf_counter()
    proc = subprocess.Popen(
        cmd,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        cwd=cwd,
        preexec_fn=limit if cap_bytes else None,
    )
    assert proc.stderr is not None
    err = proc.stderr.read().decode("utf-8", "replace")
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t
    proc.returncode = os.waitstatus_to_exitcode(status)
    lines = [ln for ln in err.replace("\r", "\n").splitlines() if ln.strip()]
    return wall, usage.ru_maxrss / 1024.0, proc.returncode, lines[-1] if lines else ""


def best(cmd: list[str], repeat: int) -> tuple[float, float]:
    runs = [measure(cmd) for _ in range(repeat)]
    for _, _, rc, last in runs:
        if rc != 0:
            raise SystemExit(f"{' '.join(cmd)} failed: {last}")
    return min(r[0] for r in runs), max(r[1] for r in runs)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--dir", type=Path, default=None, help="keep the site and outputs here")
    ap.add_argument("--repeat", type=int, default=5, help="runs of each start-up figure")
    ap.add_argument("--import-cap-gb", type=float, default=8.0)
    ap.add_argument("--skip-import", action="store_true")
    ap.add_argument(
        "--only",
        default=None,
        metavar="WORD",
        help="run only the site steps whose label contains WORD (start-up is skipped)",
    )
    args = ap.parse_args()
    folder = args.dir or Path(tempfile.mkdtemp(prefix="mapkit-scale-"))
    folder.mkdir(parents=True, exist_ok=True)
    site = folder / "site.map"
    if not site.exists():
        gen = (
            f"import sys; sys.path.insert(0, {str(ROOT / 'benchmarks')!r}); "
            f"from pathlib import Path; from bigmap import write_site_map; "
            f"write_site_map(Path({str(site)!r}))"
        )
        subprocess.run([PY, "-c", gen], check=True)
    office = ROOT / "mapkit" / "sample_maps" / "office.map"
    rows: list[tuple[str, float, float, str]] = []

    if args.only is None:
        t_np, m_np = best([PY, "-c", "import numpy"], args.repeat)
        t_help, m_help = best([*MAPKIT, "--help"], args.repeat)
        t_info, m_info = best([*MAPKIT, "info", str(office)], args.repeat)
        print(f"start-up (best of {args.repeat}):")
        print(f"  python -c 'import numpy'   {t_np:7.3f} s  {m_np:7.0f} MB   (baseline)")
        print(
            f"  mapkit --help              {t_help:7.3f} s  {m_help:7.0f} MB   "
            f"= {t_help / t_np:.2f} x numpy import"
        )
        print(
            f"  mapkit info office.map     {t_info:7.3f} s  {m_info:7.0f} MB   "
            f"= {t_info / t_np:.2f} x numpy import"
        )

    load = f"import mapkit; m = mapkit.load({str(site)!r}); print(m.scan.num_points)"
    t_load, m_load, rc, last = measure([PY, "-c", load])
    if rc:
        raise SystemExit(f"loading the site failed: {last}")
    print(
        f"\nthe site: {site.stat().st_size / 1e6:.0f} MB .map, 415 x 270 m; at 2 cm "
        f"20,805 x 13,555 = 282 M cells"
    )
    print(f"  load (baseline)            {t_load:7.2f} s  {m_load:7.0f} MB")
    yaml_pgm, yaml_png = folder / "site.yaml", folder / "site_png.yaml"
    steps = [
        ("mapkit info site.map", [*MAPKIT, "info", str(site)], None),
        (
            "rasterize 2 cm -> PGM+YAML",
            [
                *MAPKIT,
                "rasterize",
                str(site),
                "-o",
                str(yaml_pgm),
                "--resolution",
                "0.02",
                "--force",
            ],
            None,
        ),
        (
            "rasterize 2 cm -> PNG+YAML, keepout+speed masks",
            [
                *MAPKIT,
                "rasterize",
                str(site),
                "-o",
                str(yaml_png),
                "--resolution",
                "0.02",
                "--png",
                "--keepout",
                "--speed-mask",
                "--force",
            ],
            None,
        ),
        (
            "render -> 1600 px PNG",
            [*MAPKIT, "render", str(site), "-o", str(folder / "site-pic.png"), "--force"],
            None,
        ),
        ("map server: load 2 cm + serialise /map, static_map", [PY, "-c", SERVE, str(site)], None),
    ]
    if not args.skip_import:
        cap = int(args.import_cap_gb * 2**30)
        steps.append(
            (
                f"import-ros of the PGM (cap {args.import_cap_gb:g} GB)",
                [*MAPKIT, "import-ros", str(yaml_pgm), "-o", str(folder / "back.map"), "--force"],
                cap,
            )
        )
    steps = [s for s in steps if args.only is None or args.only in s[0]]
    for label, cmd, cap in steps:
        t, peak, rc, last = measure(cmd, cap_bytes=cap)
        note = "" if rc == 0 else f"  FAILED (exit {rc}): {last[:90]}"
        rows.append((label, t, peak, note))
        print(
            f"  {label:<48} {t:7.2f} s = {t / t_load:5.2f} x load  {peak:7.0f} MB = "
            f"{peak / m_load:4.2f} x load{note}",
            flush=True,
        )
    for p in sorted(folder.glob("site*.[pPy]*")):
        if p.suffix in (".pgm", ".png"):
            print(f"  wrote {p.name}: {p.stat().st_size / 1e6:.1f} MB")
    if args.dir is None:
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
