"""The editor's HTTP API as plain values: a :class:`Request` in, a :class:`Response` out.

No sockets here (the driver is :mod:`mapkit.open.server`), so every rule is testable as data:

* every request needs the session's token (``?token=`` or the cookie the page gets with
  ``/``), else 403;
* the ``Host`` header must be ``127.0.0.1`` or ``localhost`` (with this port, if any), else 403:
  a DNS-rebinding page cannot reach the editor under another name;
* a request that carries an ``Origin`` must come from the editor's own origin (403 otherwise);
* only the opened file and its siblings are ever read or written (the session does the I/O);
  static files are served from the package's ``static/`` folder only.

Routes: ``GET /`` (the page), ``GET /static/...``, ``GET /tiles/V/Z/X/Y.png``, ``GET /api/map``,
``GET /api/validate``, ``GET /api/script``, ``POST /api/edit`` (``{"edits": [...]}``),
``POST /api/undo``, ``/api/redo``, ``/api/save`` (``{"backup": true}``), ``/api/reload``.
A refused edit answers 400 with ``{"error": "one line"}``; a file changed on disk 409.
"""

from __future__ import annotations

import hmac
import json
import mimetypes
import threading
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

from mapkit.errors import EditError, MapkitError
from mapkit.open.session import ConflictError, MapSession
from mapkit.open.tiles import TileSource

__all__ = ["STATIC", "App", "Request", "Response"]

STATIC = Path(__file__).resolve().parent / "static"
_TILE_CACHE = 4096
_LOCAL_HOSTS = ("127.0.0.1", "localhost")
# The page loads nothing from elsewhere (no CDN) and runs no inline script.
_CSP = (
    "default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; "
    "img-src 'self' data:; connect-src 'self'; frame-ancestors 'none'"
)


@dataclass(frozen=True)
class Request:
    """An HTTP request: method, target (path and query), headers (any case), body."""

    method: str
    target: str
    headers: dict[str, str] = field(default_factory=dict)
    body: bytes = b""

    def header(self, name: str) -> str | None:
        """A header's value, by case-insensitive name."""
        low = name.lower()
        return next((v for k, v in self.headers.items() if k.lower() == low), None)


@dataclass(frozen=True)
class Response:
    """An HTTP response."""

    status: int
    body: bytes = b""
    content_type: str = "application/json"
    headers: tuple[tuple[str, str], ...] = ()

    @classmethod
    def json(cls, status: int, doc: Any, headers: tuple[tuple[str, str], ...] = ()) -> Response:
        """A JSON response."""
        return cls(status, json.dumps(doc).encode("utf-8"), "application/json", headers)

    @classmethod
    def error(cls, status: int, message: str) -> Response:
        """``{"error": message}`` with a status."""
        return cls.json(status, {"error": message})


