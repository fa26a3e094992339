"""Fitted numbers with their uncertainty, on :mod:`scipy.stats`.

Every number a study fits (a slope, an RMS residual, a threshold, a
stiffness, an R^2, a rank correlation) is an :class:`Estimate`: the value,
its standard error where one is defined, and a 95 % interval with the method
that gave it.  Bootstrap intervals are seeded (:data:`BOOTSTRAP_SEED` unless
given), so the same data give the same interval.

* :func:`line_fit` -- least squares ``y = slope x + intercept``
  (``scipy.stats.linregress``: standard errors of slope and intercept; the
  interval is Student's t with ``n - 2`` degrees of freedom; R^2 with a
  paired BCa bootstrap interval).
* :func:`mirrored_line_fit`, :func:`clustered_line_fit` -- the same fit where rows are not
  independent: a mirror-symmetric design's pairs, or clusters of rows that may share their errors
  (a cluster jackknife, CR3).
* :func:`rank_correlation` -- Spearman's rho (``scipy.stats.spearmanr``:
  tied values get their average rank) with a paired percentile bootstrap interval, none where
  too few orderings exist for any to exclude rho = 0 at the level.
* :func:`rms`, :func:`std` -- root mean square, standard deviation, with a BCa bootstrap
  interval.
* :func:`mean` -- mean with its standard error (t interval).
* :func:`bootstrap` -- any statistic of one or more paired samples; bias-corrected and
  accelerated (BCa) unless asked for the plain percentile interval, which undercovers
  the upper side of an RMS, a standard deviation or an R^2 (docs/verdicts.md); either at
  Hesterberg's expanded levels (:func:`expanded_z`: a bootstrap of few points is too narrow).

Intervals that cannot be formed (too few points, a degenerate resample) are
NaN; :meth:`Estimate.to_dict` turns NaN into ``None`` for JSON.

**Domains.**  A reported number and its interval stay inside the quantity's physical domain (a
density or a width is not negative, an R^2 is at most 1, a correlation lies in [-1, 1], a count is
not negative, a fraction lies in [0, 1]): :data:`DOMAINS` names the domain of a summary key by its
name, and :func:`domain_violations` walks a study's summary and claim values for numbers outside
theirs (:func:`undulate.claims.collect` refuses a study that reports one).  An interval that leaves
its domain comes from a method that does not fit its quantity (a t interval on two draws of a
density reached -2.02), and is fixed there, never clipped.

**Repeated looks.**  A study that adds runs in stages looks at its intervals
after every stage (:mod:`undulate.studies._registry`).  Every interval of a
look is formed at the level :func:`level` returns, which the registry sets
for the look with :func:`at_level` (:func:`look_levels`: the family-wise
``1 - CONFIDENCE`` split over the looks, Bonferroni); ``ci95`` in
:meth:`Estimate.to_dict` is that interval and ``level`` its level.  Outside a
look the level is :data:`CONFIDENCE`.
"""

from __future__ import annotations

import contextlib
import contextvars
import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import ParameterError

__all__ = ["Estimate", "LineFit", "line_fit", "mirrored_line_fit", "clustered_line_fit", "joined_clusters",
           "is_mirror_design", "rank_correlation", "rms",
           "std", "mean", "bootstrap", "expanded_z", "BOOTSTRAP_SEED", "N_RESAMPLES", "CONFIDENCE", "level", "at_level",
           "look_levels", "plan_level", "interval_note", "Check", "decide", "all_of", "runs_needed",
           "half_width_at", "DOMAINS", "domain_of", "domain_violations", "check_domains"]

CONFIDENCE = 0.95
"""The family-wise confidence of every claim's verdict: ``holds`` means 95 %."""

LOOK_SHARES = {1: (1.0,), 2: (0.2, 0.8), 3: (0.1, 0.3, 0.6), 4: (0.05, 0.15, 0.3, 0.5)}
"""How :func:`look_levels` splits ``alpha = 1 - CONFIDENCE`` over K looks: shares that sum to 1,
small early (the shape of O'Brien-Fleming's spending: an early look stops only for a clear answer)."""

_LEVEL: contextvars.ContextVar[float] = contextvars.ContextVar("undulate_confidence_level", default=CONFIDENCE)
_PLAN_LEVEL: contextvars.ContextVar[float | None] = contextvars.ContextVar("undulate_plan_level", default=None)


def level() -> float:
    """The confidence level of the intervals formed now (:data:`CONFIDENCE` outside a staged look)."""
    return _LEVEL.get()


def plan_level() -> float | None:
    """The level at which :func:`runs_needed` asks an interval to be decided: the last look's where a
    staged study set it (:func:`at_level`'s ``plan_at``), else None (each estimate's own level)."""
    return _PLAN_LEVEL.get()


def _confidence(v, name: str = "confidence") -> float:
    """A confidence level: a real number in (0, 1); else a ParameterError naming ``name``."""
    ok = isinstance(v, float | int | np.floating | np.integer) and not isinstance(v, bool | np.bool_)
    if not ok or not 0.0 < float(v) < 1.0:
        raise ParameterError(name, "a level in (0, 1)", v)
    return float(v)


@contextlib.contextmanager
def at_level(confidence: float, plan_at: float | None = None) -> Iterator[float]:
    """Form every interval inside the ``with`` block at ``confidence`` (0 < confidence < 1).

    ``plan_at``: the level of the look that more runs would be judged at (a staged study's last look,
    whose share of alpha is the largest); :func:`runs_needed` estimates the runs that would decide an
    interval there.  Default: each estimate's own level (``confidence`` for those formed in the block)."""
    _confidence(confidence)
    if plan_at is not None:
        _confidence(plan_at, "plan_at")
    token = _LEVEL.set(float(confidence))
    plan = _PLAN_LEVEL.set(None if plan_at is None else float(plan_at))
    try:
        yield float(confidence)
    finally:
        _PLAN_LEVEL.reset(plan)
        _LEVEL.reset(token)


def interval_note(at: float | None = None) -> str:
    """How a measured text names intervals formed at level ``at`` (an estimate's ``level``; default: the
    level now): "95 % intervals" for a single look, else that level with the family-wise 95 % it keeps,
    e.g. "97 % intervals, 95 % over the looks"."""
    lv = level() if at is None else float(at)
    if abs(lv - CONFIDENCE) < 1e-12:
        return f"{100 * CONFIDENCE:g} % intervals"
    return f"{100 * lv:.3g} % intervals, {100 * CONFIDENCE:g} % over the looks"


