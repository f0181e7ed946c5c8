"""ARIA ``.map`` files: a lossless reader (strict and tolerant) and ARIA's canonical writer.

The reader follows ARIA's two-phase parse (FORMATS.md A.3): a keyword parser for the header up
to the first data tag, then a raw reader for ``DATA``/``LINES`` rows. The writer emits exactly the
bytes ARIA's ``ArMap::writeFile`` emits (A.9). Files are handled as bytes; names are ``str``
decoded as UTF-8 with ``surrogateescape``, so every byte survives.

Where ARIA loses data (a last row without newline) mapkit keeps it and reports it; where ARIA
crashes (NaN in an object) mapkit raises :class:`~mapkit.errors.MapFormatError` in strict mode and
reports it in tolerant mode (:func:`recover`).
"""

from __future__ import annotations

from mapkit.formats.map.read import (
    load,
    loads,
    parse_map,
    recover,
)
from mapkit.formats.map.tokens import (
    tokenize as tokenize,
)
from mapkit.formats.map.writer import (
    dumpb,
    dumps,
    iter_header_lines as iter_header_lines,
    iter_map_chunks,
    save,
    written_category,
)

__all__ = [
    "dumpb",
    "dumps",
    "iter_map_chunks",
    "load",
    "loads",
    "parse_map",
    "recover",
    "save",
    "written_category",
]
