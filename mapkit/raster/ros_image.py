"""Map images as map_server reads them: opened safely, decoded whole or streamed in row bands.

:func:`open_image` looks at a file's header only and returns an :class:`ImageSource`:

* binary PNM (``P5`` grey, ``P6`` colour, ``P4`` bitmap) is read in row bands straight from the
  file (:meth:`ImageSource.read_rows` seeks to the rows), so a map of any height is read in
  memory bounded by the band; the header's size is checked against the file's length first;
* anything else (ASCII PNM, PNG and the other formats Pillow reads) is decoded whole, and only
  when it has at most :data:`MAX_DECODED_PIXELS` pixels (a PNG header claiming 40000 x 40000 is
  refused from its header, before any decompression).

Every failure is a :class:`~mapkit.raster.errors.RosMapError` naming the file: missing files,
folders, FIFOs and devices, unreadable files, names with NUL bytes or over the system's limit,
truncated data, bad PNM headers (huge numbers, bad ``maxval``), ASCII samples above ``maxval``,
and whatever Pillow's decoders raise.
"""

from __future__ import annotations

import errno
import os
import re
import stat
import struct
import zlib
from dataclasses import dataclass, replace
from pathlib import Path
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

from mapkit.raster.errors import RosMapError

__all__ = ["MAX_DECODED_PIXELS", "MAX_WIDTH", "ImageSource", "open_image", "open_regular"]

#: Largest image decoded whole (ASCII PNM, PNG, ...): 50 M pixels. Binary PNM is streamed.
MAX_DECODED_PIXELS = 50_000_000
#: Widest image read (pixels): a row band holds at least a few whole rows.
MAX_WIDTH = 1 << 22


@dataclass(frozen=True, slots=True)
class _Image:
    """Decoded pixels: ``channels`` ``(h, w, c)``, which of them is alpha, and the full scale."""

    channels: NDArray[Any]
    has_alpha: bool
    maxval: int
    palette_rgba: NDArray[np.uint8] | None = None  # a paletted image's colours (for Nav2)
    bilevel: str | None = None  # "pbm" (1 = black) or "png" (1 = white): 0/1 samples
    pnm: bool = False  # read by mapkit's own PNM decoder

    def rows(self, top: int, bottom: int) -> _Image:
        """Image rows ``top`` (inclusive) to ``bottom`` (exclusive), first row at the top."""
        pal = None if self.palette_rgba is None else self.palette_rgba[top:bottom]
        return replace(self, channels=self.channels[top:bottom], palette_rgba=pal)


def _os_error(err: OSError, what: str) -> str:
    if isinstance(err, FileNotFoundError):
        return "no such file" if what == "map YAML" else f"{what} not found"
    if isinstance(err, IsADirectoryError):
        return f"{what} is a folder, not a file"
    if isinstance(err, PermissionError):
        return f"{what} cannot be read: permission denied"
    if err.errno == errno.ENAMETOOLONG:
        return f"{what} name is too long for the file system"
    return f"{what} cannot be read: {err.strerror or err}"


def open_regular(path: Path, what: str = "file") -> IO[bytes]:
    """Open a regular file for reading, refusing folders, FIFOs and devices without blocking.

    Raises:
        RosMapError: Naming the file, for anything that cannot be opened or is not a file.
    """
    src = _shown(path)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as err:
        raise RosMapError(_os_error(err, what), source=src) from err
    except ValueError as err:  # NUL byte, unencodable name
        raise RosMapError(f"{what} name is not a valid file name ({err})", source=src) from err
    try:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            raise RosMapError(f"{what} is a folder, not a file", source=src)
        if not stat.S_ISREG(st.st_mode):
            raise RosMapError(f"{what} is not a regular file (a device or pipe)", source=src)
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def _shown(path: Path) -> str:
    """A file name for messages: control characters (a NUL in a YAML's image name) escaped."""
    text = str(path)
    return text if text.isprintable() else repr(text)[1:-1]


# -- PNM -----------------------------------------------------------------------------------------

_PNM_TOKEN = re.compile(rb"(?:\s|#[^\n\r]*[\n\r]?)*([^\s#]{1,32})")
_HEADER_MAX = 1 << 16  # header bytes read (comments included)
_PNM_MAGIC = (b"P1", b"P2", b"P3", b"P4", b"P5", b"P6")


@dataclass(frozen=True, slots=True)
class _PnmHeader:
    magic: bytes
    width: int
    height: int
    maxval: int
    offset: int  # first data byte

    @property
    def channels(self) -> int:
        return 3 if self.magic in (b"P3", b"P6") else 1

    @property
    def stride(self) -> int:
        """Bytes per row of binary data."""
        if self.magic == b"P4":
            return (self.width + 7) // 8
        return self.width * self.channels * (2 if self.maxval > 255 else 1)


