"""The odometry model (mapkit/build/_odometry.py): noise scales fitted to the log, systematic
errors calibrated."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from mapkit.build import _odometry


def test_turns_get_their_own_noise_scale() -> None:
    """Straight steps that agree with their scans and turns that slip: each gets its own noise
    scale, and the next pass keeps the turns' until it has seen turns enough itself."""
    model = _odometry._OdometryModel()
    strong = np.diag([1.0, 1.0, 1e6])  # scan matches of 1 mm and 0.06 degrees
    turn = math.radians(25.0)
    # Before any turn is seen, a turn is trusted to the model's shape (a few percent).
    assert 1.0 / math.sqrt(model.info(0.0, turn)[2, 2]) > 0.02 * turn
    rng = np.random.default_rng(3)
    for k in range(300):
        if k % 10 == 0:  # a turn on the spot slipping 2 %
            model.observe(np.array([0.0, 0.0, rng.normal(0.0, 0.02 * turn)]), strong, 0.0, turn)
        else:
            model.observe(np.zeros(3), strong, 300.0, 0.0)
    model.settle()
    assert model.turn_scale is not None and model.turn_scale > 10 * model.scale
    sigma_turn = 1.0 / math.sqrt(model.info(0.0, turn)[2, 2])
    assert 0.01 * turn < sigma_turn < 0.05 * turn, math.degrees(sigma_turn)
    # Straight steps keep the straight scale.
    assert model.info(300.0, 0.0)[2, 2] == pytest.approx(
        1.0 / (model.scale * model.variances(300.0, 0.0)[2])
    )
    # The next pass starts with both scales, and a few straight steps do not lose the turns'.
    nxt = model.fresh()
    for _ in range(40):
        nxt.observe(np.zeros(3), strong, 300.0, 0.0)
    assert nxt.turn_scale == model.turn_scale


def _turns_seen(model: _odometry._OdometryModel, slip: float, seed: int) -> None:
    """300 steps, every tenth a 25 degree turn on the spot whose odometry slips by ``slip`` of
    it (normal) against a match of 0.1 degrees; the straight steps agree with theirs."""
    turn = math.radians(25.0)
    match = np.diag([1 / 100.0, 1 / 100.0, 1 / math.radians(0.1) ** 2])
    rng = np.random.default_rng(seed)
    for k in range(300):
        if k % 10 == 0:
            d = rng.normal(0.0, math.radians(0.1)) + rng.normal(0.0, slip * turn)
            model.observe(np.array([0.0, 0.0, d]), match, 0.0, turn)
        else:
            model.observe(np.zeros(3), match, 300.0, 0.0)
    model.settle()


def test_a_stated_turn_error_is_kept_unless_the_turns_rule_it_out() -> None:
    """The robot's turn error as its owner states it (0.1 % of the turn). Turns that agree
    with it within what their matches can tell (exact, or 0.3 %) keep it, in this pass and the
    next, where the fit alone finds what their matches' noise makes of them. Turns that slip
    2 % rule it out (stated too low, the odometry would outvote every scan that saw the slip:
    metres off on the benchmark's slipping robot), and the log's own fit is taken."""
    for slip in (0.0, 0.003):
        for seed in (1, 2, 3):
            model = _odometry._OdometryModel.stated_as(0.001)
            _turns_seen(model, slip, seed)
            assert model.turn_stated and model.turn_error == pytest.approx(0.001)
            assert model.fresh().turn_error == pytest.approx(0.001)
    slipping = _odometry._OdometryModel.stated_as(0.001)
    _turns_seen(slipping, 0.02, 1)
    assert not slipping.turn_stated
    assert slipping.turn_error is not None and slipping.turn_error > 0.01
    fitted = _odometry._OdometryModel()
    _turns_seen(fitted, 0.02, 1)
    assert slipping.turn_scale == fitted.turn_scale
    # Stated as none: the fit's floor (odometry is never taken as exact).
    floor = _odometry._OdometryModel.stated_as(0.0)
    assert floor.turn_scale == pytest.approx(10.0**_odometry._MIN_LOG_TURN_SCALE)


