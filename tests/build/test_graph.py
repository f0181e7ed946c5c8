"""The pose graph (mapkit/build/_graph.py): its cost, as the optimisation minimises it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, strategies as st

from mapkit.build._graph import PoseGraph, between, plus_variance, sigma_info, then


def test_the_cost_is_what_the_optimisation_minimises() -> None:
    """Each edge's chi-square at the given poses; a robust edge's is Huber's beyond 3 standard
    deviations (linear, as its down-weighting makes it); an edge switched off counts nothing; and
    optimising lowers it."""
    x = np.array([[0.0, 0.0, 0.0], [1000.0, 0.0, 0.0], [2000.0, 0.0, 0.0]])
    g = PoseGraph()
    info = sigma_info(10.0, 10.0, 0.01)
    g.add(0, 1, np.array([1000.0, 0.0, 0.0]), info)
    g.add(1, 2, np.array([1020.0, 0.0, 0.0]), info)  # 2 standard deviations off
    assert g.cost(x) == pytest.approx(4.0)
    g.add(0, 2, np.array([2050.0, 0.0, 0.0]), info, robust=True)  # 5 off: Huber's
    assert g.cost(x) == pytest.approx(4.0 + 2 * 3.0 * 5.0 - 9.0)
    g.rejected.add(2)
    assert g.cost(x) == pytest.approx(4.0)
    g.rejected.clear()
    # The 30 mm the three edges disagree by, shared equally: each 1 standard deviation off.
    assert g.cost(g.optimize(x)) == pytest.approx(3.0, abs=1e-6)


_poses = st.tuples(
    st.floats(-1e5, 1e5), st.floats(-1e5, 1e5), st.floats(-math.pi, math.pi - 1e-9)
).map(lambda p: np.array(p, dtype=np.float64))


@given(_poses, _poses)
def test_then_undoes_between(a, b) -> None:
    back = then(a, between(a, b))
    assert np.allclose(back[:2], b[:2], atol=1e-6)
    assert math.cos(back[2] - b[2]) == pytest.approx(1.0)


@given(st.lists(st.floats(1e-6, 1e6), min_size=3, max_size=3), st.floats(0.0, 1e6))
def test_plus_variance_adds_to_the_variances(var, more) -> None:
    info = np.diag(1.0 / np.array(var))
    extra = np.array([more, 0.0, more / 2.0])
    out = plus_variance(info, extra)
    assert np.allclose(1.0 / np.diag(out), np.array(var) + extra)
    assert plus_variance(info, np.zeros(3)) is info
