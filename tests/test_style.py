"""The habits the code keeps, checked on every test run with the tools pinned in the ``test``
extra of pyproject.toml: ``ruff check``, ``ruff format --check`` and ``mypy --strict``.

Each check fails with the tool's own report. Fix what it finds (``ruff check --fix .`` and
``ruff format .`` do most of it); a per-line ``# noqa: CODE`` is for the rare line that must
break a rule (a long URL), never a rule switched off for the whole project.
"""

from __future__ import annotations

import importlib.metadata
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import IN_CI

ROOT = Path(__file__).resolve().parent.parent
TOOLS = ("ruff", "mypy")
#: A module longer than this is a room too big to find your way in: split it along its sections.
MAX_MODULE_LINES = 800


def pinned() -> dict[str, str]:
    """The ``name==version`` pins of the test extra."""
    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    return dict(re.findall(r'"(ruff|mypy)==([^"]+)"', text))


def _require(tool: str) -> None:
    want = pinned()[tool]
    try:
        have = importlib.metadata.version(tool)
    except importlib.metadata.PackageNotFoundError:
        have = None
    if have != want:
        message = (
            f"{tool} {want} is pinned in pyproject.toml, but this environment has "
            f"{have or 'none'}: .venv/bin/pip install -e '.[test]'"
        )
        if IN_CI:
            pytest.fail(message)
        pytest.skip(message)


def run(tool: str, *args: str) -> None:
    _require(tool)
    proc = subprocess.run(
        [sys.executable, "-m", tool, *args], cwd=ROOT, capture_output=True, text=True, timeout=600
    )
    if proc.returncode != 0:
        pytest.fail(
            f"{tool} {' '.join(args)} (exit {proc.returncode}):\n{proc.stdout}{proc.stderr}",
            pytrace=False,
        )


def test_the_tools_are_pinned_exactly() -> None:
    pins = pinned()
    assert set(pins) == set(TOOLS), pins
    config = (ROOT / ".pre-commit-config.yaml").read_text(encoding="utf-8")
    for tool, version in pins.items():
        assert f"{tool}=={version}" in config, f".pre-commit-config.yaml must use {tool}=={version}"


def test_no_module_is_too_big() -> None:
    big = {}
    for path in sorted((ROOT / "mapkit").rglob("*.py")):
        with path.open(encoding="utf-8") as fh:
            lines = sum(1 for _ in fh)
        if lines > MAX_MODULE_LINES:
            big[str(path.relative_to(ROOT))] = lines
    assert not big, (
        f"modules over {MAX_MODULE_LINES} lines (split them along their sections): {big}"
    )


def test_every_test_folder_is_collected(pytestconfig: pytest.Config) -> None:
    """No folder of tests (or of the package's doctests) matches a pattern pytest skips: with
    pytest's default ``norecursedirs`` (which has ``build``) tests/build never ran."""
    import fnmatch

    skip = pytestconfig.getini("norecursedirs")
    skipped = sorted(
        str(d.relative_to(ROOT))
        for top in ("tests", "mapkit")
        for d in (ROOT / top).rglob("*")
        if d.is_dir()
        and d.name != "__pycache__"
        and any(fnmatch.fnmatch(d.name, pattern) for pattern in skip)
        and (any(d.glob("test_*.py")) or (d / "__init__.py").exists())
    )
    assert not skipped, f"pytest would never collect these folders: {skipped}"


def test_ruff_check() -> None:
    run("ruff", "check", "--no-cache", ".")


def test_ruff_format() -> None:
    run("ruff", "format", "--no-cache", "--check", ".")


@pytest.mark.slow
def test_mypy_strict() -> None:
    run("mypy", "--strict")
