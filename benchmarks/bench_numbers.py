"""The .map header reader's numbers: ordinary headers and hostile ones, with ratios from one run.

    python benchmarks/bench_numbers.py [--repeat N]

Prints wall-clock seconds (best of N) and ratios against baselines measured in the same run:

* an ordinary header: 20,000 ``Cairn:`` lines and 2,000 info lines, read by ``mapkit.loads``,
  against reading the same objects' numbers with Python's ``float()`` (the floor for any reader
  that turns each number into a double);
* hostile numbers (a ``Cairn:`` line, ``OriginLatLongAlt:`` and data rows with N digits, some
  ending in a letter so that no number matches): the time for 10 N digits over the time for N.
  A linear reader gives about 10; the backtracking regex it replaced gave about 100 (44 s at
  50,000 digits).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from _timing import best

import mapkit


def ordinary_header(n_objects: int = 20_000, n_info: int = 2_000) -> bytes:
    lines = ["2D-Map", "MinPos: -50000 -50000", "MaxPos: 50000 50000", "Resolution: 20"]
    lines += [f'MapInfo: GoalType Name=T{i} "Label=Type {i}"' for i in range(n_info)]
    for i in range(n_objects):
        x, y, th = (i * 37) % 90000 - 45000, (i * 53) % 90000 - 45000, (i % 360) - 179.5
        if i % 4:
            lines.append(f'Cairn: Goal {x} {y} {th:f} "" ICON "g{i}"')
        else:
            lines.append(f'Cairn: ForbiddenArea 0 0 {th:f} "" ICON "" {x} {y} {x + 500} {y + 700}')
    return ("\n".join(lines) + "\nDATA\n1 1\n").encode()


def hostile(digits: int) -> bytes:
    d = "9" * digits
    return (
        f"2D-Map\nOriginLatLongAlt: {d} 0.{d} 1\n"
        f'Cairn: Goal {d} -{d}.5 1e{d} "" ICON "g"\n'
        f'_Cairn: Goal 1{d}x 1 0 "" ICON "bad"\n'
        f"MinPos: {d} -{d}\nDATA\n{d} 1\n1 -{d}\n"
    ).encode()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()

    text = ordinary_header()
    numbers = [
        tok
        for line in text.decode().splitlines()
        if line.startswith("Cairn:")
        for tok in line.split()[2:5] + line.split()[8:12]
    ]
    t_load = best(lambda: mapkit.loads(text), args.repeat)
    t_float = best(lambda: [float(t) for t in numbers], args.repeat)
    print(f"ordinary header ({len(text):,} bytes, {len(numbers):,} numbers):")
    print(f"  mapkit.loads            {t_load:8.4f} s")
    print(f"  float() on the numbers  {t_float:8.4f} s   loads / float() = {t_load / t_float:5.1f}")

    print("hostile numbers (mapkit.recover on a map whose numbers have N digits):")
    base = None
    for n in (50_000, 500_000, 5_000_000):
        data = hostile(n)
        t = best(lambda data=data: mapkit.recover(data), max(1, args.repeat // 2))
        ratio = "" if base is None else f"   time / time at 10x fewer digits = {t / base:5.1f}"
        print(f"  N = {n:>9,}  {t:8.4f} s{ratio}")
        base = t


if __name__ == "__main__":
    main()