def test_turns_are_presumed_good_unless_they_rule_it_out() -> None:
    """With no turn error stated, registration presumes 0.1 % after its warm-up (one log's
    turns resolve their error only coarsely; fitted alone, a simulator's came out 0.2-0.45 %).
    Turns that agree with it within what their matches can tell (exact, or 0.3 %) keep it, in
    this pass and the next. Turns that slip 2 % rule it out where they were seen, and are
    fitted exactly as with no presumption; ruled out once, it stays out in the next pass, even
    while that pass's first turns could not tell."""
    presumed = _odometry._PRESUMED_TURN_ERROR
    assert presumed is not None
    for slip in (0.0, 0.003):
        for seed in (1, 2, 3):
            model = _odometry._OdometryModel.stated_as(None)
            _turns_seen(model, slip, seed)
            model.presume()
            assert model.turn_presumed and not model.turn_stated and not model.turn_ruled_out
            assert model.turn_error == pytest.approx(presumed)
            nxt = model.fresh()
            _turns_seen(nxt, slip, seed + 10)
            assert nxt.turn_presumed and nxt.turn_error == pytest.approx(presumed)
    slipping = _odometry._OdometryModel.stated_as(None)
    _turns_seen(slipping, 0.02, 1)
    fitted = _odometry._OdometryModel()
    _turns_seen(fitted, 0.02, 1)
    slipping.presume()
    assert not slipping.turn_presumed and slipping.turn_scale == fitted.turn_scale
    # The next pass: turns that would not rule it out alone do not bring it back.
    nxt = slipping.fresh()
    _turns_seen(nxt, 0.0, 2)
    assert not nxt.turn_presumed
    assert nxt.turn_error is not None and nxt.turn_error != pytest.approx(presumed)
    # Presumed before its turns were seen: the first fit with ten of them decides.
    early = _odometry._OdometryModel.stated_as(None)
    early.presume()
    assert early.turn_scale is None
    _turns_seen(early, 0.02, 1)
    assert not early.turn_presumed and early.turn_error is not None and early.turn_error > 0.01
    # Not under a laser noisier than those it was measured under (round 28).
    for noise, held in ((16.0, True), (16.5, False), (30.0, False)):
        model = _odometry._OdometryModel.stated_as(None)
        _turns_seen(model, 0.0, 1)
        model.presume(noise)
        assert model.turn_presumed is held and not model.turn_ruled_out
        assert (model.turn_error == pytest.approx(presumed)) is held
    # A stated error is never replaced by the presumed one.
    stated = _odometry._OdometryModel.stated_as(0.003)
    _turns_seen(stated, 0.003, 1)
    stated.presume()
    assert stated.turn_stated and stated.turn_error == pytest.approx(0.003)


def test_calibration_keeps_what_an_earlier_pass_learnt_until_it_has_samples() -> None:
    """A pass starts from the factors the pass before learnt (the warm-up's, say), and keeps them
    until it has samples enough of its own; it used to fall back to no correction at its first
    refit and register metres of log with uncorrected odometry."""
    first = _odometry._Calibration()
    first.dist, first.drift = 0.995, math.radians(-0.05) / 1000.0
    cal = first.fresh()
    straight = np.array([1000.0, 0.0, 0.0])
    for _ in range(30):  # refits at 25 observations, with no sample (a corridor: no direction)
        cal.observe_run(straight, straight, np.diag([1e8, 1.0, 1e-6]))
    assert cal.dist == 0.995 and cal.drift == first.drift
    # Samples enough of its own: they win (here: odometry that needs no correction).
    for _ in range(80):
        cal.observe_run(straight, straight, np.diag([1.0, 1.0, 1e-6]))
    assert cal.dist == pytest.approx(1.0)


