"""Cold start of the ``mapkit`` command, as ratios to ``python -c "import numpy"`` in the same run.

Every case is a fresh process (the way a shell script looping over maps runs mapkit); each is
run several times, interleaved with the baseline, and the best and median wall times are kept.
The goal (issue 16): ``mapkit --help`` and ``mapkit info`` within 2x of the baseline.

    python benchmarks/bench_startup.py                 # the table
    python benchmarks/bench_startup.py --runs 20
    python benchmarks/bench_startup.py --imports info  # the 15 slowest imports of one case
                                                       # (python -X importtime)
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "mapkit" / "sample_maps" / "office.map"
MAPKIT = [sys.executable, "-c", "from mapkit.cli.main import main; main()"]

#: name -> argv. The first is the baseline.
CASES: dict[str, list[str]] = {
    "import numpy": [sys.executable, "-c", "import numpy"],
    "python (nothing)": [sys.executable, "-c", "pass"],
    "import mapkit": [sys.executable, "-c", "import mapkit"],
    "mapkit --help": [*MAPKIT, "--help"],
    "mapkit --version": [*MAPKIT, "--version"],
    "mapkit info office.map": [*MAPKIT, "info", str(SAMPLE)],
    "mapkit objects office.map": [*MAPKIT, "objects", str(SAMPLE)],
    "mapkit validate --help": [*MAPKIT, "validate", "--help"],
}
BASELINE = "import numpy"


def run_once(argv: list[str]) -> float:
    env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONDONTWRITEBYTECODE="1")
    t = time.perf_counter()
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, env=env)
    return time.perf_counter() - t


def slowest_imports(argv: list[str], n: int = 15) -> list[tuple[int, str]]:
    """The ``n`` imports with the largest cumulative time (microseconds), from -X importtime."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    res = subprocess.run(
        [argv[0], "-X", "importtime", *argv[1:]],
        capture_output=True,
        text=True,
        env=env,
        check=True,
    )
    rows = []
    for line in res.stderr.splitlines():
        if not line.startswith("import time:") or "cumulative" in line:
            continue
        _self, cumulative, name = line.split(":", 1)[1].split("|")
        rows.append((int(cumulative), name.rstrip()))
    return sorted(rows, reverse=True)[:n]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=10, help="runs per case (default 10)")
    ap.add_argument(
        "--imports",
        metavar="CASE",
        help="show the slowest imports of a case whose name contains CASE, then exit",
    )
    args = ap.parse_args()
    if args.imports:
        name = next(n for n in CASES if args.imports in n)
        print(f"slowest imports of {name!r} (cumulative microseconds):")
        for us, mod in slowest_imports(CASES[name]):
            print(f"  {us:>9}  {mod}")
        return 0
    for argv in CASES.values():  # warm the page cache and .pyc files
        run_once(argv)
    times: dict[str, list[float]] = {name: [] for name in CASES}
    for _ in range(args.runs):  # interleaved, so load on the machine hits every case alike
        for name, argv in CASES.items():
            times[name].append(run_once(argv))
    base = min(times[BASELINE])
    print(f"{'case':<28} {'best s':>8} {'median s':>9} {'best / numpy':>13}")
    for name, ts in times.items():
        print(f"{name:<28} {min(ts):>8.3f} {statistics.median(ts):>9.3f} {min(ts) / base:>13.2f}")
    print(f"goal: mapkit --help and mapkit info within 2.00x of {BASELINE!r}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