def _pnm_header(head: bytes, src: str) -> _PnmHeader:
    magic = head[:2]
    pos = 2
    fields: list[bytes] = []
    need = 2 if magic in (b"P1", b"P4") else 3
    while len(fields) < need:
        m = _PNM_TOKEN.match(head, pos)
        if not m or (m.end() >= len(head) and len(head) >= _HEADER_MAX):
            raise RosMapError("truncated or overlong PNM header", source=src)
        tok = m.group(1)
        if not tok.isdigit() or len(tok.lstrip(b"0")) > 9:
            raise RosMapError(
                f"bad PNM header field {tok[:20]!r} (a size or maxval is a "
                "number below 1,000,000,000)",
                source=src,
            )
        fields.append(tok)
        pos = m.end()
    w, h = int(fields[0]), int(fields[1])
    maxval = int(fields[2]) if need == 3 else 1
    if w <= 0 or h <= 0 or not (0 < maxval < 65536):
        raise RosMapError(f"bad PNM size {w}x{h} or maxval {maxval} (1..65535)", source=src)
    if w > MAX_WIDTH:
        raise RosMapError(f"image is {w} pixels wide; mapkit reads up to {MAX_WIDTH}", source=src)
    if magic in (b"P4", b"P5", b"P6"):
        if pos >= len(head) or not head[pos : pos + 1].isspace():
            raise RosMapError("truncated PNM header (no whitespace before the data)", source=src)
        pos += 1  # the single whitespace after the last field
    return _PnmHeader(magic, w, h, maxval, pos)


def _ascii_samples(fh: IO[bytes], count: int, maxval: int, src: str) -> NDArray[Any]:
    """``count`` decimal samples (comments skipped), read in chunks; each at most ``maxval``.

    Returns:
        uint8 samples (uint16 when ``maxval`` is above 255).
    """
    out = np.empty(count, dtype=np.uint16 if maxval > 255 else np.uint8)
    got = 0
    carry = b""
    while got < count:
        chunk = fh.read(1 << 22)
        data = carry + chunk
        if chunk:  # keep a token (or comment) cut at the chunk's end for the next round
            cut = max(data.rfind(b"\n"), data.rfind(b"\r"))
            last_ws = max(cut, data.rfind(b" "), data.rfind(b"\t"))
            hash_pos = data.rfind(b"#")
            keep_from = cut + 1 if hash_pos > cut else last_ws + 1
            data, carry = data[:keep_from], data[keep_from:]
            if len(carry) > 1 << 20:
                raise RosMapError("bad ASCII PNM data (a token or comment over 1 MiB)", source=src)
        else:
            carry = b""
        toks = re.sub(rb"#[^\n\r]*", b" ", data).split()[: count - got]
        if toks:
            arr = np.array(toks)
            if not np.char.isdigit(arr).all():
                raise RosMapError("bad ASCII PNM sample (samples are decimal digits)", source=src)
            if arr.dtype.itemsize > 18:
                arr = np.char.lstrip(arr, b"0")
                arr[arr == b""] = b"0"
                if arr.dtype.itemsize > 18 and (np.char.str_len(arr) > 18).any():
                    raise RosMapError(f"ASCII PNM sample above maxval {maxval}", source=src)
            vals = arr.astype(np.int64)
            if (vals > maxval).any():
                raise RosMapError(
                    f"ASCII PNM sample {int(vals.max())} above maxval {maxval}", source=src
                )
            out[got : got + len(vals)] = vals
            got += len(vals)
        if not chunk:
            break
    if got < count:
        raise RosMapError(f"image data truncated: {got} of {count} samples", source=src)
    return out


def _decode_ascii_pnm(fh: IO[bytes], hd: _PnmHeader, src: str) -> _Image:
    count = hd.width * hd.height * hd.channels
    fh.seek(hd.offset)
    if hd.magic == b"P1":
        digits: list[NDArray[np.uint8]] = []
        got = 0
        while got < count:
            chunk = fh.read(1 << 22)
            if not chunk:
                break
            body = re.sub(rb"#[^\n\r]*", b" ", chunk)  # comments cut at a chunk end: see below
            bits = np.frombuffer(re.sub(rb"[^01]", b"", body), np.uint8) - ord("0")
            digits.append(bits[: count - got])
            got += len(digits[-1])
        if got < count:
            raise RosMapError("image data truncated", source=src)
        arr: NDArray[Any] = np.concatenate(digits).astype(np.uint8)
    else:
        arr = _ascii_samples(fh, count, hd.maxval, src)
    bilevel = "pbm" if hd.magic == b"P1" else None
    return _Image(
        arr.reshape(hd.height, hd.width, hd.channels),
        False,
        255 if bilevel else hd.maxval,
        bilevel=bilevel,
        pnm=True,
    )