def look_levels(n_looks: int, confidence: float = CONFIDENCE) -> tuple[float, ...]:
    """The per-look confidence levels of a plan looked at ``n_looks`` times.

    Bonferroni over the looks: look k forms its intervals at ``1 - alpha_k``
    with ``sum(alpha_k) = alpha = 1 - confidence`` (shares
    :data:`LOOK_SHARES`).  By the union bound the chance that *any* look's
    interval misses the true value is at most ``alpha``, whatever the looks'
    dependence, so a verdict taken at whichever look decides it keeps the
    family-wise ``confidence`` (``holds`` means 95 %).  ``n_looks`` beyond the
    table split alpha equally.
    """
    if isinstance(n_looks, bool) or not isinstance(n_looks, int) or n_looks < 1:
        raise ParameterError("n_looks", "an integer >= 1", n_looks)
    _confidence(confidence)
    alpha = 1.0 - confidence
    shares = LOOK_SHARES.get(n_looks, (1.0 / n_looks,) * n_looks)
    return tuple(1.0 - alpha * s for s in shares)
BOOTSTRAP_SEED = 20240601
"""Seed of every bootstrap unless the caller gives one (results are reproducible)."""
N_RESAMPLES = 2000


def _f(v: Any) -> float:
    try:
        v = float(v)
    except (TypeError, ValueError):
        return math.nan
    return v


@dataclass(frozen=True)
class Estimate:
    """A fitted number with its uncertainty.

    ``value``; ``stderr`` (NaN where the method gives none); ``low``, ``high``:
    the 95 % interval; ``n``: data points used; ``method``: how the interval
    was made (``"t interval"``, ``"bootstrap BCa"``, ...).

    How the interval would narrow with more runs (:func:`runs_needed`): ``units``, the independent
    units its spread is estimated from (points, mirror pairs, clusters; 0: unknown), and ``dof``, the
    degrees of freedom of the Student-t quantile it was formed with (``units - 2`` for a line fit's
    slope, ``units - 1`` for a mean, the fold's pairs less one, and ``units - 1`` for a bootstrap at
    :func:`expanded_z`'s levels); NaN where its quantile does not depend on the units.
    """

    value: float
    stderr: float = math.nan
    low: float = math.nan
    high: float = math.nan
    n: int = 0
    method: str = ""
    level: float = CONFIDENCE
    units: int = 0
    dof: float = math.nan

    def _key(self) -> tuple:
        """The fields, a NaN as None: NaN marks what a method does not give (no interval, no spread)."""
        return tuple(None if isinstance(v, float) and math.isnan(v) else v
                     for v in (self.value, self.stderr, self.low, self.high, self.n, self.method, self.level,
                               self.units, self.dof))

    def __eq__(self, other: object) -> bool:
        """Equal fields, two NaNs equal: Python 3.13's dataclass equality compares field by field with
        ``==``, where ``nan != nan`` made every estimate without an interval unequal to itself."""
        if other.__class__ is not self.__class__:
            return NotImplemented
        return self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    @property
    def finite(self) -> bool:
        return math.isfinite(self.value)

    @property
    def has_interval(self) -> bool:
        return math.isfinite(self.low) and math.isfinite(self.high)

    def scaled(self, factor: float) -> Estimate:
        """The same estimate in other units (``factor > 0``)."""
        return Estimate(self.value * factor, self.stderr * factor, self.low * factor, self.high * factor,
                        self.n, self.method, self.level, self.units, self.dof)

    def inside(self, lo: float = -math.inf, hi: float = math.inf) -> bool | None:
        """True if the whole interval lies in ``[lo, hi]``, False if it lies wholly outside,
        None when it straddles a bound or there is no interval."""
        if not self.has_interval:
            return None
        if lo <= self.low and self.high <= hi:
            return True
        if self.high < lo or self.low > hi:
            return False
        return None

    def within(self, lo: float, hi: float, what: str = "") -> Check:
        """A :class:`Check`: the interval inside ``[lo, hi]``, wholly outside, or straddling a bound."""
        return _within(self, lo, hi, what)

    def below(self, hi: float, what: str = "") -> Check:
        """A :class:`Check`: the interval below ``hi``, wholly above it, or straddling it."""
        return _within(self, -math.inf, hi, what)

    def above(self, lo: float, what: str = "") -> Check:
        """A :class:`Check`: the interval above ``lo``, wholly below it, or straddling it."""
        return _within(self, lo, math.inf, what)

    def to_dict(self) -> dict[str, Any]:
        def j(v: float) -> float | None:
            return float(v) if math.isfinite(v) else None

        return {"value": j(self.value), "stderr": j(self.stderr), "ci95": [j(self.low), j(self.high)],
                "n": int(self.n), "method": self.method, "level": float(self.level), "units": int(self.units),
                "dof": j(self.dof)}

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> Estimate:
        """Inverse of :meth:`to_dict`: ``None`` (a missing entry) gives a NaN estimate, an
        :class:`Estimate` itself; anything else is a TypeError (never a silent NaN)."""
        if d is None:
            return cls(math.nan)
        if isinstance(d, Estimate):
            return d
        if not isinstance(d, dict):
            raise TypeError(f"Estimate.from_dict takes a dict from Estimate.to_dict, None or an Estimate, "
                            f"not {type(d).__name__}")
        lo, hi = (d.get("ci95") or [None, None])[:2]
        return cls(_f(d.get("value")), _f(d.get("stderr")), _f(lo), _f(hi), int(d.get("n") or 0),
                   str(d.get("method", "")), float(d.get("level") or CONFIDENCE), int(d.get("units") or 0),
                   _f(d.get("dof")))

    def __format__(self, spec: str) -> str:
        spec = spec or ".3g"
        if not self.finite:
            return "n/a"
        s = format(self.value, spec)
        if self.has_interval:
            s += f" [{format(self.low, spec)}, {format(self.high, spec)}]"
        elif math.isfinite(self.stderr):  # a spread has no sign: "-0.50 ± 0.82", not "± +0.82"
            s += f" ± {format(self.stderr, spec.replace('+', '').replace(' ', ''))}"
        return s

    def __str__(self) -> str:
        return format(self, "")


NAN = Estimate(math.nan)


def _g(v: float) -> str:
    return format(v, ".3g")