def test_the_distance_scale_is_fitted_on_scan_to_scan_samples_once_there_are_enough() -> None:
    """Runs measured against the local map lean towards the odometry being calibrated (its
    length is laid out with it); runs matched scan to scan do not. The scale comes from the
    direct samples once there are enough of them, from the local map's until then; direct
    samples, like the drift's they come with, do not bring the next fit forward."""
    cal = _odometry._Calibration()
    raw = np.array([2000.0, 0.0, 0.0])
    fixed = np.diag([1.0, 1.0, 1e-6])  # the walls fix the direction of travel
    rng = np.random.default_rng(8)

    def run(scale: float) -> np.ndarray:
        return np.array([2000.0 * (scale + rng.normal(0.0, 1e-4)), 0.0, 0.0])

    for _ in range(100):
        cal.observe_run(raw, run(0.996), fixed)
    assert cal.dist == pytest.approx(0.996, abs=1e-4)  # only local-map samples: theirs
    for _ in range(_odometry._Calibration._MIN - 1):
        cal.observe_run(raw, run(0.995), fixed, direct=True)
    cal.settle()
    assert cal.dist == pytest.approx(0.996, abs=1e-4)  # too few direct samples yet
    fitted = cal.dist
    for _ in range(30):  # would have been a regular fit had they counted
        cal.observe_run(raw, run(0.995), fixed, direct=True)
    assert cal.dist == fitted
    cal.settle()
    assert cal.dist == pytest.approx(0.995, abs=1e-4)
    # A run whose direction the scans do not fix (a corridor) is no sample either way.
    before = len(cal._dist_direct)
    cal.observe_run(raw, run(0.9), np.diag([1e8, 1.0, 1e-6]), direct=True)
    assert len(cal._dist_direct) == before


def test_a_simulators_turns_are_trusted_beyond_its_straight_steps() -> None:
    """Turns right to a thousandth of a degree (a simulator's) against scan matches of a tenth:
    the turn's part of the heading noise gets a scale of its own, below the straight steps' (it
    was never trusted more than them, and every turn on the spot let the matches turn the map).
    A turning step that also drives keeps the straight part of its noise."""
    model = _odometry._OdometryModel()
    match = np.diag([1 / 100.0, 1 / 100.0, 1 / math.radians(0.1) ** 2])  # 10 mm, 0.1 deg
    turn = math.radians(25.0)
    rng = np.random.default_rng(5)
    for k in range(400):
        # The disagreement is the match's noise alone: the odometry is exact.
        d = np.array([rng.normal(0, 10.0), rng.normal(0, 10.0), rng.normal(0, math.radians(0.1))])
        if k % 8 == 0:
            model.observe(d * [0.0, 0.0, 1.0], match, 0.0, turn)
        else:
            model.observe(d, match, 300.0, 0.0)
    model.settle()
    assert model.turn_scale is not None and model.turn_scale < 0.1 * model.scale
    sigma_turn = 1.0 / math.sqrt(model.info(0.0, turn)[2, 2])
    assert sigma_turn < 0.001 * turn, math.degrees(sigma_turn)
    # Driving a curve: the distance's part stays (the straight steps' scale).
    curve = model.info(500.0, math.radians(10.0))[2, 2]
    assert curve <= model.info(500.0, 0.0)[2, 2]
    assert curve == pytest.approx(model.info(500.0, 0.0)[2, 2], rel=0.1)


def test_a_turn_scale_the_matches_cannot_vouch_for_is_not_learnt() -> None:
    """Turn-scale samples from the steps of turns share their matches, so they can agree with
    each other far better than the matches are worth: a 0.3 % turn scale that the matches'
    own claims (0.15 degrees each) cannot tell from none is not learnt (it turned every turn of
    a simulator's exact odometry); a 2 % slip is."""
    for true, learnt in ((1.003, False), (0.98, True)):
        cal = _odometry._Calibration()
        rng = np.random.default_rng(2)
        sd = math.radians(0.15)
        for _ in range(60):
            raw = np.array([0.0, 0.0, math.radians(rng.uniform(10.0, 30.0))])
            seen = raw * [0.0, 0.0, true] + [0.0, 0.0, rng.normal(0.0, 0.02 * sd)]
            cal.observe_turn(raw, seen, np.diag([1.0, 1.0, 2 * sd * sd]))
        assert (cal.turn != 1.0) is learnt, cal.turn
        if learnt:
            assert cal.turn == pytest.approx(true, abs=0.002)


