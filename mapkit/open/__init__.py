"""``mapkit open``: a local web editor for one map, served on 127.0.0.1.

* :mod:`mapkit.open.session`: the file, its undo history, saving (no HTTP);
* :mod:`mapkit.open.tiles`: PNG tiles of the scan for the map view;
* :mod:`mapkit.open.api`: the HTTP API as request/response values (token and Host checks);
* :mod:`mapkit.open.server`: the standard library's threading HTTP server driving it;
* ``static/``: the page (its own small script) and the vendored Leaflet.

Edits are ``mapkit edit --script`` operations applied with :func:`mapkit.edit.apply_script`,
so a save writes the same bytes as the CLI.
"""

from mapkit.open.api import App, Request, Response
from mapkit.open.server import Editor
from mapkit.open.session import ConflictError, MapSession, OpenError

__all__ = ["App", "ConflictError", "Editor", "MapSession", "OpenError", "Request", "Response"]
