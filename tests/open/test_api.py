"""The editor's JSON API over a real socket: access checks, every edit, undo/redo, saving."""

from __future__ import annotations

import http.client
import json
import shutil
import signal
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from mapkit.cli.main import cli
from mapkit.open.server import Editor
from mapkit.open.session import OpenError

pytestmark = pytest.mark.network

OFFICE = Path(__file__).resolve().parents[2] / "mapkit" / "sample_maps" / "office.map"


class Client:
    """Plain http.client requests, so the Host and Origin headers are ours to set."""

    def __init__(self, editor: Editor) -> None:
        self.editor = editor

    def call(
        self,
        method: str,
        path: str,
        body: Any = None,
        *,
        token: str | None = "",
        host: str | None = None,
        origin: str | None = None,
    ) -> tuple[int, Any]:
        ed = self.editor
        tok = ed.token if token == "" else token
        target = path + ("" if tok is None else ("&" if "?" in path else "?") + f"token={tok}")
        conn = http.client.HTTPConnection("127.0.0.1", ed.port, timeout=60)
        headers = {"Host": host or f"127.0.0.1:{ed.port}"}
        if origin:
            headers["Origin"] = origin
        data = json.dumps(body).encode() if body is not None else None
        if data is not None:
            headers["Content-Type"] = "application/json"
        conn.request(method, target, body=data, headers=headers)
        r = conn.getresponse()
        raw = r.read()
        conn.close()
        if r.getheader("Content-Type", "").startswith("application/json"):
            return r.status, json.loads(raw)
        return r.status, raw

    def edit(self, *edits: dict[str, Any]) -> tuple[int, Any]:
        return self.call("POST", "/api/edit", {"edits": list(edits)})


def _copy(src: Path, folder: Path) -> Path:
    dst = folder / src.name
    shutil.copyfile(src, dst)
    return dst


@contextmanager
def serving(path: Path, **kw: Any) -> Iterator[Client]:
    """An editor on ``path`` (a copy the test owns), serving until the block ends."""
    ed = Editor.open(path, **kw)
    ed.start()
    try:
        yield Client(ed)
    finally:
        ed.stop()


@pytest.fixture
def office(tmp_path: Path) -> Path:
    return _copy(OFFICE, tmp_path)


@pytest.fixture
def client(office: Path) -> Iterator[Client]:
    with serving(office) as c:
        yield c


def cli_bytes(src: Path, folder: Path, edits: list[dict[str, Any]]) -> bytes:
    """What `mapkit edit COPY --script` writes for the same edits."""
    folder.mkdir()
    copy = _copy(src, folder)
    script = folder / "edits.json"
    script.write_text(json.dumps(edits))
    res = CliRunner().invoke(cli, ["edit", str(copy), "--script", str(script)])
    assert res.exit_code == 0, res.output
    return copy.read_bytes()


# -- access --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "path",
    ["/", "/api/map", "/api/validate", "/static/app.js", "/tiles/0/-5/0/-1.png", "/api/script"],
)
def test_every_path_needs_the_token(client: Client, path: str) -> None:
    assert client.call("GET", path, token=None)[0] == 403
    assert client.call("GET", path, token="wrong")[0] == 403
    assert client.call("GET", path)[0] == 200


def test_posts_need_the_token_and_leave_the_map_alone(client: Client, office: Path) -> None:
    before = office.read_bytes()
    status, doc = client.call(
        "POST", "/api/edit", {"edits": [{"add-goal": {"name": "X", "x": 0, "y": 0}}]}, token=None
    )
    assert status == 403 and "token" in doc["error"]
    assert client.call("POST", "/api/save", {}, token="nope")[0] == 403
    assert client.call("GET", "/api/map")[1]["counts"]["objects"] == 11
    assert office.read_bytes() == before


