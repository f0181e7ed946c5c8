"""The layers point one way: each module imports only from its own layer or below."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parent.parent / "mapkit"

# Lower number = lower layer. A module may import mapkit modules of its layer or lower ones.
LAYERS = {
    "mapkit.errors": 0,
    "mapkit.diagnostics": 0,
    "mapkit._typing": 0,
    "mapkit._atomic": 0,
    "mapkit._text": 0,
    "mapkit.samples": 0,
    "mapkit.model": 1,
    "mapkit.formats": 2,
    "mapkit.edit": 3,
    "mapkit.raster": 3,
    "mapkit.mesh": 3,
    "mapkit.validate": 3,
    "mapkit.build": 3,
    "mapkit.render": 3,
    "mapkit.simulate": 3,
    "mapkit.logs": 3,
    "mapkit.transfer": 4,
    "mapkit.ros": 4,
    "mapkit.demo": 4,
    "mapkit.arnet": 4,
    "mapkit.aria": 4,
    "mapkit.ros2": 4,
    "mapkit.open": 5,
    "mapkit.cli": 6,
}
# Siblings in layer 3 that may use each other (one direction only).
ALLOWED_SIBLINGS = {
    ("mapkit.validate", "mapkit.raster"),
    ("mapkit.build", "mapkit.raster"),
    ("mapkit.mesh", "mapkit.raster"),
    ("mapkit.render", "mapkit.raster"),
    ("mapkit.simulate", "mapkit.raster"),
    ("mapkit.raster", "mapkit.logs"),
    ("mapkit.build", "mapkit.logs"),
    ("mapkit.simulate", "mapkit.logs"),
    ("mapkit.ros", "mapkit.transfer"),
    ("mapkit.ros", "mapkit.arnet"),
    ("mapkit.aria", "mapkit.arnet"),
    ("mapkit.ros2", "mapkit.ros"),
    ("mapkit.ros2", "mapkit.arnet"),
}
# The ROS 2 message, naming and discovery modules are sans-I/O (no sockets, no DDS binding).
ROS2_CORE = ("messages", "graph", "errors")
# The ArNetworking protocol core is sans-I/O and imports no mapkit layer above errors.
ARNET_CORE = ("packet", "reader", "events", "connection", "services", "errors")


def layer_of(module: str) -> tuple[str, int] | None:
    best = None
    for prefix, layer in LAYERS.items():
        if (module == prefix or module.startswith(prefix + ".")) and (
            best is None or len(prefix) > len(best[0])
        ):
            best = (prefix, layer)
    return best


def module_name(path: Path) -> str:
    rel = path.relative_to(PKG.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imports(path: Path) -> list[tuple[str, int]]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.extend((a.name, node.lineno) for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.append((node.module, node.lineno))
    return out


FILES = sorted(p for p in PKG.rglob("*.py") if module_name(p) not in ("mapkit", "mapkit.__main__"))


@pytest.mark.parametrize("path", FILES, ids=lambda p: module_name(p))
def test_imports_point_down(path: Path) -> None:
    me = layer_of(module_name(path))
    assert me is not None, f"{module_name(path)} has no layer: add it to LAYERS in this test"
    for target, lineno in imports(path):
        if not target.startswith("mapkit"):
            continue
        if target == "mapkit":
            assert me[1] >= 6, f"{path}:{lineno}: only the CLI imports the top-level package"
            continue
        other = layer_of(target)
        assert other is not None, f"{path}:{lineno}: {target} has no layer"
        if other[0] == me[0]:
            continue
        # Layer-3 packages are siblings that must not lean on each other (but for the listed
        # pairs); elsewhere a module may use another of its own layer.
        same_layer_ok = other[1] == me[1] != 3
        ok = other[1] < me[1] or same_layer_ok or (me[0], other[0]) in ALLOWED_SIBLINGS
        assert ok, f"{path}:{lineno}: {me[0]} (layer {me[1]}) must not import {target}"


# The sans-I/O core of the transfer protocol and its helpers use the standard library and
# mapkit.errors only (so a binding for another transport can take them alone).
# The protocol package's modules may also use each other.
PROTOCOL = sorted(p.stem for p in (PKG / "transfer" / "protocol").glob("*.py"))
SANS_IO = {
    **{f"protocol/{m}": {"mapkit.errors", "mapkit.transfer.wirejson"} for m in PROTOCOL},
    "wirejson": set(),
    "admission": set(),
}


def test_the_protocol_package_is_all_listed() -> None:
    assert {"__init__", "channel", "handshake", "sender", "receiver"} <= set(PROTOCOL)


@pytest.mark.parametrize("name", sorted(SANS_IO))
def test_the_transfer_core_is_stdlib_only(name: str) -> None:
    path = PKG / "transfer" / f"{name}.py"
    for target, lineno in imports(path):
        top = target.split(".")[0]
        if top == "mapkit":
            ok = target in SANS_IO[name] or (
                name.startswith("protocol/") and target.startswith("mapkit.transfer.protocol.")
            )
            assert ok, f"{path}:{lineno}: imports {target}"
        else:
            import sys

            assert top in sys.stdlib_module_names or top == "__future__", (
                f"{path}:{lineno}: imports {target}, not in the standard library"
            )


# At the top level live the layer-0 basics, the package's entry points and the aria facade;
# everything else has a package whose layer LAYERS gives.
TOP_LEVEL_MODULES = {
    "__init__",
    "__main__",
    "errors",
    "diagnostics",
    "_typing",
    "_atomic",
    "_text",
    "aria",
}


def test_the_top_level_holds_packages() -> None:
    modules = {p.stem for p in PKG.glob("*.py")}
    assert modules <= TOP_LEVEL_MODULES, (
        f"{sorted(modules - TOP_LEVEL_MODULES)}: give a new module a home in a package of its layer"
    )
    for pkg in ("demo", "mesh", "render", "samples", "simulate"):
        assert (PKG / pkg / "__init__.py").is_file()
        assert layer_of(f"mapkit.{pkg}") is not None


@pytest.mark.parametrize("name", ARNET_CORE)
def test_arnet_core_is_sans_io(name: str) -> None:
    path = PKG / "arnet" / f"{name}.py"
    for target, lineno in imports(path):
        assert target.split(".")[0] not in (
            "socket",
            "select",
            "selectors",
            "asyncio",
            "threading",
        ), f"{path}:{lineno}: the ArNetworking core does no I/O ({target})"
        if target.startswith("mapkit"):
            assert target.startswith(("mapkit.arnet", "mapkit.errors")), (
                f"{path}:{lineno}: the ArNetworking core imports only errors and itself ({target})"
            )
    tree_text = path.read_text(encoding="utf-8")
    assert "mapkit.cli" not in tree_text


def test_arnet_does_not_import_the_cli() -> None:
    for path in sorted((PKG / "arnet").glob("*.py")):
        for target, lineno in imports(path):
            assert not target.startswith(("mapkit.cli", "mapkit.ros", "mapkit.transfer")), (
                f"{path}:{lineno}: arnet is at the transfer level ({target})"
            )


@pytest.mark.parametrize("name", ROS2_CORE)
def test_ros2_core_is_sans_io(name: str) -> None:
    path = PKG / "ros2" / f"{name}.py"
    for target, lineno in imports(path):
        assert target.split(".")[0] not in ("socket", "cyclonedds", "threading", "asyncio"), (
            f"{path}:{lineno}: the ROS 2 core does no I/O ({target})"
        )
        assert not target.startswith(("mapkit.cli", "mapkit.ros2.dds")), (
            f"{path}:{lineno}: {target}"
        )