@dataclass(frozen=True)
class Check:
    """One criterion of a claim, judged on an interval: three outcomes.

    ``state``: True when the interval lies inside the accepted region, False
    when it lies wholly outside, None when it straddles a boundary (or there is
    no interval: then ``runs_needed`` is None too).  ``text`` names what was
    checked, the interval and, when undecided, the boundary it straddles.
    ``runs_needed``: for a straddling interval, about how many runs (points)
    would make its half-width shorter than the estimate's distance from the
    boundary at :func:`plan_level` or the interval's own (:func:`runs_needed`; None when the
    estimate sits on it).
    Make them with :meth:`Estimate.within`, :meth:`Estimate.below`,
    :meth:`Estimate.above`, :meth:`Check.apart` or :meth:`Check.exact`.
    """

    state: bool | None
    text: str
    runs_needed: int | None = None
    growth_needed: float | None = None
    """``runs_needed`` over the runs the interval rests on: how many times more runs would decide it."""

    @classmethod
    def exact(cls, ok: bool, text: str) -> Check:
        """A criterion on a count or an exact number (no interval): never undecided."""
        return cls(bool(ok), text)

    @classmethod
    def apart(cls, a: Estimate, b: Estimate, what: str) -> Check:
        """``a > b`` judged on both intervals: True when ``a``'s lies wholly above ``b``'s, False when
        wholly below, None when they overlap (``what`` names the comparison; ``runs_needed``: the runs
        at which the two facing half-widths, narrowing as :func:`runs_needed` says, would fit between
        the values)."""
        if not (a.has_interval and b.has_interval):
            return cls(None, f"{what}: no interval")
        if a.low > b.high:
            return cls(True, f"{what}: [{_g(a.low)}, {_g(a.high)}] above [{_g(b.low)}, {_g(b.high)}]")
        if a.high < b.low:
            return cls(False, f"{what}: [{_g(a.low)}, {_g(a.high)}] below [{_g(b.low)}, {_g(b.high)}]")
        gap = abs(a.value - b.value)
        up, down = (a, b) if a.value >= b.value else (b, a)  # the facing half-widths: up's lower, down's upper
        g = _growth(((up, up.value - up.low), (down, down.high - down.value)), gap)
        n = min(a.n, b.n)
        needed = int(math.ceil(n * g - 1e-9)) if n > 0 and g is not None else None
        return cls(None, f"{what}: [{_g(a.low)}, {_g(a.high)}] overlaps [{_g(b.low)}, {_g(b.high)}]", needed,
                   g if needed is not None else None)


def _quantile(conf: float, dof: float) -> float:
    """The upper quantile an interval at ``conf`` uses: Student's t on ``dof`` degrees of freedom, the
    normal's for ``dof`` NaN (or infinite)."""
    from scipy import stats as st

    p = (1 + conf) / 2
    return float(st.norm.ppf(p)) if not math.isfinite(dof) else float(st.t.ppf(p, dof))


def half_width_at(e: Estimate, half: float, growth: float, conf: float | None = None) -> float:
    """The half-width ``half`` of ``e``'s interval with ``growth`` times its runs, formed at ``conf``
    (default :func:`plan_level`, else the estimate's own level), the estimate's value and spread
    staying put: ``half * q(conf, dof') / q(e.level, dof) / sqrt(growth)`` with
    ``dof' = growth * units - (units - dof)`` (the same number of fitted parameters on more units) and
    ``q`` the quantile of :func:`_quantile`.  An estimate with no ``dof`` keeps its quantile's shape
    (the normal's): only the level and the 1/sqrt(n) change."""
    conf = (plan_level() or e.level) if conf is None else float(conf)
    dof = e.dof if (e.units > 0 and math.isfinite(e.dof) and e.dof > 0) else math.nan
    dof_g = growth * e.units - (e.units - dof) if math.isfinite(dof) else math.nan
    return half * _quantile(conf, dof_g) / _quantile(e.level, dof) / math.sqrt(growth)


def _growth(sides: Sequence[tuple[Estimate, float]], gap: float) -> float | None:
    """The least growth ``g >= 1`` of the runs at which the half-widths ``sides`` (each an estimate and
    its half-width facing the boundary), narrowing as :func:`half_width_at` says, add up to no more than
    ``gap``; None when ``gap`` is not positive or no half-width is (nothing to extrapolate)."""
    from scipy.optimize import brentq

    if not (gap > 0 and all(math.isfinite(h) and h >= 0 for _, h in sides) and sum(h for _, h in sides) > 0):
        return None

    def excess(log_g: float) -> float:
        return sum(half_width_at(e, h, math.exp(log_g)) for e, h in sides) - gap

    if excess(0.0) <= 0:
        return 1.0
    hi = 1.0  # log g: every half-width falls at least as 1/sqrt(g), so a bracket is found
    while excess(hi) > 0:
        if hi >= 32:  # ~1e14 times the runs: nothing would decide it
            return None
        hi *= 2
    return math.exp(brentq(excess, 0.0, hi, xtol=1e-10, rtol=1e-12))


def runs_needed(e: Estimate, bound: float) -> int | None:
    """About how many runs (``e.n``'s units: runs or points) would bring the half-width of ``e``'s
    interval on the side facing ``bound`` to the estimate's distance from ``bound`` at
    :func:`plan_level` (else at the estimate's own level), if the value and the spread stay where they are.

    The half-width narrows as ``q(dof) / sqrt(n)`` (:func:`half_width_at`): Student's t quantile falls
    as the degrees of freedom grow with the runs, which a plain 1/sqrt(n) rule ignores. On few units
    that rule is far too pessimistic: a slope on 2 mirror pairs at 99 % (t on 1 dof: 63.7) whose
    half-width is 40 times its distance from the boundary needs ~9 pairs, not the rule's 3 200
    (tests/test_runs_needed.py).  None when the estimate sits on the boundary or the interval has no
    width."""
    gap = abs(e.value - bound)
    half = (e.value - e.low) if bound < e.value else (e.high - e.value)
    g = _growth(((e, half),), gap) if e.n > 0 else None
    return None if g is None else int(math.ceil(e.n * g - 1e-9))


def _within(e: Estimate, lo: float, hi: float, what: str) -> Check:
    region = (f"[{_g(lo)}, {_g(hi)}]" if math.isfinite(lo) and math.isfinite(hi)
              else f"> {_g(lo)}" if math.isfinite(lo) else f"< {_g(hi)}")
    head = f"{what} {e:.3g}"
    state = e.inside(lo, hi)
    if not e.has_interval:
        return Check(None, f"{head}: no interval")
    if state is True:
        return Check(True, f"{head} inside {region}")
    if state is False:
        return Check(False, f"{head} wholly outside {region}")
    straddled = [b for b in (lo, hi) if math.isfinite(b) and e.low <= b <= e.high]
    needed = [runs_needed(e, b) for b in straddled]
    n = None if None in needed or not needed else max(needed)  # type: ignore[type-var]
    bounds = " and ".join(_g(b) for b in straddled)
    return Check(None, f"{head} straddles {bounds} (region {region})", n, None if n is None else n / e.n)


def all_of(*states: bool | None) -> bool | None:
    """Three-valued AND: False if any state is False, else None if any is None (undecided), else True."""
    states_ = [None if s is None else bool(s) for s in states]
    if False in states_:
        return False
    if None in states_:
        return None
    return True


def decide(checks: Sequence[Check]) -> bool | None:
    """Several criteria of one claim: False if any fails, else None if any is undecided, else True."""
    return all_of(*(c.state for c in checks))