@pytest.mark.parametrize(
    "host",
    [
        "evil.example",
        "evil.example:{port}",
        "127.0.0.1:1",
        "localhost.evil.example:{port}",
        "10.0.0.1:{port}",
        "",
    ],
)
def test_foreign_host_header_is_refused(client: Client, host: str) -> None:
    status, doc = client.call("GET", "/api/map", host=host.format(port=client.editor.port) or " ")
    assert status == 403 and "127.0.0.1 or localhost" in doc["error"]


@pytest.mark.parametrize("host", ["127.0.0.1", "localhost", "127.0.0.1:{port}", "LOCALHOST:{port}"])
def test_local_host_headers_are_served(client: Client, host: str) -> None:
    assert client.call("GET", "/api/map", host=host.format(port=client.editor.port))[0] == 200


def test_cross_origin_post_is_refused(client: Client) -> None:
    assert client.edit({"add-goal": {"name": "X", "x": 0, "y": 0}})[0] == 200
    status, _ = client.call("POST", "/api/undo", {}, origin="http://evil.example")
    assert status == 403
    ok = client.call("POST", "/api/undo", {}, origin=f"http://127.0.0.1:{client.editor.port}")
    assert ok[0] == 200


def test_page_sets_a_port_scoped_cookie_that_also_admits(client: Client) -> None:
    conn = http.client.HTTPConnection("127.0.0.1", client.editor.port, timeout=10)
    conn.request("GET", f"/?token={client.editor.token}")
    r = conn.getresponse()
    page = r.read().decode()
    cookie = r.getheader("Set-Cookie", "")
    assert client.editor.token in page and "SameSite=Strict" in cookie and "HttpOnly" in cookie
    conn.request("GET", "/api/map", headers={"Cookie": cookie.split(";")[0]})
    assert conn.getresponse().status == 200


def test_static_files_stay_inside_the_static_folder(client: Client) -> None:
    for path in ("/static/../session.py", "/static/%2e%2e/session.py", "/static/nope.js"):
        assert client.call("GET", path)[0] == 404
    status, body = client.call("GET", "/static/vendor/leaflet/LICENSE")
    assert status == 200 and b"BSD 2-Clause License" in body


def test_tiles_are_png_and_bad_ones_404(client: Client) -> None:
    status, body = client.call("GET", "/tiles/0/-6/0/-1.png")
    assert status == 200 and body[:4] == b"\x89PNG"
    assert client.call("GET", "/tiles/0/x/0/0.png")[0] == 404
    assert client.call("GET", "/tiles/0/99/0/0.png")[0] == 404


# -- edits ---------------------------------------------------------------------------------------

EVERY_OPERATION = [
    [{"add-goal": {"name": "Pantry", "x": 1000, "y": 2000}}],
    [{"add-goal": {"name": "Desk 2", "x": -1500, "y": 300, "heading": 135}}],
    [{"add-dock": {"name": "Charger 2", "x": 500, "y": 500, "heading": -90}}],
    [{"add-home": {"x": 0, "y": 100, "heading": 45}}],
    [
        {
            "add-object": {
                "type": "ForbiddenArea",
                "area": [0, 0, 800, 400],
                "angle": 20,
                "rotate-about-centre": True,
            }
        }
    ],
    [{"forbid": {"area": [-2000, -1000, -1000, 0]}}, {"move": {"name": "#12", "heading": 30}}],
    [{"forbid": {"line": [0, 0, 3000, 1000], "name": "Stairs"}}],
    [{"remove": {"names": ["#1"]}}],
    [{"rename": {"name": "#2", "new-name": "Renamed"}}],
    [{"move": {"name": "#3", "x": 1234, "y": -567}}],
    [{"move": {"name": "#3", "by": [100, 50], "heading": 90}}],
    [{"erase": {"box": [-3000, -3000, 3000, 3000]}}],
    [{"erase": {"polygon": [[0, 0], [4000, 0], [0, 4000]]}}],
    [{"draw-line": {"line": [-5000, 5000, 5000, 5000]}}],
    [{"transform": {"rotate": 90, "translate": [1000, 0]}}],
    [{"crop": {"box": [-6000, -6000, 6000, 6000], "keep-objects": True}}],
]