def test_a_pass_hands_on_what_all_its_drift_samples_give() -> None:
    """Drift samples that look like a drift early on and like none once the pass has seen them
    all (a few stretches whose matches lean the same way, as on a simulated robot whose odometry
    has none): the factor a pass hands on is what all its samples give, fitted when the pass
    ends, not what its last regular fit saw; and the pass still counts as having moved (the
    poses registered with the drift must be registered again)."""
    cal = _odometry._Calibration()
    cal.mark()
    straight = np.array([2000.0, 0.0, 0.0])
    corridor = np.diag([1e8, 1.0, 1e-6])  # runs that give no distance sample
    lean = math.radians(0.03) * 2.0  # 0.03 degrees per metre over 2 m
    rng = np.random.default_rng(5)
    for _ in range(50):  # a stretch that leans
        cal.observe_drift(straight, lean + rng.normal(0.0, 1e-5), 1e-6)
    for _ in range(25):  # a regular fit
        cal.observe_run(straight, straight, corridor)
    assert cal.drift == pytest.approx(math.radians(0.03) / 1000.0, rel=0.05)
    assert cal.moved
    for _ in range(150):  # the rest of the pass: none, and no regular fit after it
        cal.observe_drift(straight, rng.normal(0.0, 1e-4), 1e-6)
    assert cal.drift != 0.0  # the last regular fit's
    cal.settle()
    assert cal.drift == 0.0
    assert cal.moved
    # A pass during which the factors never changed has not moved.
    cal.mark()
    cal.settle()
    assert not cal.moved


def test_several_logs_turns_pin_the_robots_turn_error_down() -> None:
    """A robot whose turns err 0.3 %: each log's 30 turns (against matches of 0.1 degrees)
    give its turn error only coarsely; the turns of ten logs at once, within a tenth of it."""
    truth = 0.003
    alone, evidence = [], []
    for seed in range(1, 11):
        model = _odometry._OdometryModel()
        _turns_seen(model, truth, seed)
        turns = model.turns(since=0)
        assert len(turns.disagreement) == 30
        alone.append(_odometry.pooled_turn_error([turns]))
        evidence.append(turns)
    pooled = _odometry.pooled_turn_error(evidence)
    assert pooled is not None and abs(pooled - truth) < 0.1 * truth, pooled
    assert max(abs(a - truth) for a in alone if a is not None) > 3 * abs(pooled - truth), alone


@settings(max_examples=40, deadline=None)
@given(st.lists(st.integers(0, 60), min_size=1, max_size=5), st.integers(0, 2**16))
def test_pooled_turns_do_not_depend_on_how_they_are_split_into_logs(
    cuts: list[int], seed: int
) -> None:
    """The pooled fit is the fit of all the turning steps: how they fall into logs (and
    logs with none) does not change it; fewer than ten steps in all give None."""
    rng = np.random.default_rng(seed)
    n = 60
    shape = (0.03 * np.radians(rng.uniform(6.0, 90.0, n))) ** 2
    known = np.radians(rng.uniform(0.05, 0.3, n)) ** 2
    d = rng.normal(0.0, np.sqrt(known + 0.01 * shape))
    whole = _odometry.TurnEvidence(d, known, shape)
    edges = sorted({0, n, *cuts})
    logs = [
        _odometry.TurnEvidence(d[a:b], known[a:b], shape[a:b]) for a, b in itertools.pairwise(edges)
    ]
    assert _odometry.pooled_turn_error(logs) == _odometry.pooled_turn_error([whole])
    few = _odometry.TurnEvidence(d[:9], known[:9], shape[:9])
    assert _odometry.pooled_turn_error([few]) is None
    assert _odometry.pooled_turn_error([]) is None


def test_turns_since_a_step_are_that_pass_s_own() -> None:
    """What a pass's turns say leaves out the steps observed before it (the warm-up's, seen
    again by the pass); the fit's view is the latest steps."""
    model = _odometry._OdometryModel()
    _turns_seen(model, 0.003, 1)
    start = model.observed
    _turns_seen(model, 0.003, 2)
    assert model.observed == 600
    assert len(model.turns().disagreement) == 60
    own = model.turns(since=start)
    assert len(own.disagreement) == 30
    np.testing.assert_array_equal(own.disagreement, model.turns().disagreement[30:])
