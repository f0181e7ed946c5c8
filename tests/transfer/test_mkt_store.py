"""The robot's destination file in background-thread mode: out-of-order chunks, and a resume
journal that never claims a chunk whose data was not fsynced first."""

from __future__ import annotations

import hashlib
import json
import os
import random
import threading
import time

import pytest

import mapkit.transfer.store as store_mod
from mapkit.transfer.protocol import Offer, decode_bitmap
from mapkit.transfer.store import PartialFile, partial_paths


@pytest.mark.parametrize("seed", range(4))
def test_chunks_in_any_order_are_hashed_and_published(tmp_path, seed) -> None:
    rng = random.Random(seed)
    cs = 4096
    data = rng.randbytes(cs * 37 + 11)
    offer = Offer.for_bytes("f.2d", data, chunk_size=cs)
    order = list(range(offer.chunks))
    rng.shuffle(order)
    pf = PartialFile.open(str(tmp_path), "f.2d", offer)
    pf.start_writer(min_size=0)
    assert len(pf._threads) == 3  # write, hash, checkpoint
    for i in order:
        pf.write(i, data[i * cs : (i + 1) * cs])
    info = pf.finalize()
    assert info["sha256"] == hashlib.sha256(data).hexdigest()
    assert (tmp_path / "f.2d").read_bytes() == data
    assert sorted(os.listdir(tmp_path)) == ["f.2d"]


def test_small_files_stay_in_the_callers_thread(tmp_path) -> None:
    offer = Offer.for_bytes("s.2d", b"x" * 1000, chunk_size=100)
    pf = PartialFile.open(str(tmp_path), "s.2d", offer)
    pf.start_writer()
    assert pf._threads == []
    for i in range(10):
        pf.write(i, b"x" * 100)
    assert pf.finalize()["size"] == 1000


def test_journal_never_claims_a_chunk_written_after_its_fsync(tmp_path, monkeypatch) -> None:
    """Chunks keep arriving while the checkpoint thread fsyncs: whatever a journal claims was
    written before the fsync that preceded it."""
    cs = 1024
    data = random.Random(5).randbytes(cs * 300)
    offer = Offer.for_bytes("j.2d", data, chunk_size=cs)
    written: set[int] = set()
    synced: dict[int, set[int]] = {}  # thread -> chunks written when its last fsync began
    claims: list[tuple[set[int], set[int]]] = []
    real_pwrite, real_fsync = store_mod._pwrite, store_mod._fsync
    real_atomic = store_mod.atomic_write
    _, journal = partial_paths(str(tmp_path), "j.2d")

    def pwrite(fd, buf, off):
        time.sleep(0.0002)  # a slow disk widens the window between a write and a checkpoint
        n = real_pwrite(fd, buf, off)
        written.add(off // cs)
        return n

    def fsync(fd):
        synced[threading.get_ident()] = set(written)
        time.sleep(0.002)
        real_fsync(fd)

    def atomic_write(path, content, *a, **kw):
        if path == journal:
            d = json.loads(content)
            claimed = {i for i, v in enumerate(decode_bitmap(d["have"], offer.chunks)) if v}
            claims.append((claimed, synced[threading.get_ident()]))
        return real_atomic(path, content, *a, **kw)

    monkeypatch.setattr(store_mod, "_pwrite", pwrite)
    monkeypatch.setattr(store_mod, "_fsync", fsync)
    monkeypatch.setattr(store_mod, "atomic_write", atomic_write)
    pf = PartialFile.open(str(tmp_path), "j.2d", offer, checkpoint_interval=0.005)
    pf.start_writer(min_size=0)
    for i in range(offer.chunks - 1):  # all but the last: the transfer is then cut
        pf.write(i, data[i * cs : (i + 1) * cs])
    pf.close(keep=True)
    assert len(claims) >= 3  # checkpoints ran while chunks were arriving, and one at the end
    for claimed, durable in claims:
        assert claimed <= durable
    assert claims[-1][0] == set(range(offer.chunks - 1))
    # and the journal resumes: only the missing chunk is asked for
    again = PartialFile.open(str(tmp_path), "j.2d", offer)
    assert again.resumed == offer.chunks - 1
    again.write(offer.chunks - 1, data[-cs:])
    again.finalize()
    assert (tmp_path / "j.2d").read_bytes() == data
