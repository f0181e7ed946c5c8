"""The HTTP driver: the standard library's threading server on 127.0.0.1, handing every request
to :class:`mapkit.open.api.App`.

Examples:
    >>> import os, tempfile, urllib.request, json
    >>> d = tempfile.mkdtemp(); p = os.path.join(d, "a.map")
    >>> _ = open(p, "w").write("2D-Map\\nDATA\\n0 0\\n")
    >>> srv = Editor.open(p, port=0)
    >>> srv.start()
    >>> with urllib.request.urlopen(srv.url("/api/map")) as r:
    ...     json.load(r)["counts"]
    {'points': 1, 'lines': 0, 'objects': 0}
    >>> srv.stop()
"""

from __future__ import annotations

import http.server
import secrets
import threading
from typing import Any
from urllib.parse import quote

from mapkit._typing import PathLike
from mapkit.open.api import App, Request
from mapkit.open.session import MapSession, OpenError

__all__ = ["HOST", "Editor"]

HOST = "127.0.0.1"
_MAX_BODY = 64 * 1024 * 1024


class _Handler(http.server.BaseHTTPRequestHandler):
    server_version = "mapkit-open"
    protocol_version = "HTTP/1.1"
    editor: Editor  # set on the subclass made per server

    def _serve(self) -> None:
        length = int(self.headers.get("Content-Length") or 0)
        if length > _MAX_BODY:
            self.send_error(413)
            return
        body = self.rfile.read(length) if length else b""
        req = Request(self.command, self.path, dict(self.headers.items()), body)
        resp = self.editor.app.handle(req)
        self.send_response(resp.status)
        self.send_header("Content-Type", resp.content_type)
        self.send_header("Content-Length", str(len(resp.body)))
        self.send_header("X-Content-Type-Options", "nosniff")
        for k, v in resp.headers:
            self.send_header(k, v)
        self.end_headers()
        if self.command != "HEAD":
            try:
                self.wfile.write(resp.body)
            except (BrokenPipeError, ConnectionResetError):  # the page dropped a tile it left
                self.close_connection = True

    do_GET = do_POST = do_PUT = do_DELETE = _serve

    def log_message(self, format: str, *args: Any) -> None:  # quiet: the CLI prints the URL only
        pass


class Editor:
    """A running (or ready) editor: a server bound to 127.0.0.1 and its :class:`App`.

    Args:
        session: The open file.
        port: 0 picks a free port.
        token: The secret; random when not given.
    """

    def __init__(self, session: MapSession, *, port: int = 0, token: str | None = None) -> None:
        self.token = token or secrets.token_urlsafe(24)
        handler = type("Handler", (_Handler,), {"editor": self})  # one class per server
        try:
            self.httpd = http.server.ThreadingHTTPServer((HOST, port), handler)
        except OSError as err:
            raise OpenError(
                f"cannot serve on {HOST}:{port}: {err.strerror or err}; "
                "pick another --port (0 picks a free one)"
            ) from err
        self.httpd.daemon_threads = True
        self.port = int(self.httpd.server_address[1])
        self.app = App(session, self.token, self.port)
        self._thread: threading.Thread | None = None

    @classmethod
    def open(
        cls,
        path: PathLike,
        *,
        port: int = 0,
        keepout: PathLike | None = None,
        token: str | None = None,
    ) -> Editor:
        """Open a file and bind the server (not yet serving)."""
        return cls(MapSession.open(path, keepout=keepout), port=port, token=token)

    def url(self, path: str = "/") -> str:
        """The address of ``path`` with the token."""
        sep = "&" if "?" in path else "?"
        return f"http://{HOST}:{self.port}{path}{sep}token={quote(self.token)}"

    def serve_forever(self) -> None:
        """Serve until :meth:`stop` (or Ctrl-C in the caller)."""
        self.httpd.serve_forever(poll_interval=0.2)

    def start(self) -> None:
        """Serve in a background thread."""
        self._thread = threading.Thread(target=self.serve_forever, name="mapkit-open", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop serving and close the socket."""
        if self._thread is not None:
            self.httpd.shutdown()
            self._thread.join(timeout=5)
        self.httpd.server_close()