@pytest.mark.parametrize("edits", EVERY_OPERATION, ids=lambda e: "+".join(next(iter(x)) for x in e))
def test_every_operation_saves_the_clis_bytes(
    client: Client, office: Path, tmp_path: Path, edits: list[dict[str, Any]]
) -> None:
    status, doc = client.edit(*edits)
    assert status == 200, doc
    assert doc["summary"] and doc["map"]["dirty"] and doc["map"]["edits"] == edits
    status, saved = client.call("POST", "/api/save", {})
    assert status == 200 and saved["written"] == [str(office.resolve())]
    assert office.read_bytes() == cli_bytes(OFFICE, tmp_path / "cli", edits)
    assert client.call("GET", "/api/map")[1]["dirty"] is False


def test_declared_type_with_parameters(tmp_path: Path, shared_dir: Path) -> None:
    src = shared_dir / "real" / "aria291-columbia.map"
    with serving(_copy(src, tmp_path)) as c:
        types = {t["name"]: t for t in c.call("GET", "/api/map")[1]["types"]}
        assert types["BadGPSSector"]["shape"] == "rect" and types["Measure"]["shape"] == "line"
        edits = [
            {
                "add-object": {
                    "type": "BadGPSSector",
                    "area": [0, 0, 5000, 2000],
                    "name": "Car park",
                }
            },
            {"add-object": {"type": "Measure", "line": [0, 0, 10000, 0], "name": "Stick"}},
        ]
        assert c.edit(*edits)[0] == 200
        assert c.call("POST", "/api/save", {})[0] == 200
        assert c.editor.app.session.path.read_bytes() == cli_bytes(src, tmp_path / "cli", edits)


@pytest.mark.parametrize(
    "edits, words",
    [
        ([{"add-goal": {"name": "A", "x": 0}}], "missing argument y"),
        ([{"add-goal": {"name": "A", "x": 0, "y": 0, "colour": 1}}], "unknown argument colour"),
        ([{"teleport": {}}], "unknown operation 'teleport'"),
        ([{"remove": {"names": ["No such thing"]}}], "No such thing"),
        (
            [
                {"add-goal": {"name": "A", "x": 0, "y": 0}},
                {"add-goal": {"name": "A", "x": 1, "y": 1}},
            ],
            "edit 2 (add-goal)",
        ),
        ([{"add-goal": {"name": "A", "x": 1e12, "y": 0}}], "edit 1"),
        ([{"merge": {"other": "/etc/passwd"}}], "merge reads another file"),
        ([], "non-empty list"),
        ("add-goal", "non-empty list"),
    ],
)
def test_refused_edits_are_400_and_change_nothing(
    client: Client, office: Path, edits: Any, words: str
) -> None:
    before = office.read_bytes()
    status, doc = client.call("POST", "/api/edit", {"edits": edits})
    assert status == 400 and words in doc["error"], doc
    m = client.call("GET", "/api/map")[1]
    assert m["counts"]["objects"] == 11 and not m["can_undo"] and not m["dirty"]
    assert client.call("POST", "/api/save", {})[1]["written"] == []
    assert office.read_bytes() == before


@pytest.mark.parametrize("body", [b"{not json", b"[1, 2]", b'{"edit": []}'])
def test_malformed_bodies_are_400(client: Client, body: bytes) -> None:
    conn = http.client.HTTPConnection("127.0.0.1", client.editor.port, timeout=10)
    conn.request("POST", f"/api/edit?token={client.editor.token}", body=body)
    r = conn.getresponse()
    assert r.status == 400 and "error" in json.loads(r.read())


