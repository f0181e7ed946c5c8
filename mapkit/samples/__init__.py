"""The maps and logs bundled with mapkit (``mapkit/sample_maps``), made by
``scripts/make_samples.py``."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from mapkit.errors import MapkitError

__all__ = ["list_samples", "sample_path"]


def _folder() -> Path:
    return Path(str(resources.files("mapkit") / "sample_maps"))


def list_samples() -> list[str]:
    """Names of the bundled samples (file names without folder), sorted.

    Examples:
        >>> "office.map" in list_samples()
        True
    """
    return sorted(p.name for p in _folder().iterdir() if p.suffix in (".map", ".2d"))


def sample_path(name: str) -> Path:
    """Path of a bundled sample; ``office`` finds ``office.map``, ``office-loop``
    ``office-loop.2d``.

    Args:
        name: File name, or a map's name without ``.map``.

    Returns:
        The path.

    Raises:
        MapkitError: When there is no such sample (the message lists them).
    """
    folder = _folder()
    for candidate in (name, name + ".map", name + ".2d"):
        p = folder / candidate
        if p.is_file():
            return p
    raise MapkitError(f"no bundled sample {name!r}; there are: {', '.join(list_samples())}")
