"""Readers and writers: ARIA ``.map`` (:mod:`mapkit.formats.map`), and a registry by suffix."""

from mapkit.formats.map import dumpb, dumps, load, loads, parse_map, recover, save

__all__ = ["dumpb", "dumps", "load", "loads", "parse_map", "recover", "save"]