def test_undo_and_redo(client: Client, office: Path) -> None:
    assert client.call("POST", "/api/undo", {})[1]["error"] == "nothing to undo"
    client.edit({"add-goal": {"name": "A", "x": 0, "y": 0}})
    client.edit({"rename": {"name": "A", "new-name": "B"}})
    status, doc = client.call("POST", "/api/undo", {})
    assert status == 200 and len(doc["summary"]) == 1 and "'A'" in doc["summary"][0]
    assert [o["name"] for o in doc["map"]["objects"]][-1] == "A" and doc["map"]["can_redo"]
    status, doc = client.call("POST", "/api/redo", {})
    assert [o["name"] for o in doc["map"]["objects"]][-1] == "B"
    assert client.call("POST", "/api/redo", {})[0] == 400
    client.call("POST", "/api/undo", {})
    client.edit({"add-dock": {"name": "D", "x": 5, "y": 5}})  # a new edit drops the redo branch
    doc = client.call("GET", "/api/map")[1]
    assert not doc["can_redo"] and [o["name"] for o in doc["objects"]][-2:] == ["A", "D"]
    assert client.call("GET", "/api/script")[1]["edits"] == [
        {"add-goal": {"name": "A", "x": 0, "y": 0}},
        {"add-dock": {"name": "D", "x": 5, "y": 5}},
    ]
    client.call("POST", "/api/undo", {})
    client.call("POST", "/api/undo", {})
    assert client.call("POST", "/api/save", {})[1]["written"] == []  # back where it started


def test_data_edits_change_the_tiles_version(client: Client) -> None:
    v0 = client.call("GET", "/api/map")[1]["data_version"]
    assert client.edit({"add-goal": {"name": "A", "x": 0, "y": 0}})[1]["map"]["data_version"] == v0
    v1 = client.edit({"erase": {"box": [-9e4, -9e4, 9e4, 9e4]}})[1]["map"]["data_version"]
    assert v1 != v0
    assert client.call("POST", "/api/undo", {})[1]["map"]["data_version"] == v0


# -- saving --------------------------------------------------------------------------------------


def test_save_keeps_a_backup_when_asked(client: Client, office: Path) -> None:
    before = office.read_bytes()
    client.edit({"add-goal": {"name": "A", "x": 0, "y": 0}})
    status, doc = client.call("POST", "/api/save", {"backup": True})
    assert status == 200 and doc["backup"] is True
    assert Path(f"{office}.bak").read_bytes() == before and office.read_bytes() != before


def test_save_refuses_a_file_changed_on_disk(client: Client, office: Path) -> None:
    client.edit({"add-goal": {"name": "Mine", "x": 0, "y": 0}})
    theirs = office.read_bytes().replace(b"\nDATA\n", b"\nDATA\n0 0\n", 1)
    office.write_bytes(theirs)
    status, doc = client.call("POST", "/api/save", {})
    assert status == 409 and "changed on disk" in doc["error"]
    assert office.read_bytes() == theirs
    status, doc = client.call("POST", "/api/reload", {})
    assert status == 200 and not doc["map"]["dirty"] and "Mine" not in str(doc["map"]["objects"])
    client.edit({"add-goal": {"name": "Mine", "x": 0, "y": 0}})
    assert client.call("POST", "/api/save", {})[0] == 200
    assert b'"Mine"' in office.read_bytes()


def test_same_edits_same_bytes_on_every_real_sample(real_sample: Path, tmp_path: Path) -> None:
    with serving(_copy(real_sample, tmp_path)) as c:
        (x0, y0), (x1, y1) = c.call("GET", "/api/map")[1]["bounds"]
        cx, cy = round((x0 + x1) / 2), round((y0 + y1) / 2)
        n = c.call("GET", "/api/map")[1]["counts"]["objects"]
        edits = [
            {"add-goal": {"name": "mapkit open goal", "x": cx, "y": cy, "heading": 30}},
            {"forbid": {"area": [cx - 1000, cy - 500, cx + 1000, cy + 500]}},
            {"move": {"name": f"#{n + 2}", "heading": 25}},
            {"forbid": {"line": [cx, cy - 2000, cx + 2000, cy - 2000]}},
            {"erase": {"box": [cx - 300, cy - 300, cx + 300, cy + 300]}},
            {"draw-line": {"line": [cx - 3000, cy + 3000, cx + 3000, cy + 3000]}},
        ]
        for e in edits:
            status, doc = c.edit(e)
            assert status == 200, doc
        assert c.call("POST", "/api/save", {})[0] == 200
        saved = c.editor.app.session.path.read_bytes()
        assert saved == cli_bytes(real_sample, tmp_path / "cli", edits)


