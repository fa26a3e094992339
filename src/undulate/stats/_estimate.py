"""A fitted number with its interval (:class:`Estimate`) and a criterion's three-valued check of it (:class:`Check`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any


from ._levels import CONFIDENCE, plan_level


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
    normal's for ``dof`` NaN (or infinite); NaN for ``dof <= 0``.  Through ``scipy.special``'s ``ndtri``
    and ``stdtrit``, the functions ``scipy.stats.norm.ppf`` and ``t.ppf`` evaluate (bitwise their values,
    at ~1/60 of the cost: :func:`runs_needed` calls this inside a root search)."""
    from scipy import special

    p = (1 + conf) / 2
    if not math.isfinite(dof):
        return float(special.ndtri(p))
    return float(special.stdtrit(dof, p)) if dof > 0 else math.nan


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
