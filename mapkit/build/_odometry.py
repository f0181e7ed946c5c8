"""Odometry as evidence: its noise model scaled to the log, and its systematic errors calibrated.

Poses and steps are ``(x mm, y mm, theta radians)`` numpy arrays; see :class:`_OdometryModel` and
:class:`_Calibration`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any, NamedTuple

import numpy as np

from mapkit.build._graph import wrap
from mapkit.build._match import _NOISE_HELD

FloatArray = np.ndarray[Any, np.dtype[np.float64]]

#: The noise scale is fitted on at most this many of the latest steps.
_FIT_STEPS = 3000

#: Fewest drift samples fitted (each is a scan-to-scan match over metres of path: fewer needed).
_MIN_DRIFT = 25

#: Least noise scale (log10): odometry is never trusted as exact, so scans keep a say.
_MIN_LOG_SCALE = -2.0

#: Largest noise scale (log10) either fit searches.
_MAX_LOG_SCALE = 2.0

#: Least noise scale (log10) of the turn's part of the heading noise: 0.03 % of the turn (a
#: simulator's turns, or a well-kept robot's on a hard floor, are that good).
_MIN_LOG_TURN_SCALE = -4.0


#: Added to a scan match's information before it is inverted (a corridor leaves it singular).
_EPS = np.diag([1e-8, 1e-8, 1e-4])

#: The model's shape for the turn's part of the heading noise: this fraction of the turn (its
#: scale multiplies the variance, see :meth:`_OdometryModel.parts`).
_TURN_SHAPE = 0.03

#: A step turning more than this (radians) is a turning step (its own noise scale).
_TURN = math.radians(5.0)

#: Fewest turning steps their own noise scale is fitted on.
_MIN_TURNS = 10

#: How far a robot's turns are presumed to err (a fraction of the turn, standard deviation)
#: where none is stated, unless its log's turns rule that out (:func:`_ruled_out`): a
#: simulator's, or a well-kept robot's on a hard floor (None: fitted from the log alone). One
#: log's few dozen turns resolve their error only to about +-0.004 of the model's scale: fitted
#: alone, robots whose turns err nothing or 0.03 % came out at 0.2-0.45 %, and each turn's own
#: scan match then outvoted their odometry and turned the map about the start (docs/logs.md,
#: rounds 19 and 27). A robot that slips rules it out in registration's warm-up (see
#: :meth:`_OdometryModel.presume`), and is registered as before.
_PRESUMED_TURN_ERROR: float | None = 0.001

#: The laser's scatter about the walls (mm) up to which turns are presumed good: as quiet as the
#: lasers the presumption was measured under (the benchmark's, 16 mm or less), the bar at which
#: every match's allowance for a noisy laser starts (``_match._NOISE_HELD``). Under noisier
#: ones it did worse on 144 logs, and a robot whose turns truly erred 0.1 %, with a 30 mm laser
#: and sweeps whose lag varies, came out 205.1 mm from the truth with them held there and 23.6
#: fitted from the log: a loop closure matched against the start's turning sweeps turned the map
#: (docs/logs.md, round 28).
_PRESUMED_UP_TO_NOISE = _NOISE_HELD

#: The median of chi-square with 1 degree of freedom.
_CHI2_1_HALF = 0.455


def _fit_scale(
    D: FloatArray,
    S: FloatArray,
    V: FloatArray,
    pct: float,
    target: float,
    floor: float = _MIN_LOG_SCALE,
) -> float:
    """The factor k on the odometry variances ``V`` for which the ``pct`` percentile of the
    steps' disagreements ``D`` with their scan matches (covariances ``S``), normalised by both
    noises, is ``target`` (bisection on log10 k, never below ``floor``, a log10). ``D`` and
    ``V`` may hold fewer than 3 components (``S`` matching)."""
    eye = np.eye(D.shape[1])

    def chi(k: float) -> float:
        C = S + np.einsum("ni,ij->nij", V * k, eye)
        x = np.linalg.solve(C, D[..., None])[..., 0]
        return float(np.percentile(np.einsum("ni,ni->n", D, x), pct))

    lo, hi = floor, _MAX_LOG_SCALE  # log10 of the scale, never below the floor
    if chi(10**lo) <= target:
        return float(10**lo)
    if chi(10**hi) >= target:
        return float(10**hi)
    for _ in range(20):
        mid = (lo + hi) / 2
        if chi(10**mid) > target:
            lo = mid
        else:
            hi = mid
    return float(10 ** ((lo + hi) / 2))


#: Log-likelihood by which a log's turns must prefer their own likeliest noise scale to a stated
#: one to rule it out (e^10: over four standard deviations).
_RULED_OUT = 10.0

#: Steps (log10) of the search for the turning steps' likeliest noise scale.
_RULE_OUT_STEP = 0.025

#: Degrees of freedom of the Student t the turning steps' disagreements are taken as (a few
#: matches of a turn go wrong by far more than they claim).
_TURN_NU = 4.0

#: The square of the scale a Student t of ``_TURN_NU`` degrees of freedom fits to normal data of
#: unit variance: with it, normal disagreements are taken at the variance they have.
_TURN_T_SCALE = 0.693


def _ruled_out(D: FloatArray, S: FloatArray, V: FloatArray, stated: float) -> bool:
    """Whether turning steps whose headings disagree with their matches by ``D`` (known
    variances ``S``: the match's and the straight part's; ``V``: the turn's at scale 1) rule out
    the turn scale ``stated``: their likelihood under it is ``_RULED_OUT`` (log) below that
    under their likeliest scale (searched on a grid of ``_RULE_OUT_STEP``), each taken as a
    Student t (robust to a few matches gone wrong).

    On 60 logs of ten classes a simulator's 0.1 % (0.0011) was within 4.5 of the likeliest on
    every class but the robot slipping 2 % in its turns (36-137): one log's turns resolve their
    noise only coarsely, but tell a slipping robot from a good one (docs/logs.md, round 19)."""
    grid = np.arange(_MIN_LOG_TURN_SCALE, _MAX_LOG_SCALE + _RULE_OUT_STEP / 2, _RULE_OUT_STEP)
    ks = np.append(10.0**grid, stated)
    var = _TURN_T_SCALE * (S[None, :] + ks[:, None] * V[None, :])
    cost = np.sum(
        0.5 * np.log(var) + (_TURN_NU + 1.0) / 2.0 * np.log1p(D * D / (_TURN_NU * var)), 1
    )
    return bool(cost[-1] - cost.min() > _RULED_OUT)


class TurnEvidence(NamedTuple):
    """What a log's turning steps say of how far the robot's odometry errs in its turns: per
    step (a turn of more than 5 degrees), in radians and radians squared."""

    #: How far the step's scan match turned it from its odometry (heading).
    disagreement: FloatArray
    #: The variance of that known besides the turn's own noise: the match's and the straight
    #: part's of the odometry.
    known: FloatArray
    #: The turn's own variance at noise scale 1 (the model's shape, 3 % of the turn).
    shape: FloatArray

    @classmethod
    def none(cls) -> TurnEvidence:
        """No turning steps (a log not registered, or no logs)."""
        return cls(np.zeros(0), np.zeros(0), np.zeros(0))


def _turn_scale(turns: TurnEvidence) -> float:
    """The scale of the turns' noise for which the median turning step disagrees with its
    match as much as chance gives (floored at ``_MIN_LOG_TURN_SCALE``)."""
    return _fit_scale(
        turns.disagreement[:, None],
        turns.known[:, None, None],
        turns.shape[:, None],
        50.0,
        _CHI2_1_HALF,
        floor=_MIN_LOG_TURN_SCALE,
    )


def pooled_turn_error(evidence: Iterable[TurnEvidence]) -> float | None:
    """How far a robot's turns err (a fraction of the turn, standard deviation), fitted on the
    turning steps of several of its logs at once, as :meth:`_OdometryModel._fit_turns` fits one
    log's; None when they have fewer than ``_MIN_TURNS`` turning steps in all.

    One log's few dozen turns resolve it only coarsely (a robot whose turns err 0.1 % gets
    0.03-0.4 % from one log, docs/logs.md, round 19); a robot's turns are the robot's, and the
    steps of several logs pin them down."""
    turns = list(evidence)
    pooled = (
        TurnEvidence(*(np.concatenate(parts) for parts in zip(*turns, strict=True)))
        if turns
        else TurnEvidence.none()
    )
    if len(pooled.disagreement) < _MIN_TURNS:
        return None
    return _TURN_SHAPE * math.sqrt(_turn_scale(pooled))


class _OdometryModel:
    """Odometry noise per step: distance- and turn-dependent, scaled to the log.

    The model's shape (standard deviations) is ``2 mm + 2 %`` of the distance in x and y and, in
    heading, ``0.05 deg + 0.15 deg per metre`` from the distance and ``3 %`` of the turn from the
    turn (two independent parts, see :meth:`parts`). How good a robot's odometry
    really is differs by orders of magnitude (a simulated robot's is nearly perfect, a slipping one
    is not), so the variances are scaled by a factor found from the log itself: the disagreement of
    each step's odometry with its scan match is compared with the two noises combined (scan match
    noise from its information), and the scale is chosen so that the median normalised
    disagreement is what chance gives (the median of chi-square with 3 degrees of freedom). Odometry
    that agrees with the scans better than the scans' own noise explains gets its scale lowered, so
    the scans cannot walk away from it; drifting odometry gets it raised. The turn's part has a
    scale of its own (:meth:`_fit_turns`). The scale never falls
    below a floor (``10 ** _MIN_LOG_SCALE``): odometry that is good but not perfect (a few tenths of
    a percent) is otherwise taken as exact and drifts unchecked between loop closures.
    """

    #: The 80th percentile of chi-square with 3 degrees of freedom (the fit uses the upper part
    #: of the distribution: turns, where odometry errs most, are a minority of the steps).
    _CHI2_3_P80 = 4.642

    def __init__(
        self,
        scale: float = 1.0,
        calibration: _Calibration | None = None,
        turn_scale: float | None = None,
        stated: float | None = None,
        presumed: float | None = None,
        ruled_out: bool = False,
    ) -> None:
        self.scale = scale
        #: The turns' scale as stated (see :meth:`stated_as`); None: fitted.
        self.stated = stated
        #: The turns' scale presumed when none is stated (``_PRESUMED_TURN_ERROR``), held once
        #: the log's first turns do not rule it out; None: fitted from the start.
        self.presumed = presumed
        #: Whether the log's turns ruled the stated (or presumed) scale out: then it is fitted
        #: for the rest of the log, in every pass (a later pass's first few turns cannot
        #: reinstate what the whole log's ruled out).
        self.ruled_out = ruled_out
        #: The scale of the turn's part of the heading noise (None: not known yet), see
        #: :meth:`_fit_turns`.
        self.turn_scale = stated if turn_scale is None else turn_scale
        self.calibration = calibration or _Calibration()
        self.frozen = False  # True: the calibration is final
        self._d: list[FloatArray] = []
        self._scan_cov: list[FloatArray] = []
        self._odo_var: list[FloatArray] = []
        self._turning: list[bool] = []
        #: The turn's part of each step's heading variance (the rest of ``_odo_var``'s is the
        #: distance's part).
        self._turn_var: list[float] = []
        self._next = 30

    def fresh(self) -> _OdometryModel:
        """A model for another pass: the noise scales as found, the calibration as learnt (its
        samples gone)."""
        return _OdometryModel(
            self.scale,
            self.calibration.fresh(),
            self.turn_scale,
            self.stated,
            self.presumed,
            self.ruled_out,
        )

    @staticmethod
    def stated_as(turn_error: float | None) -> _OdometryModel:
        """A model whose turns err by ``turn_error`` of the turn (standard deviation, a
        fraction), as the robot's owner knows them, unless the log's turns rule that out (see
        :meth:`_fit_turns`); None: fitted from the log (until :meth:`presume`)."""
        if turn_error is None:
            return _OdometryModel()
        return _OdometryModel(stated=_OdometryModel._turn_scale_of(turn_error))

    @staticmethod
    def _turn_scale_of(turn_error: float) -> float:
        """The turns' noise scale of a turn error (a fraction of the turn, standard deviation),
        never below the fit's own floor: odometry is never taken as exact."""
        return float(max((turn_error / _TURN_SHAPE) ** 2, 10.0**_MIN_LOG_TURN_SCALE))

    def presume(self, laser_noise: float = 0.0) -> None:
        """Hold the turns' scale at the presumed one (``_PRESUMED_TURN_ERROR``) from now on
        where none was stated, unless the turning steps seen so far rule it out (then they are
        fitted, as before). With fewer than ``_MIN_TURNS`` of them seen, the first fit that has
        them decides (:meth:`_fit_turns`). Not under a laser that scatters more than
        ``_PRESUMED_UP_TO_NOISE`` mm about the walls (``laser_noise``).

        Registration presumes after its warm-up, which fits the turns from the log alone: a
        robot that slips rules the presumption out there, and is registered as it was before
        there was one."""
        if (
            self.stated is not None
            or _PRESUMED_TURN_ERROR is None
            or laser_noise > _PRESUMED_UP_TO_NOISE
        ):
            return
        self.presumed = self._turn_scale_of(_PRESUMED_TURN_ERROR)
        turns = self.turns()
        if len(turns.disagreement) >= _MIN_TURNS:
            self._hold(turns)

    def _hold(self, turns: TurnEvidence) -> bool:
        """Hold the turns' scale at the stated one (or, none stated, the presumed one) unless
        ``turns`` rule it out (:func:`_ruled_out`), or ruled it out before; whether held."""
        held = self.stated if self.stated is not None else self.presumed
        if held is None or self.ruled_out:
            return False
        if _ruled_out(*turns, held):
            self.ruled_out = True
            return False
        self.turn_scale = held
        return True

    @property
    def turn_stated(self) -> bool:
        """Whether the turns' scale is the stated one (not ruled out by the log's turns)."""
        return self.stated is not None and not self.ruled_out and self.turn_scale == self.stated

    @property
    def turn_ruled_out(self) -> bool:
        """Whether a turns' scale was stated and the log's turns ruled it out."""
        return self.stated is not None and not self.turn_stated

    @property
    def turn_presumed(self) -> bool:
        """Whether the turns' scale is the presumed one (none stated; the log's turns did not
        rule it out)."""
        return self.presumed is not None and not self.ruled_out and self.turn_scale == self.presumed

    @property
    def turn_error(self) -> float | None:
        """How far the turns err, as a fraction of the turn (standard deviation), as stated,
        presumed or fitted (None: no turns seen)."""
        return None if self.turn_scale is None else _TURN_SHAPE * math.sqrt(self.turn_scale)

    @staticmethod
    def variances(trans: float, turn: float) -> FloatArray:
        """The model's shape: variances of x, y and heading at scale 1 (the turn's part
        included, see :meth:`parts`)."""
        s_xy, s_th, s_turn = _OdometryModel.parts(trans, turn)
        return np.array([s_xy * s_xy, s_xy * s_xy, s_th * s_th + s_turn * s_turn])

    @staticmethod
    def parts(trans: float, turn: float) -> tuple[float, float, float]:
        """Standard deviations at scale 1: in x and y, of the heading from the distance (and a
        floor), and of the heading from the turn. The last is what wheel slip makes, and is
        scaled on its own (:meth:`_fit_turns`)."""
        s_xy = 2.0 + 0.02 * trans
        s_th = math.radians(0.05) + math.radians(0.15) * trans / 1000.0
        return s_xy, s_th, _TURN_SHAPE * abs(turn)

    def info(self, trans: float, turn: float) -> FloatArray:
        s_xy, s_th, s_turn = self.parts(trans, turn)
        turn_scale = self.turn_scale
        if turn_scale is None:
            # Until turns enough were seen, the model's own shape: a few percent of the turn.
            turn_scale = max(self.scale, 1.0) if abs(turn) > _TURN else self.scale
        var_xy = self.scale * s_xy * s_xy
        var_th = self.scale * s_th * s_th + turn_scale * s_turn * s_turn
        return np.diag(1.0 / np.array([var_xy, var_xy, var_th]))

    def settle(self) -> None:
        """Fit now (on what was seen) and keep what was seen for later fits."""
        if self._d:
            self._fit()

    def observe(
        self,
        d: FloatArray,
        scan_info: FloatArray,
        trans: float,
        turn: float,
        extra: FloatArray | None = None,
    ) -> None:
        """One step's disagreement ``d`` of its scan match (information ``scan_info``) with the
        odometry over ``trans`` and ``turn``; ``extra``: further variances of the step (x, y,
        heading) known besides the model's, counted with the match's."""
        self._d.append(d.copy())
        cov: FloatArray = np.linalg.inv(scan_info + _EPS).astype(np.float64)
        if extra is not None and extra.any():
            cov = cov + np.diag(extra)
        self._scan_cov.append(cov)
        self._odo_var.append(self.variances(trans, turn))
        s_turn = self.parts(trans, turn)[2]
        self._turn_var.append(s_turn * s_turn)
        self._turning.append(abs(turn) > _TURN)
        if len(self._d) >= self._next:
            self._next = int(len(self._d) * 1.3) + 10
            self._fit()

    def _fit(self) -> None:
        # The latest steps (a few thousand are plenty, and keep long logs fast).
        D = np.array(self._d[-_FIT_STEPS:])
        S = np.array(self._scan_cov[-_FIT_STEPS:])
        V = np.array(self._odo_var[-_FIT_STEPS:])
        self.scale = _fit_scale(D, S, V, 80.0, self._CHI2_3_P80)
        self._fit_turns()

    def _fit_turns(self) -> None:
        """The scale of the turn's part of the heading noise on its own, once there are turns
        enough.

        A turn's error is mostly wheel slip, which the straight steps (the most of a log) say
        nothing of: with one scale fitted to all, a robot that slips 2 % in its turns gets its
        turns trusted to a few tenths of a percent, and the scans that see the slip are
        outvoted by it. The other way round, a simulator's turns are right to a few hundredths
        of a percent: trusted like its straight steps, every turn on the spot lets the scans
        (a tenth of a degree each on a noisy laser) turn the map. So the turn's part gets its
        own scale, down to ``_MIN_LOG_TURN_SCALE``; the distance's part of a turning step (drift
        while driving a curve) keeps the straight steps' scale.

        A stated scale (:meth:`stated_as`) is kept unless the turning steps rule it out
        (:func:`_ruled_out`); then they are fitted as when none is stated. With none stated, the
        presumed scale is held once there are turning steps enough to test it and they do not
        rule it out: until then a turn is trusted to the model's own shape, as a fitted one is,
        so that a robot that slips is not held to it before its turns were heard. Ruled out
        once, either is fitted from then on.
        """
        turns = self.turns()
        if len(turns.disagreement) < _MIN_TURNS:
            return  # as before (from an earlier pass, or none)
        if not self._hold(turns):
            self.turn_scale = _turn_scale(turns)

    @property
    def observed(self) -> int:
        """How many steps were observed (:meth:`observe`)."""
        return len(self._d)

    def turns(self, since: int | None = None) -> TurnEvidence:
        """What the turning steps say of the turns' noise: the latest ``_FIT_STEPS`` (what the
        fit takes), or all observed from step ``since`` on."""
        turning = np.flatnonzero(self._turning)
        turning = turning[-_FIT_STEPS:] if since is None else turning[turning >= since]
        # The heading alone: a turn on the spot hardly moves, what it gets wrong is the angle.
        D = np.array([self._d[k][2] for k in turning], dtype=np.float64)
        # What is not the turn's own part is known noise: the match's and the straight part.
        turn_var = np.array([self._turn_var[k] for k in turning], dtype=np.float64)
        S = np.array([self._scan_cov[k][2, 2] for k in turning], dtype=np.float64)
        S += self.scale * (np.array([self._odo_var[k][2] for k in turning]) - turn_var)
        return TurnEvidence(D, S, turn_var)


