"""Connection slots of a server (mapkit/transfer/admission.py): eviction order and deadlines."""

from __future__ import annotations

import pytest
from hypothesis import given, strategies as st

from mapkit.transfer.admission import Admission


def test_a_full_address_gives_way_oldest_silent_first() -> None:
    a = Admission(max_pending=10, per_address=3, handshake_timeout=5)
    for i in range(3):
        assert a.admit(i, "10.0.0.1", now=float(i)) == []
    a.progressed(0)  # 0 sent a complete frame: it goes last
    assert a.admit(3, "10.0.0.1", now=3.0) == [1]
    assert a.admit(4, "10.0.0.2", now=3.0) == []  # another address is not affected
    assert a.pending("10.0.0.1") == 3 and a.pending() == 4


def test_a_full_pool_gives_way_from_the_address_holding_most() -> None:
    a = Admission(max_pending=4, per_address=4, handshake_timeout=5)
    a.admit("a1", "A", 0.0)
    a.admit("b1", "B", 1.0)
    a.admit("b2", "B", 2.0)
    a.admit("c1", "C", 3.0)
    assert a.admit("d1", "D", 4.0) == ["b1"]  # B holds the most; its oldest goes
    assert a.evicted == 1


def test_sessions_never_take_pending_room_and_are_capped() -> None:
    a = Admission(max_sessions=2, max_pending=2, per_address=2, handshake_timeout=5)
    for k in "xyz":
        a.admit(k, k, 0.0)
    assert a.authenticated("y") and a.authenticated("z")
    assert a.sessions() == 2 and a.pending() == 0
    a.admit("w", "w", 1.0)
    assert not a.authenticated("w")  # sessions full: refused, forgotten
    assert a.pending() == 0
    a.release("y")
    a.admit("v", "v", 1.0)
    assert a.authenticated("v")
    assert a.expired(100.0) == []  # sessions have no handshake deadline


def test_deadlines_do_not_move_with_progress() -> None:
    a = Admission(handshake_timeout=2)
    a.admit("k", "A", 10.0)
    a.progressed("k")
    assert a.next_deadline() == 12.0
    assert a.expired(11.9) == [] and a.expired(12.0) == ["k"]
    assert a.next_deadline() is None and a.timed_out == 1
    assert not a.authenticated("k")  # too late


def test_limits_must_be_positive() -> None:
    with pytest.raises(ValueError):
        Admission(per_address=0)


@given(
    st.lists(
        st.tuples(
            st.sampled_from(["admit", "progressed", "auth", "release", "expire"]),
            st.integers(0, 30),
            st.sampled_from("ABCD"),
            st.floats(0, 20),
        ),
        max_size=80,
    )
)
def test_bounds_hold_whatever_happens(ops) -> None:
    a = Admission(max_sessions=5, max_pending=6, per_address=3, handshake_timeout=4)
    live: set[int] = set()
    for op, key, addr, now in ops:
        if op == "admit" and key not in live:
            for k in a.admit(key, addr, now):
                live.discard(k)
            live.add(key)
        elif op == "progressed":
            a.progressed(key)
        elif op == "auth":
            a.authenticated(key)
        elif op == "release":
            a.release(key)
            live.discard(key)
        else:
            a.expired(now)
        assert a.pending() <= 6 and a.sessions() <= 5
        assert all(a.pending(x) <= 3 for x in "ABCD")


def test_peers_with_bytes_waiting_go_after_silent_ones() -> None:
    a = Admission(max_pending=10, per_address=3, handshake_timeout=5)
    for i in range(3):
        a.admit(i, "A", now=float(i))
    talking = {0}  # 0 is the oldest, but its HELLO sits in the socket buffer

    assert a.admit(3, "A", now=3.0, waiting=talking.__contains__) == [1]
    assert a.admit(4, "A", now=4.0, waiting=talking.__contains__) == [2]
    assert a.admit(5, "A", now=5.0, waiting=lambda k: k in (0, 4)) == [3]
    assert a.admit(6, "A", now=6.0, waiting=lambda k: True) == [0]  # all talk: the oldest
