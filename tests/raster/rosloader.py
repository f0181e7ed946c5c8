"""An independent reading of ROS-MAPS.md's loader rules, for checking mapkit's files.

Written from the documented rules only (not from mapkit's code): parse the YAML the way
map_server does, decode PGM P5 and 8-bit grey PNG, and turn pixels into cells.
"""

from __future__ import annotations

import re
import zlib
from pathlib import Path

import numpy as np


def parse_map_yaml(path: Path) -> dict:
    """The YAML as map_server needs it; asserts every documented rule on the way."""
    import yaml

    text = path.read_text(encoding="utf-8")
    doc = yaml.safe_load(text)
    for key in ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh"):
        assert key in doc, f"required key {key} missing"
    # negate is read as an integer: the text must be 0 or 1 (not true/false/1.0).
    assert re.search(r"^negate: [01]$", text, re.M), "negate must be written as 0 or 1"
    assert isinstance(doc["negate"], int) and not isinstance(doc["negate"], bool)
    assert isinstance(doc["origin"], list) and len(doc["origin"]) == 3
    assert all(isinstance(v, float) for v in doc["origin"]), "origin holds doubles"
    assert doc.get("mode", "trinary") in ("trinary", "scale", "raw")
    assert isinstance(doc["resolution"], float) and doc["resolution"] > 0
    image = Path(doc["image"])
    doc["image_path"] = image if image.is_absolute() else path.parent / image
    return doc


def decode(path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """(grey, alpha) of a PGM P5 (maxval 255) or an 8-bit PNG (grey or grey+alpha, filter 0..4)."""
    data = path.read_bytes()
    if data[:2] == b"P5":
        fields = re.match(rb"P5(?:\s+|#[^\n]*\n)+(\d+)\s+(\d+)\s+(\d+)\s", data)
        assert fields, "bad PGM header"
        w, h, maxval = (int(x) for x in fields.groups())
        assert maxval == 255, "8-bit PGM expected"
        body = data[fields.end() :]
        assert len(body) == w * h, "PGM has exactly width*height bytes after the header"
        return np.frombuffer(body, np.uint8).reshape(h, w), None
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, ihdr = 8, b"", None
    while pos < len(data):
        n = int.from_bytes(data[pos : pos + 4], "big")
        kind, body = data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + n]
        assert zlib.crc32(kind + body) == int.from_bytes(data[pos + 8 + n : pos + 12 + n], "big")
        if kind == b"IHDR":
            ihdr = body
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    w, h = int.from_bytes(ihdr[0:4], "big"), int.from_bytes(ihdr[4:8], "big")
    depth, ctype = ihdr[8], ihdr[9]
    assert depth == 8 and ctype in (0, 4), "8-bit grey (or grey+alpha) PNG expected"
    bpp = 1 if ctype == 0 else 2
    raw = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(h, w * bpp + 1)
    assert (raw[:, 0] == 0).all(), "mapkit writes filter type 0"
    pix = raw[:, 1:].reshape(h, w, bpp)
    return pix[..., 0].copy(), (pix[..., 1].copy() if bpp == 2 else None)


def cells(yaml_path: Path) -> tuple[np.ndarray, dict]:
    """The OccupancyGrid.data map_server (ROS 1 rules) publishes for a YAML, and the YAML."""
    doc = parse_map_yaml(yaml_path)
    grey, alpha = decode(doc["image_path"])
    p = grey.astype(np.float64)
    if doc["negate"]:
        p = 255 - p
    mode = doc.get("mode", "trinary")
    if mode == "raw":
        out = p.astype(np.uint8).view(np.int8)
    else:
        occ = (255 - p) / 255
        hi, lo = doc["occupied_thresh"], doc["free_thresh"]
        out = np.where(occ > hi, 100, np.where(occ < lo, 0, -1))
        if mode == "scale":
            between = (occ <= hi) & (occ >= lo)
            if alpha is not None:
                between &= alpha > 0
            ratio = (occ - lo) / (hi - lo)
            out = np.where(between, np.trunc(1 + 98 * ratio), out)
        out = out.astype(np.int8)
    return out[::-1], doc  # image rows flipped: bottom row is row 0
