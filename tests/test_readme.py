"""Every command and Python block in README.md runs, so the README cannot rot; docs stand alone.

The ```sh blocks are run in order by bash with ``set -e`` in a stand-in checkout (a temporary
folder whose ``.venv`` and ``scripts`` point at the real ones), with ``HOME`` and ``TMPDIR`` in
temporary folders too; the ```python blocks then run in the tour's scratch folder. Afterwards the
stand-in checkout must hold nothing new: the README's commands leave nothing in a checkout. The
two setup commands at the top begin with ``./scripts/setup``, which CI has just run (``.ci/run``
runs exactly the README's test command, as checked below); here they run without it, and the test
command itself is not run again.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
SETUP = "./scripts/setup && "
TEST_COMMAND = "./scripts/setup && .venv/bin/python -m pytest -q -n 2"
#: What a user has: docs must not send them to files outside the checkout.
OUTSIDE = re.compile(
    r"\.\./shared|\bshared/|FORMATS\.md|ROS-MAPS\.md|TRANSFER\.md|ROS2-DDS\.md|"
    r"LANDSCAPE\.md|STYLE\.md|aria-peer"
)


def sh_blocks() -> list[str]:
    return re.findall(r"```sh\n(.*?)```", README.read_text(encoding="utf-8"), flags=re.S)


def python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), flags=re.S)


def test_readme_opens_with_the_two_commands() -> None:
    blocks = sh_blocks()
    assert blocks[0].strip().startswith(SETUP) and "mapkit demo" in blocks[0]
    assert blocks[1].strip() == TEST_COMMAND


def test_ci_runs_the_readme_test_command() -> None:
    assert TEST_COMMAND in (ROOT / ".ci" / "run").read_text()


@pytest.mark.parametrize(
    "page", [*sorted((ROOT / "docs").glob("*.md")), README], ids=lambda p: p.name
)
def test_docs_stand_on_their_own(page: Path) -> None:
    hits = [
        f"{page.name}:{n}: {line.strip()}"
        for n, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1)
        if OUTSIDE.search(line)
    ]
    assert not hits, "docs cite files a user does not have:\n" + "\n".join(hits)


def test_the_python_api_block_runs(tmp_path: Path) -> None:
    """The README's Python runs as shown (quick: on the bundled samples, without the tour)."""
    from mapkit.samples import sample_path

    for name in ("office.map", "office-loop.2d"):
        (tmp_path / name).write_bytes(Path(sample_path(name)).read_bytes())
    blocks = python_blocks()
    assert blocks and any("mapkit.edit" in b for b in blocks)
    for i, block in enumerate(blocks):
        result = subprocess.run(
            [sys.executable, "-c", block], cwd=tmp_path, capture_output=True, text=True, timeout=300
        )
        assert result.returncode == 0, f"README python block {i + 1}:\n{result.stderr[-3000:]}"


def _image_difference(a: Path, b: Path) -> float:
    """Share of pixels that differ between two PNGs of the same size (1.0 when sizes differ)."""
    from PIL import Image, ImageChops

    with Image.open(a) as ia, Image.open(b) as ib:
        if ia.size != ib.size:
            return 1.0
        diff = ImageChops.difference(ia.convert("RGB"), ib.convert("RGB")).convert("L")
        changed = sum(diff.point(lambda v: 255 if v > 48 else 0).histogram()[255:])
        return changed / (ia.size[0] * ia.size[1])


@pytest.mark.slow
def test_every_readme_command_runs(tmp_path: Path) -> None:
    checkout = tmp_path / "checkout"
    home, scratch = tmp_path / "home", tmp_path / "tmp"
    for d in (checkout, home, scratch):
        d.mkdir()
    (checkout / ".venv").symlink_to(sys.prefix)
    (checkout / "scripts").symlink_to(ROOT / "scripts")
    blocks = sh_blocks()
    script = ["set -euo pipefail"]
    for i, block in enumerate(blocks):
        text = block.strip()
        if text == TEST_COMMAND:
            continue  # the suite running this test is that command
        if text.startswith(SETUP):
            text = text[len(SETUP) :]
        script.append(f"echo '--- README block {i + 1}' >&2")
        script.append(text)
    python = [f"python - <<'MAPKIT_README_PY'\n{b}MAPKIT_README_PY" for b in python_blocks()]
    script.extend([*python, 'echo "$PWD" > "$HOME/tour-folder"'])
    env = dict(
        os.environ,
        PATH=f"{Path(sys.prefix) / 'bin'}{os.pathsep}{os.environ['PATH']}",
        HOME=str(home),
        TMPDIR=str(scratch),
    )
    env.pop("MAPKIT_SECRET", None)
    result = subprocess.run(
        ["bash", "-c", "\n".join(script)],
        cwd=checkout,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr[-4000:] + result.stdout[-2000:]
    # nothing left in the checkout; the tour's files are in its scratch folder
    assert sorted(p.name for p in checkout.iterdir()) == [".venv", "scripts"]
    tour = Path((home / "tour-folder").read_text().strip())
    assert tour.parent == scratch and (tour / "edited.map").exists()
    # the README's picture is what `mapkit demo` draws today
    drawn = home / "mapkit-demo" / "office.png"
    assert _image_difference(drawn, ROOT / "docs" / "img" / "demo-office.png") < 1e-4, (
        "docs/img/demo-office.png is stale: copy ~/mapkit-demo/office.png of `mapkit demo`"
    )