def test_validate_findings_have_codes_and_places(client: Client) -> None:
    client.edit(
        {"draw-line": {"line": [-500, 7000, 500, 7000]}},
        {"add-goal": {"name": "In the wall", "x": 0, "y": 7000}},
    )
    status, doc = client.call("GET", "/api/validate?radius=250")
    assert status == 200
    hits = [f for f in doc["findings"] if f["name"] == "GOAL_IN_WALL"]
    assert hits and hits[0]["code"] == 409 and hits[0]["xy"] == [0.0, 7000.0]
    assert all(f["code"] and f["severity"] in ("error", "warning", "info") for f in doc["findings"])


# -- the command ---------------------------------------------------------------------------------


def test_cli_prints_one_line_and_serves_until_interrupted(office: Path) -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "mapkit", "open", str(office), "--no-browser"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert line.startswith("mapkit open: http://127.0.0.1:") and "?token=" in line
        port = int(line.split(":")[3].split("/")[0])
        token = line.strip().split("token=")[1]
        conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
        conn.request("GET", f"/api/map?token={token}")
        assert json.loads(conn.getresponse().read())["file"] == str(office.resolve())
    finally:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=20)
    assert proc.returncode == 0 and "stopped" in err and out == ""


def test_cli_refuses_a_file_that_is_not_a_map(tmp_path: Path) -> None:
    bad = tmp_path / "bad.map"
    bad.write_text("hello\n")
    res = CliRunner().invoke(cli, ["open", str(bad), "--no-browser"])
    assert res.exit_code == 1 and "bad.map" in res.output


# -- ROS maps: keepout zones -----------------------------------------------------------------------


@pytest.fixture
def ros_map(tmp_path: Path) -> Path:
    """office.map rasterised for ROS, with its keepout mask (NAME_keepout.*) beside it."""
    res = CliRunner().invoke(
        cli, ["rasterize", str(OFFICE), "-o", str(tmp_path / "office.yaml"), "--keepout"]
    )
    assert res.exit_code == 0, res.output
    return tmp_path / "office.yaml"


def test_ros_keepout_zones_are_edited_and_saved_as_the_mask(ros_map: Path, tmp_path: Path) -> None:
    from mapkit.raster.masks import write_filters

    folder = ros_map.parent
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    with serving(ros_map) as c:
        doc = c.call("GET", "/api/map")[1]
        assert doc["kind"] == "ros" and doc["counts"]["points"] > 100
        assert {o["type"] for o in doc["objects"]} <= {"ForbiddenArea", "ForbiddenLine"}
        zones = doc["counts"]["objects"]
        assert zones >= 1  # office.map's forbidden area came back from the mask
        for refused in (
            {"add-goal": {"name": "A", "x": 0, "y": 0}},
            {"erase": {"box": [0, 0, 1000, 1000]}},
            {"draw-line": {"line": [0, 0, 1000, 0]}},
        ):
            status, err = c.edit(refused)
            assert status == 400 and "read only" in err["error"]
        status, out = c.edit(
            {"forbid": {"area": [2000, 2000, 4000, 3000]}},
            {"move": {"name": f"#{zones + 1}", "heading": 30}},
            {"forbid": {"line": [6000, 1000, 9000, 1000]}},
        )
        assert status == 200, out
        status, saved = c.call("POST", "/api/save", {"backup": True})
        assert status == 200, saved
        assert [Path(p).name for p in saved["written"]] == [
            "office_keepout.yaml",
            "office_keepout.pgm",
            "office_filters.yaml",
        ]
        assert (folder / "office.yaml").read_bytes() == before["office.yaml"]
        assert (folder / "office.pgm").read_bytes() == before["office.pgm"]
        assert (folder / "office_keepout.pgm.bak").read_bytes() == before["office_keepout.pgm"]
        # The same writers the CLI uses give the same files for the same zones.
        other = tmp_path / "lib"
        other.mkdir()
        shutil.copyfile(ros_map, other / "office.yaml")
        write_filters(c.editor.app.session.map, c.editor.app.session.grid, other / "office.yaml")
        for name in ("office_keepout.yaml", "office_keepout.pgm"):
            assert (folder / name).read_bytes() == (other / name).read_bytes()
        assert (folder / "office_filters.yaml").read_text().replace(str(folder), "D") == (
            other / "office_filters.yaml"
        ).read_text().replace(str(other), "D")
        assert (folder / "office_keepout.pgm").read_bytes() != before["office_keepout.pgm"]
    again = Editor.open(ros_map)  # the saved mask reads back with the new zones
    assert again.app.session.describe()["counts"]["objects"] >= zones + 2
    again.httpd.server_close()