def _values(name: str, a) -> np.ndarray:
    """``a`` as a flat float array; a ParameterError naming ``name`` where it holds what is not a real number."""
    if a is None or isinstance(a, (str, bytes)):
        raise ParameterError(name, "an array of real numbers", type(a).__name__)
    try:
        return np.asarray(a, float).ravel()
    except (TypeError, ValueError):  # strings, a ragged list
        raise ParameterError(name, "an array of real numbers", type(a).__name__) from None


def _paired(*arrays, names: Sequence[str] = ("x", "y")) -> list[np.ndarray]:
    """``arrays`` (named ``names``) as flat float arrays of one length: paired rows."""
    arrs = [_values(name, a) for name, a in zip(names, arrays, strict=True)]
    for name, a in zip(names[1:], arrs[1:]):
        if a.size != arrs[0].size:
            raise ParameterError(name, f"as many values as {names[0]} ({arrs[0].size})", a.size)
    return arrs


def _clean(*arrays, names: Sequence[str] = ("x", "y")) -> tuple[np.ndarray, ...]:
    """The rows of ``arrays`` (paired, :func:`_paired`) where every one is finite."""
    arrs = _paired(*arrays, names=names)
    ok = np.ones(arrs[0].shape, bool)
    for a in arrs:
        ok &= np.isfinite(a)
    return tuple(a[ok] for a in arrs)


BOOTSTRAP_METHODS = ("BCa", "percentile")


def expanded_z(conf: float, n: int) -> float:
    """The normal quantile a bootstrap interval of ``n`` resampled points uses at level ``conf``:
    ``sqrt(n / (n - 1)) t_{n-1}((1 + conf) / 2)`` (Hesterberg's expanded percentile levels, ``ExpandProbs``
    of his R package ``resample``; Hesterberg 2015, *What teachers should know about the bootstrap*,
    Am. Stat. 69, 371).  A bootstrap distribution is about ``sqrt((n - 1) / n)`` as wide as the
    statistic's own, and a normal quantile stands where Student's t should for a spread estimated from
    ``n`` points; both make small-sample intervals too narrow.  ``z_{(1 + conf) / 2}`` itself for
    ``n = inf``; at 95 %: 3.10 at 5 points, 2.45 at 9, 2.19 at 17, 2.07 at 33 (against 1.96)."""
    from scipy import stats as st

    if not math.isfinite(n):
        return float(st.norm.ppf((1 + conf) / 2))
    if n < 2:
        return math.inf
    return math.sqrt(n / (n - 1)) * float(st.t.ppf((1 + conf) / 2, n - 1))


def bootstrap(statistic: Callable[..., float], *samples, seed: int | None = None,
              n_resamples: int = N_RESAMPLES, vectorized: bool = False,
              method: str = "BCa", expand: bool = True) -> tuple[float, float, float]:
    """Paired bootstrap of ``statistic(*samples)`` (``scipy.stats.bootstrap`` draws the resamples).

    ``samples``: equally long 1-D arrays resampled together.  Returns ``(stderr, low, high)``: the
    standard deviation of the bootstrap distribution and the interval at the current level
    (:func:`level`).  ``method``: ``"BCa"`` (bias-corrected and accelerated; Efron & Tibshirani 1993,
    ch. 14: the percentiles moved by the distribution's median bias ``z0`` and the jackknife's
    acceleration ``a``; :func:`_bca_levels`) or ``"percentile"`` (the distribution's plain
    percentiles, whose upper bound on an RMS or an R^2 falls
    short of the truth several times more often than it says: docs/verdicts.md).  A resample on which
    the statistic is undefined (NaN: an R^2 of a resample with no spread) is left out of the
    distribution, and of the jackknife, rather than voiding the interval as ``scipy.stats.bootstrap``'s
    own BCa interval does; with no such resample the BCa interval is scipy's to rounding
    (tests/test_bootstrap.py).  NaNs with fewer than 3 points, when over half the resamples are
    undefined, or when the statistic of the sample itself is undefined or lies outside every
    resample's (no bias correction exists).  ``vectorized``: ``statistic(*xs, axis=-1)`` takes every
    resample at once (rows of 2-D arrays); the resamples are the same as without it (scipy draws them
    before evaluating), only evaluated in one NumPy call instead of one Python call each.

    ``expand`` (default): the interval's levels are those of
    :func:`expanded_z` for the ``n`` points resampled (for a cluster bootstrap, the clusters) instead
    of the normal quantile, in either method: the interval widens by ~20 % at 9 points, ~10 % at 17,
    ~5 % at 33, and misses the truth on either side less often at every size measured
    (``explorations/interval_coverage.py``, docs/verdicts.md).  ``expand=False``: the textbook levels
    (scipy's BCa interval to rounding).
    """
    from scipy import stats as st

    if method not in BOOTSTRAP_METHODS:
        raise ParameterError("method", f"one of {', '.join(BOOTSTRAP_METHODS)}", method)
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0):
        raise ParameterError("seed", "None or an integer >= 0", seed)
    samples = tuple(_values(f"samples[{i}]", a).reshape(np.shape(a)) for i, a in enumerate(samples))
    if len({a.size for a in samples}) > 1:
        raise ParameterError("samples", "equally long (they are resampled together)", [a.size for a in samples])
    nan3 = (math.nan, math.nan, math.nan)
    if samples[0].size < 3:
        return nan3

    def stat(*xs, axis=-1):
        with np.errstate(all="ignore"):
            return statistic(*xs, axis=axis) if vectorized else statistic(*xs)

    import warnings

    conf = level()
    rng = np.random.default_rng(BOOTSTRAP_SEED if seed is None else seed)
    with warnings.catch_warnings():  # degenerate resamples are handled below
        warnings.simplefilter("ignore")
        res = st.bootstrap(samples, stat, paired=True, vectorized=vectorized, n_resamples=n_resamples,
                           confidence_level=conf, method="percentile", rng=rng)
    dist = np.asarray(res.bootstrap_distribution, float)
    dist = dist[np.isfinite(dist)]
    if dist.size < n_resamples // 2:  # too many degenerate resamples: no honest interval
        return nan3
    se = float(dist.std(ddof=1))
    n = samples[0].size
    z = expanded_z(conf, n if expand else math.inf)
    if method == "percentile":
        from scipy.special import ndtr

        lo, hi = np.quantile(dist, [float(ndtr(-z)), float(ndtr(z))])
        return se, float(lo), float(hi)
    theta = float(stat(*samples))
    if not math.isfinite(theta):
        return nan3
    if np.ptp(dist) == 0:  # every resample gives one value: the interval is that value
        return se, float(dist[0]), float(dist[0])
    keep = ~np.eye(n, dtype=bool)  # row i: every point but the i-th
    if vectorized:
        jack = np.asarray(stat(*(s[None, :].repeat(n, 0)[keep].reshape(n, n - 1) for s in samples)), float)
    else:
        jack = np.array([stat(*(s[keep[i]] for s in samples)) for i in range(n)], float)
    levels = _bca_levels(dist, theta, jack[np.isfinite(jack)], z)
    if levels is None:
        return nan3
    lo, hi = np.quantile(dist, levels)
    return se, float(lo), float(hi)