class App:
    """The editor: routes requests to a :class:`MapSession` (one lock around it) and tiles.

    Args:
        session: The open file.
        token: The session's secret.
        port: The port served on (for the Host and Origin checks).
    """

    def __init__(self, session: MapSession, token: str, port: int) -> None:
        self.session = session
        self.token = token
        self.port = port
        self._lock = threading.Lock()
        self._tiles: OrderedDict[tuple[int, int, int, int], bytes] = OrderedDict()
        m = session.map  # index the scan now, not on the first tile the page asks for
        self._source: tuple[int, TileSource] | None = (
            session.data_version,
            TileSource(m.points, m.lines, m.scan.resolution),
        )

    # -- checks --------------------------------------------------------------------------------

    def _host_ok(self, host: str | None) -> bool:
        if not host:
            return False
        name, _, port = host.rpartition(":") if ":" in host else (host, "", "")
        return name.lower() in _LOCAL_HOSTS and (port in ("", str(self.port)))

    def _origin_ok(self, origin: str | None) -> bool:
        if origin is None:
            return True
        return origin in tuple(f"http://{h}:{self.port}" for h in _LOCAL_HOSTS)

    def _cookie_name(self) -> str:
        return f"mapkit_open_{self.port}"

    def _token_ok(self, req: Request, query: dict[str, list[str]]) -> bool:
        given = query.get("token", [""])[0]
        if not given:
            for part in (req.header("Cookie") or "").split(";"):
                k, _, v = part.strip().partition("=")
                if k == self._cookie_name():
                    given = v
        return bool(given) and hmac.compare_digest(given.encode(), self.token.encode())

    # -- dispatch ------------------------------------------------------------------------------

    def handle(self, req: Request) -> Response:
        """Answer one request (never raises for bad input)."""
        if not self._host_ok(req.header("Host")):
            return Response.error(
                403, "forbidden: the editor answers to 127.0.0.1 or localhost only"
            )
        if not self._origin_ok(req.header("Origin")):
            return Response.error(403, "forbidden: request from another origin")
        url = urlsplit(req.target)
        query = parse_qs(url.query)
        if not self._token_ok(req, query):
            return Response.error(
                403, "forbidden: open the address with ?token= that `mapkit open` printed"
            )
        path = url.path
        try:
            if req.method == "GET":
                return self._get(path, query)
            if req.method == "POST":
                return self._post(path, req.body)
            return Response.error(405, f"method {req.method} not allowed")
        except ConflictError as err:
            return Response.error(409, str(err))
        except (MapkitError, ValueError) as err:
            return Response.error(400, str(err))
        except OSError as err:
            return Response.error(500, f"{err.filename or ''}: {err.strerror or err}")

    def _get(self, path: str, query: dict[str, list[str]]) -> Response:
        if path in ("/", "/index.html"):
            return self._index()
        if path.startswith("/static/"):
            return self._static(path[len("/static/") :])
        if path.startswith("/tiles/"):
            return self._tile(path)
        with self._lock:
            if path == "/api/map":
                return Response.json(200, self.session.describe())
            if path == "/api/script":
                return Response.json(200, {"edits": self.session.edits})
            if path == "/api/validate":
                radius = query.get("radius", [None])[0]
                r = float(radius) if radius is not None else None
                return Response.json(200, {"findings": self.session.findings(robot_radius=r)})
        return Response.error(404, f"no such page: {path}")

    def _post(self, path: str, body: bytes) -> Response:
        try:
            doc = json.loads(body.decode("utf-8")) if body.strip() else {}
        except (UnicodeDecodeError, json.JSONDecodeError) as err:
            return Response.error(400, f"the request body is not JSON: {err}")
        if not isinstance(doc, dict):
            return Response.error(400, "the request body is a JSON object")
        with self._lock:
            s = self.session
            if path == "/api/edit":
                if "edits" not in doc:
                    raise EditError('give {"edits": [...]}: edit-script operations')
                out = s.edit(doc["edits"])
            elif path == "/api/undo":
                out = s.undo()
            elif path == "/api/redo":
                out = s.redo()
            elif path == "/api/save":
                out = s.save(backup=bool(doc.get("backup", False)))
            elif path == "/api/reload":
                out = s.reload()
            else:
                return Response.error(404, f"no such API: {path}")
            return Response.json(200, {**out, "map": s.describe()})

    # -- files and tiles -----------------------------------------------------------------------

    def _index(self) -> Response:
        html = (STATIC / "index.html").read_text(encoding="utf-8")
        cookie = f"{self._cookie_name()}={self.token}; Path=/; HttpOnly; SameSite=Strict"
        return Response(
            200,
            html.replace("{{TOKEN}}", self.token).encode("utf-8"),
            "text/html; charset=utf-8",
            (
                ("Set-Cookie", cookie),
                ("Cache-Control", "no-store"),
                ("Content-Security-Policy", _CSP),
            ),
        )

    def _static(self, rel: str) -> Response:
        f = (STATIC / rel).resolve()
        if not f.is_relative_to(STATIC) or not f.is_file():
            return Response.error(404, f"no such file: {rel}")
        ctype = mimetypes.guess_type(f.name)[0] or "application/octet-stream"
        if ctype.startswith("text/") or ctype.endswith("javascript"):
            ctype += "; charset=utf-8"
        return Response(200, f.read_bytes(), ctype, (("Cache-Control", "no-cache"),))

    def _tile(self, path: str) -> Response:
        parts = path[len("/tiles/") :].removesuffix(".png").split("/")
        try:
            _v, z, x, y = (int(p) for p in parts)
        except ValueError:
            return Response.error(404, f"no such tile: {path}")
        if not -30 <= z <= 10:
            return Response.error(404, f"zoom {z} is out of range")
        with self._lock:
            version = self.session.data_version
            key = (version, z, x, y)
            png = self._tiles.get(key)
            if png is None and (self._source is None or self._source[0] != version):
                m = self.session.map
                self._source = (version, TileSource(m.points, m.lines, m.scan.resolution))
            source = self._source[1] if self._source else None
        if png is None:
            assert source is not None
            png = source.render(z, x, y)
            with self._lock:
                self._tiles[key] = png
                while len(self._tiles) > _TILE_CACHE:
                    self._tiles.popitem(last=False)
        return Response(200, png, "image/png", (("Cache-Control", "max-age=3600"),))
