"""Every command in README.md runs, so the README cannot rot.

The ```sh blocks are run in order, in one temporary folder, by bash with ``set -e``; ``.venv`` there
points at the environment running the tests. The two setup commands at the top begin with
``./scripts/setup``, which CI has just run (``.ci/run`` runs exactly the README's test command, as
checked below); here they run without it, and the test command itself is not run again.
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
TEST_COMMAND = "./scripts/setup && .venv/bin/python -m pytest -q"


def sh_blocks() -> list[str]:
    return re.findall(r"```sh\n(.*?)```", README.read_text(encoding="utf-8"), flags=re.S)


def test_readme_opens_with_the_two_commands() -> None:
    blocks = sh_blocks()
    assert blocks[0].strip().startswith(SETUP) and "mapkit demo" in blocks[0]
    assert blocks[1].strip() == TEST_COMMAND


def test_ci_runs_the_readme_test_command() -> None:
    assert TEST_COMMAND in (ROOT / ".ci" / "run").read_text()


@pytest.mark.slow
def test_every_readme_command_runs(tmp_path: Path) -> None:
    (tmp_path / ".venv").symlink_to(sys.prefix)
    (tmp_path / "scripts").symlink_to(ROOT / "scripts")
    blocks = sh_blocks()
    script = ["set -euo pipefail"]
    for i, block in enumerate(blocks):
        text = block.strip()
        if text == TEST_COMMAND:
            continue  # the suite running this test is that command
        if text.startswith(SETUP):
            text = text[len(SETUP):]
        script.append(f"echo '--- README block {i + 1}' >&2")
        script.append(text)
    env = dict(os.environ, PATH=f"{Path(sys.prefix) / 'bin'}{os.pathsep}{os.environ['PATH']}")
    env.pop("MAPKIT_SECRET", None)
    result = subprocess.run(["bash", "-c", "\n".join(script)], cwd=tmp_path, env=env,
                            capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-4000:] + result.stdout[-2000:]