def _bca_levels(dist: np.ndarray, theta: float, jack: np.ndarray, z: float) -> tuple[float, float] | None:
    """The BCa interval's two quantile levels of the (finite) bootstrap distribution ``dist``:
    ``Phi(z0 + (z0 + q) / (1 - a (z0 + q)))`` for ``q = -+z`` (``z``: the level's upper normal quantile,
    :func:`expanded_z`), with ``z0 = Phi^-1``
    of the share of resamples below ``theta`` (ties count half, as in scipy) and ``a = sum d^3 / (6
    (sum d^2)^1.5)``, ``d``: the jackknife values' mean minus each (``jack``: the statistic without one
    point each, finite ones).  ``a = 0`` where the jackknife values are all equal (the bias correction
    alone).  None where ``theta`` lies outside the distribution (``z0`` infinite)."""
    from scipy.special import ndtr, ndtri

    share = (np.count_nonzero(dist < theta) + np.count_nonzero(dist <= theta)) / (2 * dist.size)
    z0 = float(ndtri(share))
    if not math.isfinite(z0):
        return None
    d = jack.mean() - jack if jack.size else np.zeros(1)
    den = float(np.sum(d * d))
    a = float(np.sum(d ** 3)) / (6 * den ** 1.5) if den > 0 else 0.0

    def at(q: float) -> float:  # past the transform's pole (1 - a (z0 + q) <= 0) the level is the end's
        den_q = 1 - a * (z0 + q)
        return float(ndtr(z0 + (z0 + q) / den_q)) if den_q > 0 else float(q > 0)

    return at(-z), at(z)


@dataclass(frozen=True)
class LineFit:
    """``y = slope x + intercept`` with uncertainties; ``r2``: coefficient of determination."""

    slope: Estimate
    intercept: Estimate
    r2: Estimate
    n: int

    def to_dict(self) -> dict[str, Any]:
        return {"slope": self.slope.to_dict(), "intercept": self.intercept.to_dict(),
                "r2": self.r2.to_dict(), "n": self.n}


def _pearson_rows(a, b, axis=-1):
    """Pearson's r along ``axis`` (every resample at once); NaN where either has no spread."""
    a = np.moveaxis(np.asarray(a, float), axis, -1)
    b = np.moveaxis(np.asarray(b, float), axis, -1)
    ac = a - a.mean(axis=-1, keepdims=True)
    bc = b - b.mean(axis=-1, keepdims=True)
    with np.errstate(all="ignore"):
        r = np.clip((ac * bc).sum(axis=-1) / np.sqrt((ac * ac).sum(axis=-1) * (bc * bc).sum(axis=-1)), -1.0, 1.0)
    flat = (np.ptp(a, axis=-1) == 0) | (np.ptp(b, axis=-1) == 0)
    return np.where(flat, np.nan, r)


def line_fit(x, y, *, seed: int | None = None) -> LineFit:
    """Least squares of ``y`` on ``x`` (NaNs dropped): ``scipy.stats.linregress``.

    Slope and intercept: standard errors from linregress and Student-t 95 %
    intervals (``n - 2`` degrees of freedom); R^2: paired BCa bootstrap interval.
    NaN estimates with fewer than 2 points or no spread in ``x``.
    """
    from scipy import stats as st

    x, y = _clean(x, y)
    n = int(x.size)
    if n < 2 or np.ptp(x) == 0:
        return LineFit(Estimate(math.nan, n=n), Estimate(math.nan, n=n), Estimate(math.nan, n=n), n)
    r = st.linregress(x, y)
    dof = n - 2
    conf = level()
    q = float(st.t.ppf((1 + conf) / 2, dof)) if dof > 0 else math.nan
    se_s = float(r.stderr) if dof > 0 else math.nan
    se_i = float(r.intercept_stderr) if dof > 0 else math.nan
    slope = Estimate(float(r.slope), se_s, r.slope - q * se_s, r.slope + q * se_s, n, "linregress, t interval",
                     conf, n, dof)
    icpt = Estimate(float(r.intercept), se_i, r.intercept - q * se_i, r.intercept + q * se_i, n,
                    "linregress, t interval", conf, n, dof)

    def r2_of(a, b, axis=-1):
        return _pearson_rows(a, b, axis) ** 2

    r2v = float(r.rvalue ** 2) if np.ptp(y) > 0 else math.nan
    se, lo, hi = bootstrap(r2_of, x, y, seed=seed, vectorized=True)
    return LineFit(slope, icpt, Estimate(r2v, se, lo, hi, n, "bootstrap BCa", conf, n, n - 1), n)


def is_mirror_design(x) -> bool:
    """Whether the finite ``x`` are a mirror-symmetric design: every ``x != 0`` once at ``+|x|`` and once
    at ``-|x|`` (matched to 1e-9), any number of rows at ``x = 0``."""
    x = np.asarray(x, float).ravel()
    x = x[np.isfinite(x)]
    key = np.round(np.abs(x), 9)
    return all(np.sum(x[key == k] > 0) == 1 and np.sum(x[key == k] < 0) == 1 for k in np.unique(key[key > 0]))