def test_ros_keepout_option_and_refusals(ros_map: Path, tmp_path: Path) -> None:
    mask = ros_map.parent / "office_keepout.yaml"
    named = ros_map.parent / "zones.yaml"
    shutil.copyfile(mask, named)
    with serving(ros_map, keepout=named) as c:
        assert c.editor.app.session.keepout == named.resolve()
        assert c.edit({"forbid": {"area": [2000, 2000, 4000, 3000]}})[0] == 200
        status, saved = c.call("POST", "/api/save", {})
        assert status == 200, saved
        assert [Path(p).name for p in saved["written"]] == [
            "zones.yaml",
            "office_keepout.pgm",
            "office_filters.yaml",
        ]  # the image zones.yaml names
        assert "zones.yaml" in (ros_map.parent / "office_filters.yaml").read_text()
    with pytest.raises(OpenError, match="no such keepout mask"):
        Editor.open(ros_map, keepout=tmp_path / "none.yaml")
    res = CliRunner().invoke(cli, ["open", str(OFFICE), "--keepout", str(mask), "--no-browser"])
    assert res.exit_code == 1 and "ROS map YAML" in res.output


def test_cli_says_when_the_port_is_taken(office: Path, client: Client) -> None:
    res = CliRunner().invoke(
        cli, ["open", str(office), "--no-browser", "--port", str(client.editor.port)]
    )
    assert res.exit_code == 1 and f"cannot serve on 127.0.0.1:{client.editor.port}" in res.output


def test_declared_types_with_their_parameters(tmp_path: Path, shared_dir: Path) -> None:
    src = shared_dir / "real" / "omron-ld-showroom-ex4.map"
    with serving(_copy(src, tmp_path)) as c:
        types = {t["name"]: t for t in c.call("GET", "/api/map")[1]["types"]}
        assert {p["name"] for p in types["MovementParametersSector"]["params"]} >= {"TransVelMax"}
        status, err = c.edit(
            {
                "add-object": {
                    "type": "DoorGoal",
                    "at": [0, 0],
                    "name": "D",
                    "params": {"NoSuchParam": 1},
                }
            }
        )
        assert status == 400 and "NoSuchParam" in err["error"]
        edits = [
            {
                "add-object": {
                    "type": "MovementParametersSector",
                    "area": [0, 0, 3000, 2000],
                    "name": "Slow zone",
                    "params": {"TransVelMax": "300"},
                }
            },
            {
                "add-object": {
                    "type": "DoorGoal",
                    "at": [1500, 1000],
                    "heading": 90,
                    "name": "Door goal",
                    "params": {"CustomDoneDist": 250},
                }
            },
        ]
        status, doc = c.edit(*edits)
        assert status == 200, doc
        rows = {o["name"]: o for o in doc["map"]["objects"]}
        assert rows["Slow zone"]["params"]["TransVelMax"] == "300"
        assert c.call("POST", "/api/save", {})[0] == 200
        assert c.editor.app.session.path.read_bytes() == cli_bytes(src, tmp_path / "cli", edits)