def _binary_rows(fh: IO[bytes], hd: _PnmHeader, top: int, bottom: int, src: str) -> _Image:
    n = bottom - top
    fh.seek(hd.offset + top * hd.stride)
    buf = fh.read(n * hd.stride)
    if len(buf) < n * hd.stride:
        raise RosMapError(
            f"image data truncated (rows {top}..{bottom - 1} of {hd.height})", source=src
        )
    if hd.magic == b"P4":
        packed = np.frombuffer(buf, np.uint8).reshape(n, hd.stride)
        arr: NDArray[Any] = np.unpackbits(packed, axis=1)[:, : hd.width].astype(np.uint8)
        return _Image(arr[..., None], False, 255, bilevel="pbm", pnm=True)
    if hd.maxval > 255:
        arr = np.frombuffer(buf, dtype=">u2").astype(np.uint16)
    else:
        arr = np.frombuffer(buf, dtype=np.uint8)
    return _Image(arr.reshape(n, hd.width, hd.channels), False, hd.maxval, pnm=True)


# -- Pillow --------------------------------------------------------------------------------------


def _from_pillow(im: Any) -> _Image:
    mode = im.mode
    if mode == "P":
        # ROS 1 (SDL) reads the index as a one-channel pixel; Nav2 the colour.
        idx = np.asarray(im, dtype=np.uint8)
        rgba = np.asarray(im.convert("RGBA"), dtype=np.uint8)
        return _Image(idx[..., None], False, 255, palette_rgba=rgba)
    if mode == "1":
        return _Image(np.asarray(im, dtype=np.uint8)[..., None], False, 255, bilevel="png")
    if mode in ("I;16", "I;16B", "I;16L", "I"):
        arr = np.asarray(im).astype(np.int64)
        return _Image(np.clip(arr, 0, 65535).astype(np.uint16)[..., None], False, 65535)
    if mode == "L":
        return _Image(np.asarray(im, dtype=np.uint8)[..., None], False, 255)
    if mode == "LA":
        a = np.asarray(im, dtype=np.uint8)
        rgba = np.stack([a[..., 0], a[..., 0], a[..., 0], a[..., 1]], axis=2)
        return _Image(rgba, True, 255)
    if mode == "RGB":
        return _Image(np.asarray(im, dtype=np.uint8), False, 255)
    if mode == "RGBA":
        return _Image(np.asarray(im, dtype=np.uint8), True, 255)
    conv = im.convert("RGBA" if "A" in mode else "RGB")
    return _Image(np.asarray(conv, dtype=np.uint8), "A" in mode, 255)


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _check_png_chunks(fh: IO[bytes], src: str) -> None:
    """Walk a PNG's chunks as libpng does: CRCs, PLTE for palette images, IEND at the end.

    Pillow skips these checks; map_server's libpng refuses such files. Reads in blocks.
    """
    fh.seek(len(_PNG_SIGNATURE))
    color_type, seen_plte = -1, False
    while True:
        head = fh.read(8)
        if len(head) < 8:
            raise RosMapError("truncated PNG (no IEND chunk)", source=src)
        length, kind = struct.unpack(">I4s", head)
        if length > 0x7FFFFFFF:
            raise RosMapError(f"bad PNG chunk length {length}", source=src)
        crc = zlib.crc32(kind)
        left = length
        first = b""
        while left:
            block = fh.read(min(left, 1 << 20))
            if not block:
                raise RosMapError(f"truncated PNG (inside a {kind!r} chunk)", source=src)
            if not first:
                first = block[:13]
            crc = zlib.crc32(block, crc)
            left -= len(block)
        tail = fh.read(4)
        if len(tail) < 4 or struct.unpack(">I", tail)[0] != crc:
            raise RosMapError(
                f"PNG chunk {kind.decode('latin-1')!r} has a bad CRC (corrupt file)", source=src
            )
        if kind == b"IHDR" and len(first) == 13:
            color_type = first[9]
        elif kind == b"PLTE":
            seen_plte = True
        elif kind == b"IDAT" and color_type == 3 and not seen_plte:
            raise RosMapError("palette PNG without a PLTE chunk", source=src)
        elif kind == b"IEND":
            return