def mirrored_line_fit(x, y, *, seed: int | None = None) -> LineFit:
    """Least squares of ``y`` on ``x`` over a mirror-symmetric design (:func:`is_mirror_design`; a study's
    runs at +dphi and -dphi, one design point seen mirrored, their residuals nearly opposite).
    :func:`line_fit`'s t interval counts the two rows as independent and is too narrow by about sqrt(2)
    there (docs/verdicts.md, "Staged runs"); here the pairs are the units.

    Slope: the half-differences ``d = (y(x) - y(-x)) / 2`` of the G complete pairs (the intercept
    cancels) regressed on ``x`` through the origin, Student's t on ``G - 1`` degrees of freedom; the
    value is the least-squares slope of the rows used.  Intercept: the mean of the half-sums
    ``(y(x) + y(-x)) / 2`` and of the rows at ``x = 0``, t on their count less one.  R^2: the least
    squares' over the rows used, BCa bootstrap resampling each pair together (:func:`bootstrap`).  Rows
    used: the complete pairs and the rows at ``x = 0``; a pair one of whose ``y`` is NaN (a run without a
    result) is left out, ``n`` counts the rest.  No interval for the slope with fewer than 2 pairs.
    ``ValueError`` when the finite ``x`` are not a mirror-symmetric design.
    """
    from scipy import stats as st

    x, y = _paired(x, y)
    y = y[np.isfinite(x)]
    x = x[np.isfinite(x)]
    if not is_mirror_design(x):
        raise ParameterError("x", "a mirror-symmetric design: every x != 0 once at +|x| and once at -|x|")
    key = np.round(np.abs(x), 9)
    xs, d, halves, labels = [], [], [], np.full(x.size, -1)
    at_zero = np.flatnonzero((key == 0) & np.isfinite(y))
    labels[at_zero] = np.arange(at_zero.size) + x.size  # each row at x = 0 is its own unit
    for k in np.unique(key[key > 0]):
        up, down = int(np.flatnonzero((key == k) & (x > 0))[0]), int(np.flatnonzero((key == k) & (x < 0))[0])
        if np.isfinite(y[up]) and np.isfinite(y[down]):
            xs.append(float(k))
            d.append((y[up] - y[down]) / 2)
            halves.append((y[up] + y[down]) / 2)
            labels[[up, down]] = len(xs) - 1
    units = halves + [float(v) for v in y[at_zero]]  # the intercept's: half-sums and rows at x = 0
    used = labels >= 0
    xu, yu, lab = x[used], y[used], labels[used]
    xs_, d_ = np.asarray(xs), np.asarray(d)
    g, n, conf = len(xs), int(used.sum()), level()
    method = "mirror pairs: fold, t interval"
    if g == 0:
        return LineFit(Estimate(math.nan, n=n), mean(units), Estimate(math.nan, n=n), n)
    sxx = float(xs_ @ xs_)
    b = float(xs_ @ d_) / sxx
    if g >= 2:
        r = d_ - b * xs_
        se = math.sqrt(float(r @ r) / (g - 1) / sxx)
        q = float(st.t.ppf((1 + conf) / 2, g - 1))
        slope = Estimate(b, se, b - q * se, b + q * se, n, method, conf, g, g - 1)
    else:
        slope = Estimate(b, n=n, method=method)
    return LineFit(slope, mean(units), _clustered_r2(xu, yu, lab, seed), n)