class _Calibration:
    """Systematic odometry errors learnt from the scan matches: distance scale, turn scale, drift.

    A wrong wheel diameter makes every distance too long or short, a wrong wheel base every turn,
    unequal wheels a steady heading drift per metre. Where two scan matches pin the motion between
    them down (the walls in view fix the direction of travel, or the heading), the motion they saw
    is compared with the raw odometry over the same steps: over a metre or more of path for the
    distance scale and the drift, over one step for a turn on the spot. The median ratio (or drift
    per metre) is applied to the odometry of later steps when it differs from none by more than
    three times its standard error, so that good odometry is left alone.

    The motion is taken between matches, not between the estimate and a match: the estimate is
    odometry and scans fused, so it lags behind the scans, and the lag would be counted again in
    every step's disagreement (and the correction overshoot).
    """

    _MIN = 50

    def __init__(self) -> None:
        self.dist = 1.0
        self.turn = 1.0
        self.drift = 0.0  # radians per mm
        self._dist: list[float] = []
        #: Distance scale samples matched scan to scan (see :meth:`observe_run`).
        self._dist_direct: list[float] = []
        self._turn: list[float] = []
        self._turn_info: list[float] = []
        self._drift: list[float] = []
        self._seen = 0
        #: The factors kept until there are samples enough for new ones (see :meth:`fresh`).
        self._prior = (1.0, 1.0, 0.0)
        #: The factors :meth:`moved` compares with, and whether they differed from them.
        self._mark = (1.0, 1.0, 0.0)
        self._moved = False

    def fresh(self) -> _Calibration:
        """A calibration that starts from this one's factors but forgets its observations; it
        keeps them until it has samples enough of its own."""
        c = _Calibration()
        c.dist, c.turn, c.drift = self.dist, self.turn, self.drift
        c._prior = (self.dist, self.turn, self.drift)
        return c

    @property
    def factors(self) -> tuple[float, float, float]:
        """Distance scale, turn scale and drift (radians per mm) as applied now."""
        return self.dist, self.turn, self.drift

    def summary(self) -> dict[str, float]:
        """The factors, for the build's summary."""
        return {
            "distance_scale": round(self.dist, 5),
            "turn_scale": round(self.turn, 5),
            "drift_deg_per_m": round(math.degrees(self.drift) * 1000.0, 4),
        }

    def correct(self, raw: FloatArray) -> FloatArray:
        out = raw.copy()
        out[:2] *= self.dist
        trans = math.hypot(raw[0], raw[1])
        out[2] = wrap(raw[2] * self.turn + self.drift * trans)
        return out

    def observe_run(
        self, raw: FloatArray, motion: FloatArray, var: FloatArray, *, direct: bool = False
    ) -> None:
        """A run of a metre or more: its raw odometry, and the motion the scans saw over it.

        ``motion`` is the later scan's pose in the earlier one's frame and ``var`` its 3x3
        covariance (in the frame ``motion`` is given in). A direction the scans do not fix (a
        corridor's axis) has a large variance and gives no sample.

        ``direct``: the motion was matched scan to scan, not between two local-map matches. The
        local map is laid out with the odometry being calibrated, and over metres its length
        leans towards it: on a simulated building (0.5 % too long, a true scale of 0.99502) the
        local-map samples gave 0.99607, their motions 1.0 mm too long on a median run, where
        scan to scan gave -0.1 mm. The scale is fitted on the direct samples once there are
        ``_MIN`` of them (a long log), on the local map's until then (a short log has few runs a
        direct match can measure). Direct samples come with the drift's (see
        :class:`~mapkit.build._calibrate.CalibrationFeed`) and, like them, do not count
        towards the next fit.
        """
        trans_raw = math.hypot(raw[0], raw[1])
        if trans_raw < 1.0 or abs(raw[2]) > math.radians(3.0):
            return
        u = np.array([raw[0], raw[1]]) / trans_raw
        c, s = math.cos(motion[2]), math.sin(motion[2])
        u_frame = np.array([c * u[0] - s * u[1], s * u[0] + c * u[1]])
        sig_u = math.sqrt(max(float(u_frame @ var[:2, :2] @ u_frame), 0.0))
        if sig_u < 0.01 * trans_raw:
            (self._dist_direct if direct else self._dist).append(float(motion[:2] @ u) / trans_raw)
        if not direct:
            self._count()

    def observe_drift(self, raw: FloatArray, turn: float, var: float) -> None:
        """A straight run: its raw odometry, the turn the scans saw over it and that turn's
        variance (radians squared)."""
        trans_raw = math.hypot(raw[0], raw[1])
        if trans_raw < 1.0 or math.sqrt(var) > math.radians(0.3):
            return
        self._drift.append((turn - raw[2] * self.turn) / trans_raw)

    @staticmethod
    def on_the_spot(raw: FloatArray) -> bool:
        """Whether a raw odometry step is a turn on the spot (a turning step that hardly moves)."""
        return math.hypot(raw[0], raw[1]) < 50.0 and abs(raw[2]) > _TURN

    def observe_turn(self, raw: FloatArray, motion: FloatArray, var: FloatArray) -> None:
        """One step (see :meth:`observe_run`): a turn on the spot gives a turn scale sample."""
        if not self.on_the_spot(raw):
            return
        if math.sqrt(var[2, 2]) < 0.05 * abs(raw[2]):
            self._turn.append(float(motion[2]) / raw[2])
            # The ratio's weight: its inverse variance (a small turn's ratio is a noisy one).
            self._turn_info.append(float(raw[2]) ** 2 / max(float(var[2, 2]), 1e-12))
        self._count()

    def _count(self) -> None:
        self._seen += 1
        if self._seen % (25 if self._seen < 1000 else 250) == 0:
            self.settle()

    def settle(self) -> None:
        """Fit the factors now, on all samples so far (a pass ends with this: the factors it
        hands on are those all its samples give, not those of the last regular fit)."""
        dist, turn, drift = self._prior
        direct = len(self._dist_direct) >= self._MIN
        self.dist = self._fit(self._dist_direct if direct else self._dist, 1.0, dist)
        self.turn = self._fit(self._turn, 1.0, turn, weights=self._turn_info)
        self.drift = self._fit(self._drift, 0.0, drift, least=_MIN_DRIFT)
        self._moved = self._moved or _apart(self.factors, self._mark)

    def mark(self) -> None:
        """Remember the factors as they are now (see :meth:`moved`)."""
        self._mark = self.factors
        self._moved = False

    @property
    def moved(self) -> bool:
        """Whether the factors applied differed from the ones at :meth:`mark` at any fit since
        (a drift learnt half way and dropped at the end still turned the poses registered
        with it)."""
        return self._moved

    @property
    def drift_samples(self) -> list[float]:
        """The drift samples so far (radians per mm)."""
        return self._drift

    def _fit(
        self,
        obs: list[float],
        none: float,
        prior: float,
        least: int = 0,
        weights: list[float] | None = None,
    ) -> float:
        """The median of ``obs`` where it differs from ``none`` (no error) by more than three
        standard errors, else ``none``; ``prior`` while there are too few samples. ``weights``:
        the samples' inverse variances, which bound the standard error from below."""
        if len(obs) < (least or self._MIN):
            return prior
        a = np.array(obs)
        med = float(np.median(a))
        err = 1.4826 * float(np.median(np.abs(a - med))) * 1.25 / math.sqrt(len(a))
        if weights is not None:
            # What the samples' matches claim (inverse variances): the spread of samples that
            # share matches (one turn's steps do) can look smaller than it is.
            err = max(err, 1.25 / math.sqrt(float(np.sum(weights))))
        return med if abs(med - none) > 3.0 * err else none


def _apart(a: tuple[float, float, float], b: tuple[float, float, float]) -> bool:
    """Whether two calibrations' factors (see :attr:`_Calibration.factors`) differ by enough
    to matter."""
    return (
        abs(a[0] - b[0]) > 0.003
        or abs(a[1] - b[1]) > 0.01
        or abs(a[2] - b[2]) > math.radians(0.02) / 1000.0
    )