def _decode_pillow(fh: IO[bytes], src: str) -> _Image:
    try:
        from PIL import Image
    except ImportError as err:  # pragma: no cover - Pillow comes with matplotlib
        raise RosMapError(
            "reading this image format needs Pillow (pip install pillow)", source=src
        ) from err
    if fh.read(len(_PNG_SIGNATURE)) == _PNG_SIGNATURE:
        _check_png_chunks(fh, src)
    fh.seek(0)
    try:
        with Image.open(fh) as im:
            w, h = im.size
            if w * h > MAX_DECODED_PIXELS or w > MAX_WIDTH:
                raise RosMapError(
                    f"image is {w} x {h} pixels; mapkit decodes up to {MAX_DECODED_PIXELS:,} "
                    "pixels of this format (binary PGM, P5, of any size is read in bands)",
                    source=src,
                )
            im.load()
            return _from_pillow(im)
    except RosMapError:
        raise
    except MemoryError as err:
        raise RosMapError("image too large to decode in memory", source=src) from err
    except Exception as err:  # the decoders raise many types (zlib, struct, EOF, bomb checks)
        text = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise RosMapError(f"cannot read image: {text[:200]}", source=src) from err


# -- sources -------------------------------------------------------------------------------------


class ImageSource:
    """An image whose rows can be read in bands (see the module docstring).

    Attributes:
        path: The file.
        width: Pixels per row.
        height: Rows.
        maxval: Full scale of the samples (255, 65535, or a PNM's ``maxval``).
        pnm: Read by mapkit's own PNM decoder (``True``) or by Pillow.
        streamed: Rows are read from the file on demand (binary PNM) rather than decoded whole.
    """

    def __init__(
        self,
        path: Path,
        width: int,
        height: int,
        maxval: int,
        *,
        pnm: bool,
        header: _PnmHeader | None = None,
        image: _Image | None = None,
    ) -> None:
        self.path, self.width, self.height, self.maxval = path, width, height, maxval
        self.pnm = pnm
        self._header, self._image = header, image
        self.streamed = image is None

    def read_rows(self, top: int, bottom: int) -> _Image:
        """Image rows ``top`` to ``bottom`` (exclusive; row 0 is the image's top row)."""
        top, bottom = max(0, top), min(self.height, bottom)
        if self._image is not None:
            return self._image.rows(top, bottom)
        assert self._header is not None
        with open_regular(self.path, "image file") as fh:
            return _binary_rows(fh, self._header, top, bottom, str(self.path))

    def read_all(self) -> _Image:
        """The whole image."""
        return self.read_rows(0, self.height)


def image_size(path: Path | str) -> tuple[int, int] | None:
    """Width and height from a PNM or PNG header, without decoding the image (``None`` for a
    file that is not one, or whose header is bad: :func:`open_image` says what is wrong)."""
    p = Path(os.fspath(path))
    try:
        with open_regular(p, "image file") as fh:  # a pipe or device is not waited on
            head = fh.read(_HEADER_MAX)
        if head[:8] == _PNG_SIGNATURE and head[12:16] == b"IHDR" and len(head) >= 24:
            w, h = struct.unpack(">II", head[16:24])
            return int(w), int(h)
        if head[:2] in _PNM_MAGIC:
            hd = _pnm_header(head, _shown(p))
            return hd.width, hd.height
    except (OSError, RosMapError):
        return None
    return None


def open_image(path: Path | str) -> ImageSource:
    """Open a map image: a header check for binary PNM, a bounded whole decode otherwise.

    Raises:
        RosMapError: Naming the file, for anything that is not a readable image.
    """
    p = Path(os.fspath(path))
    src = _shown(p)
    with open_regular(p, "image file") as fh:
        try:
            head = fh.read(_HEADER_MAX)
            if head[:2] in _PNM_MAGIC:
                hd = _pnm_header(head, src)
                if hd.magic in (b"P4", b"P5", b"P6"):
                    size = os.fstat(fh.fileno()).st_size
                    need = hd.offset + hd.height * hd.stride
                    if size < need:
                        raise RosMapError(
                            f"image data truncated: {hd.width}x{hd.height} needs "
                            f"{need:,} bytes, the file has {size:,}",
                            source=src,
                        )
                    maxval = 255 if hd.magic == b"P4" else hd.maxval
                    return ImageSource(p, hd.width, hd.height, maxval, pnm=True, header=hd)
                if hd.width * hd.height > MAX_DECODED_PIXELS:
                    raise RosMapError(
                        f"ASCII PNM image is {hd.width} x {hd.height} pixels; mapkit decodes up "
                        f"to {MAX_DECODED_PIXELS:,} (convert to binary PGM, P5, which is read in "
                        "bands)",
                        source=src,
                    )
                img = _decode_ascii_pnm(fh, hd, src)
            else:
                fh.seek(0)
                img = _decode_pillow(fh, src)
        except OSError as err:
            raise RosMapError(_os_error(err, "image file"), source=src) from err
    h, w = img.channels.shape[:2]
    return ImageSource(p, w, h, img.maxval, pnm=img.pnm, image=img)