def joined_clusters(*labelings) -> np.ndarray:
    """One cluster label per row (0, 1, ...) joining every labeling given: two rows share a cluster
    when any labeling gives them the same label, directly or through other rows (the connected
    components of the rows linked by each labeling; ``scipy.sparse.csgraph``).  E.g. a run's
    neighbour pairs (one run) and the runs at +dphi and -dphi (one design point mirrored)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    labs = [np.asarray(lab).ravel() for lab in labelings]
    if not labs:
        raise ParameterError("labelings", "at least one labeling")
    n = labs[0].size
    if any(lab.size != n for lab in labs):
        raise ParameterError("labelings", f"one label per row ({n}) each", [lab.size for lab in labs])
    cols = []
    for lab in labs:  # each row linked to the first row of its label
        _, first, which = np.unique(lab, return_index=True, return_inverse=True)
        cols.append(first[which.ravel()])
    rows = np.tile(np.arange(n), len(labs))
    graph = coo_matrix((np.ones(rows.size), (rows, np.concatenate(cols))), shape=(n, n))
    return connected_components(graph, directed=False)[1]


CLUSTERED_SLOPE_METHOD = "least squares, cluster jackknife CR3, t on G - 1"


def clustered_line_fit(x, y, clusters, *, seed: int | None = None) -> LineFit:
    """Least squares of ``y`` on ``x`` where the rows of a cluster may share their errors (the neighbour
    pairs of one run of a group, the runs at +dphi and -dphi of a mirrored grid): rows with a NaN ``x``
    or ``y`` dropped, ``clusters`` one label per row.

    Slope and intercept: the least-squares values, with the cluster-robust CR3 standard error (the
    delete-one-cluster jackknife ``(G - 1) / G * sum_g (b_(g) - b)^2`` about the full fit ``b``, for
    ``G`` clusters) and Student's t on ``G - 1`` degrees of freedom (MacKinnon, Nielsen & Webb 2023,
    J. Econometrics 232, 272: on few clusters CR3 with t(G - 1) keeps its level where the usual CR1
    sandwich does not).  Measured here (docs/verdicts.md): at 95 % it covered 94-95 % on 4-12
    clusters of rows sharing a run effect (the rows' t: 58-81 %, CR1: 80-91 %), of rows whose errors
    cancel (the rows' t: 99 %), and of independent rows.  ``units`` the clusters and ``dof`` ``G - 1``,
    so :func:`runs_needed` extrapolates in clusters.  R^2: the rows' value, BCa bootstrap resampling
    each cluster together.  No interval with fewer than 3 clusters or where leaving a cluster out
    leaves no spread in ``x``.
    """
    from scipy import stats as st

    x, y = _paired(x, y)
    labels = np.asarray(clusters).ravel()
    if labels.size != x.size:
        raise ParameterError("clusters", f"one label per row ({x.size})", labels.size)
    ok = np.isfinite(x) & np.isfinite(y)
    x, y, labels = x[ok], y[ok], labels[ok]
    n = int(x.size)
    if n < 2 or np.ptp(x) == 0:
        return LineFit(Estimate(math.nan, n=n), Estimate(math.nan, n=n), Estimate(math.nan, n=n), n)
    _, which = np.unique(labels, return_inverse=True)
    g = int(which.max()) + 1

    def fit(keep: np.ndarray) -> np.ndarray:  # (intercept, slope) of the rows kept; NaN without spread
        xk, yk = x[keep], y[keep]
        if xk.size < 2 or np.ptp(xk) == 0:
            return np.full(2, np.nan)
        xm, ym = xk.mean(), yk.mean()
        b = float((xk - xm) @ (yk - ym) / ((xk - xm) @ (xk - xm)))
        return np.array([ym - b * xm, b])

    full = fit(np.ones(n, bool))
    conf = level()
    method = f"{CLUSTERED_SLOPE_METHOD}, {g} clusters"
    se = np.full(2, np.nan)
    if g >= 3:
        jack = np.array([fit(which != k) for k in range(g)])
        if np.isfinite(jack).all():
            se = np.sqrt((g - 1) / g * np.sum((jack - full) ** 2, axis=0))
    q = float(st.t.ppf((1 + conf) / 2, g - 1)) if g >= 3 else math.nan

    def est(k: int) -> Estimate:
        v = float(full[k])
        if not math.isfinite(se[k]):
            return Estimate(v, n=n, method=method)
        return Estimate(v, float(se[k]), v - q * se[k], v + q * se[k], n, method, conf, g, g - 1)

    return LineFit(est(1), est(0), _clustered_r2(x, y, which, seed, "clusters"), n)


def _clustered_r2(x: np.ndarray, y: np.ndarray, labels: np.ndarray, seed: int | None,
                  what: str = "mirror pairs") -> Estimate:
    """R^2 of ``y`` on ``x`` with a BCa bootstrap interval resampling the rows of a label together
    (per label: the count and the sums of x, y, x^2, y^2 and xy)."""
    n = int(x.size)
    if n < 3 or np.ptp(x) == 0 or np.ptp(y) == 0:
        return Estimate(math.nan, n=n)
    r2v = float(_pearson_rows(x, y) ** 2)
    _, which = np.unique(labels, return_inverse=True)
    k = int(which.max()) + 1
    sums = [np.bincount(which, w, minlength=k) for w in (None, x, y, x * x, y * y, x * y)]

    def r2_of(c, sx, sy, sxx, syy, sxy, axis=-1):
        m, sx, sy = np.sum(c, axis=axis), np.sum(sx, axis=axis), np.sum(sy, axis=axis)
        vx = m * np.sum(sxx, axis=axis) - sx * sx
        vy = m * np.sum(syy, axis=axis) - sy * sy
        cov = m * np.sum(sxy, axis=axis) - sx * sy
        return np.where((vx > 0) & (vy > 0), cov * cov / (vx * vy), np.nan)

    se, lo, hi = bootstrap(r2_of, *sums, seed=seed, vectorized=True)
    return Estimate(r2v, se, lo, hi, n, f"bootstrap BCa over {what}", level(), k, k - 1)


def _orderings_suffice(orderings: float, level_: float) -> bool:
    """Whether a rank statistic with ``orderings`` distinct orderings of its data can exclude no trend at
    ``level_``: the most extreme ordering comes by chance once in that many, so at least ``2 / (1 - level)``."""
    return orderings * (1.0 - level_) >= 2.0


def rank_correlation_points(level_: float | None = None) -> int:
    """The fewest points (without ties) for which :func:`rank_correlation` gives an interval at ``level_``
    (None: the current :func:`level`): the smallest ``n`` with ``n! (1 - level) >= 2``; 5 up to 98.3 %."""
    lv = level() if level_ is None else float(level_)
    n = 3
    while not _orderings_suffice(math.factorial(n), lv):
        n += 1
    return n


def rank_correlation(x, y, *, seed: int | None = None) -> Estimate:
    """Spearman's rho of ``y`` against ``x`` (ties get average ranks), with a paired percentile
    bootstrap 95 % interval; NaNs dropped; NaN with fewer than 3 points.

    No interval (the value and its bootstrap standard error only) while the distinct orderings of the
    data, ``n!`` over the factorials of the tie counts in ``x`` and in ``y``, are fewer than ``2 / (1 -
    level)``: with no trend the most extreme ordering comes by chance once in that many, so no data
    could exclude rho = 0 at the level (without ties: 5 points up to 98.3 %, 6 up to 99.7 %), whereas
    every resample of a monotone sample is monotone and the bootstrap's interval is [-1, -1] (three
    channel widths in a monotone order would otherwise be judged rho = -1 [-1, -1])."""
    from scipy import stats as st

    x, y = _clean(x, y)
    n = int(x.size)
    if n < 3 or np.ptp(x) == 0 or np.ptp(y) == 0:
        return Estimate(math.nan, n=n, method="spearmanr")

    def rho_rows(a, b, axis=-1):  # spearmanr of every resample: Pearson's r of the (tie-averaged) ranks
        return _pearson_rows(st.rankdata(a, axis=axis), st.rankdata(b, axis=axis), axis)

    # a rank statistic: BCa gains nothing on it (bivariate normal samples of 9-37 points, six rows: the
    # percentile interval misses at most 5.5 % a side, BCa 4.0 %, but BCa's misses sum to 22.9 points
    # against 17.4; explorations/interval_coverage.py --pairs)
    se, lo, hi = bootstrap(rho_rows, x, y, seed=seed, vectorized=True, method="percentile")
    rho = float(st.spearmanr(x, y).statistic)
    ties = [math.factorial(int(c)) for v in (x, y) for c in np.unique(v, return_counts=True)[1]]
    if not _orderings_suffice(math.factorial(n) / math.prod(ties), level()):
        return Estimate(rho, se, n=n, method="spearmanr; too few orderings for an interval at this level",
                        level=level())
    return Estimate(rho, se, lo, hi, n, "spearmanr, bootstrap percentile", level(), n, n - 1)


def _root_mean_square(values, centred: bool, seed: int | None, clusters=None) -> Estimate:
    """``sqrt(mean(c**2))`` of the finite ``values`` (``c``: the values, less their mean if ``centred``),
    with a bias-corrected and accelerated (BCa) bootstrap interval at the expanded levels (:func:`bootstrap`,
    :func:`expanded_z`; the levels of the design points resampled, so of the clusters where given).

    The percentile bootstrap of a root mean square undercovers on its upper side: its bound cannot
    exceed ``max |v|``, and the statistic's skew is not corrected.  Normal samples (seeded trials,
    ``explorations/interval_coverage.py``): the true RMS above the percentile interval in 7 % of
    samples of 49 points and 18 % of 9 (nominal 2.5 %); BCa corrects part of it, and more for heavy
    tails, and the expanded levels a little more (12 % at 9 with BCa, 9.5 % with both; docs/verdicts.md,
    "How an interval is formed").  A studentized bootstrap covers better on
    normal samples but is unstable on the studies' residuals (mirror pairs give equal squares, and
    near-zero spreads in resamples): tried and set aside.  ``stderr``: the bootstrap distribution's
    standard deviation.  An exact interval when every resample gives the value (all ``c**2`` equal);
    NaN with no values, no interval with fewer than 3 values or 3 clusters.

    ``clusters``: one label per value; the values of a label are resampled together (a cluster
    bootstrap), as one design point: a study's residuals at +dphi and -dphi are one pair seen mirrored,
    nearly equal in size, and resampled apart they would count each design point twice and narrow the
    interval.  The value is the same with or without clusters (every value counts once).
    """
    method = "bootstrap BCa" if clusters is None else "bootstrap BCa over clusters"
    v = _values("values", values)
    labels = np.arange(v.size) if clusters is None else np.asarray(clusters).ravel()
    if labels.shape != v.shape:
        raise ParameterError("clusters", f"one label per value ({v.size})", labels.size)
    keep = np.isfinite(v)
    v, labels = v[keep], labels[keep]
    if v.size == 0:
        return Estimate(math.nan, method=method)
    c = v - v.mean() if centred else v
    n, value = int(v.size), float(np.sqrt(np.mean(c * c)))
    _, which = np.unique(labels, return_inverse=True)
    k = int(which.max()) + 1
    if n < 3 or k < 3:
        return Estimate(value, n=n, method=method)
    if np.ptp(c * c) == 0:
        return Estimate(value, 0.0, value, value, n, method, level(), k, k - 1)
    # per cluster: the count, the sum and the sum of squares of c (c centred on the whole sample's mean:
    # a resample's variance is then a difference of small sums, with no cancellation)
    count, total, squares = (np.bincount(which, w, minlength=k) for w in (None, c, c * c))

    def f(cnt, tot, sq, axis=-1):
        m = np.sum(cnt, axis=axis)
        ms = np.sum(sq, axis=axis) / m - (np.sum(tot, axis=axis) / m) ** 2 * centred
        return np.sqrt(np.maximum(ms, 0.0))

    se, lo, hi = bootstrap(f, count, total, squares, seed=seed, vectorized=True)
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return Estimate(value, n=n, method=method)
    return Estimate(value, se, lo, hi, n, method, level(), k, k - 1)


def rms(values, *, seed: int | None = None, clusters=None) -> Estimate:
    """Root mean square of the finite ``values``, with a BCa bootstrap 95 % interval
    (:func:`_root_mean_square`; ``clusters``: labels of values resampled together)."""
    return _root_mean_square(values, False, seed, clusters)


def std(values, *, seed: int | None = None, clusters=None) -> Estimate:
    """Standard deviation (ddof = 0) of the finite ``values``, with a BCa bootstrap 95 % interval
    (:func:`_root_mean_square` of the centred values; ``clusters``: labels of values resampled together)."""
    return _root_mean_square(values, True, seed, clusters)


def mean(values) -> Estimate:
    """Mean of the finite ``values`` with its standard error and a t 95 % interval."""
    from scipy import stats as st

    (v,) = _clean(values, names=("values",))
    n = int(v.size)
    if n == 0:
        return Estimate(math.nan, method="t interval")
    m = float(v.mean())
    if n < 2:
        return Estimate(m, n=n, method="t interval")
    se = float(v.std(ddof=1) / math.sqrt(n))
    conf = level()
    q = float(st.t.ppf((1 + conf) / 2, n - 1))
    return Estimate(m, se, m - q * se, m + q * se, n, "t interval", conf, n, n - 1)


DOMAINS: tuple[tuple[str, float, float, str], ...] = (
    (r"(^|_)r2($|_)", -math.inf, 1.0, "an R^2"),
    (r"spearman|kendall|pearson|correlation", -1.0, 1.0, "a correlation"),
    (r"(^|_)(rms|std)($|_)", 0.0, math.inf, "a root mean square or a spread"),
    (r"rho_tilde|density", 0.0, math.inf, "a density"),
    (r"width", 0.0, math.inf, "a width"),
    (r"fraction", 0.0, 1.0, "a fraction"),
    (r"^n_|(^|_)count($|_)|^runs_needed$", 0.0, math.inf, "a count"),
)
"""The physical domain of a summary's quantity by its key's name: ``(pattern, low, high, what)``, the
first whose regular expression is found in the key wins (``"spearman_k_vs_d"`` is a correlation,
``"threshold_rho_tilde"`` a density, ``"rms_interval_width"`` a root mean square).  A key no pattern
names has no domain; the items of a list, and of a dict keyed by numbers (``{"3": ..., "5": ...}``),
take their key's."""


def domain_of(key: str) -> tuple[float, float, str] | None:
    """``(low, high, what)``: the physical domain of the quantity a summary key names (:data:`DOMAINS`),
    None where no pattern names it."""
    import re

    for pattern, lo, hi, what in DOMAINS:
        if re.search(pattern, str(key)):
            return lo, hi, what
    return None


def _is_label(key: Any) -> bool:
    """A dict key that labels an item (a number: an N, a phi_max) rather than naming a quantity."""
    try:
        float(key)
    except (TypeError, ValueError):
        return False
    return True


def _finite_number(v: Any) -> bool:
    return (isinstance(v, int | float | np.integer | np.floating) and not isinstance(v, bool | np.bool_)
            and math.isfinite(float(v)))


def domain_violations(obj: Any, key: str = "", _domain: tuple[float, float, str] | None = None,
                      _path: str = "") -> list[str]:
    """Every number in ``obj`` (a study's summary, a claim's value: nested dicts, lists, arrays and
    :meth:`Estimate.to_dict` dicts) that lies outside the physical domain its key names
    (:func:`domain_of`), one line each naming where it is, the number or interval, and the domain.  An
    estimate's value and both ends of its interval are checked; NaN and missing ends (None) are not
    numbers to check.  ``key``: the name of ``obj`` itself (its domain, where it is a number or an
    estimate).  Empty when every number is inside its domain."""
    dom = domain_of(key) if key and not _is_label(key) else None
    dom = dom or _domain
    path = _path or str(key)
    if isinstance(obj, Estimate):
        obj = obj.to_dict()
    if isinstance(obj, np.ndarray):
        obj = obj.tolist()
    out: list[str] = []
    if isinstance(obj, dict) and "value" in obj and "ci95" in obj:  # an Estimate.to_dict
        if dom is None:
            return out
        lo, hi, what = dom
        ci = [v for v in (obj.get("ci95") or []) if _finite_number(v)]
        nums = [obj["value"]] if _finite_number(obj.get("value")) else []
        bad = [float(v) for v in nums + ci if not lo <= float(v) <= hi]
        if bad:
            out.append(f"{path}: {what} {_g(obj['value']) if nums else 'n/a'} "
                       f"[{', '.join('n/a' if v is None else _g(v) for v in (obj.get('ci95') or [None, None]))}]"
                       f" outside its domain [{_g(lo)}, {_g(hi)}]")
        return out
    if isinstance(obj, dict):
        for k, v in obj.items():
            inherit = dom if _is_label(k) else None
            out += domain_violations(v, str(k), inherit, f"{path}.{k}" if path else str(k))
        return out
    if isinstance(obj, list | tuple):
        for i, v in enumerate(obj):
            out += domain_violations(v, "", dom, f"{path}[{i}]")
        return out
    if dom is not None and _finite_number(obj) and not dom[0] <= float(obj) <= dom[1]:
        out.append(f"{path}: {dom[2]} {_g(float(obj))} outside its domain [{_g(dom[0])}, {_g(dom[1])}]")
    return out


def check_domains(obj: Any, where: str) -> None:
    """Raise :class:`~undulate.errors.UndulateError` naming ``where`` and every number of ``obj``
    outside its physical domain (:func:`domain_violations`); a reported interval outside its
    quantity's domain comes from a method that does not fit the quantity, and is refused, never
    clipped."""
    bad = domain_violations(obj)
    if bad:
        from .errors import UndulateError

        raise UndulateError(f"{where}: {len(bad)} number(s) outside their physical domain: " + "; ".join(bad[:10])
                            + (f"; and {len(bad) - 10} more" if len(bad) > 10 else ""))


def estimates(values: Sequence[Estimate]) -> list[dict[str, Any]]:
    """``[e.to_dict() for e in values]``."""
    return [e.to_dict() for e in values]
