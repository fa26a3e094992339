"""The sensitivity study's design: its constants, its plan (quick and full) and its typed case ids.

Read by the study (:mod:`undulate.studies.sensitivity`) and by its explanations
(:mod:`undulate.studies._explanations`), so that both name a case the same way.
A case is one set of runs judged by one claim's criterion; its :class:`CaseId`
is the :class:`CaseSet` it belongs to and the values of the factors that
define it, e.g. ``CaseId.of(CaseSet.XI32, n_links=8, duration_s=30.0)``.  The
display labels (``factor``, ``level``) are the table's and the figure's only.
:func:`planned_cases` lists, without running anything, every case id the
study's dataset holds for a plan; the dataset checks that it made exactly
those, and an explanation may name no other (:class:`UnknownCaseError`).
"""

from __future__ import annotations

import dataclasses
import enum
import functools
from dataclasses import dataclass

from ..errors import UndulateError
from ..params import SwimmerGeometry
from . import _analysis as analysis
from ._criteria import PAIR_CHANNEL_M
from ._gaits import BETA_DEG  # noqa: F401 - the 3-link joint amplitude, re-exported

__all__ = ["FACTORS", "FACTOR_GROUPS", "SKIPPABLE_GROUPS", "CaseId", "CaseSet", "Plan", "UnknownCaseError", "known_cases", "pair_cases", "plan",
           "planned_cases", "spaced_channel_m", "xi32_durations"]

PAPER_RANGE_HIGH = 1.2
LONG_S = 60.0
"""Length of the default xi = 1 runs (run whole, cut short for 20 and 30 s) and the longest xi = 3/2
runs at N > 3 (stopped once steady, cut at 30 s), s."""
DEFAULT_S = 30.0
CONFINEMENT_S = 40.0
DEFAULT_BODY_M = SwimmerGeometry().width_m
PER_SWIMMER, WHOLE_WIDTH = "per-swimmer", "whole-width"
D_READINGS = (PER_SWIMMER, WHOLE_WIDTH)
"""The readings of the paper's confinement ``d`` in the confinement cases: the wall distance per swimmer
(the default, :func:`undulate.theory.channel_width_m`: a pair's channel is ``W = 2 d``, the reading the
measured thresholds support, docs/confinement_d.md) and the whole channel width (``W = d``), kept as one
sensitivity row."""
D_READING_SCALE = {PER_SWIMMER: 1.0, WHOLE_WIDTH: 0.5}
"""Per reading, the per-swimmer ``d/2A`` of the channel that the reading calls ``d/2A = 1`` (a pair)."""
IMPULSE_DRAGS_N_S_PER_M = (1.0, 4.0, 8.0, 16.0)
"""The viscous ground's linear drag per link for the impulse runs besides the default 2 N s/m: the drag sets
how fast contact pushes the pair apart along x (overdamped: speed = force / drag), and so how much of the
two-period window the pair spends in contact before it escapes toward compatibility."""
IMPULSE_DRAG_DEFAULT = 2.0
FLUID_DENSITIES = (1000.0, 250.0)
"""Swimming ground: water (the default, Ground.swimming) and a quarter of it (weaker anisotropic drag)."""
SWIM_DRAG_N_S_PER_M = 0.5
"""A stronger linear drag per link for the swimming ground (default 0.1 N s/m; the viscous ground's is 2):
the damping of sliding, the other half of the swimming model."""
SWIM_MIN_SPEED_M_S = 1e-3
"""Pairs must still swim (mean speed over the dphi) for the drag level to count as a swimming model."""

# (factor, level label, group_point overrides) for xi = 1; the default is run at LONG_S
MODEL_LEVELS = (
    ("servo stiffness", "kp 5 N m/rad (default 10)", {"kp_Nm_per_rad": 5.0}),
    ("torque limit", "0.75 N m (default 1.5)", {"torque_limit_Nm": 0.75}),
    ("slew limit", "3 rad/s (default 6)", {"max_speed_rad_s": 3.0}),
    ("contact softness", "time constant 8 ms (default 2 dt = 4 ms)", {"contact_timeconst_s": 0.008}),
    ("drag", "1 N s/m per link (default 2)", {"drag_N_s_per_m": 1.0}),
    ("drag", "4 N s/m per link (default 2)", {"drag_N_s_per_m": 4.0}),
)
MODEL_DEFAULTS = {"kp_Nm_per_rad": 10.0, "torque_limit_Nm": 1.5, "max_speed_rad_s": 6.0,
                  "contact_timeconst_s": 0.0, "drag_N_s_per_m": 2.0}
"""The defaults of the MODEL_LEVELS keys (0 s contact time constant: two time steps); a test checks
them against the parameter types."""
DURATIONS_S = (20.0, 30.0, 60.0)
PAIR_SPACING_M = 0.032
"""Median steady lateral spacing of the reference pairs' centre lines in d = 0.13 m, m (measured by the
groups study, quick and full mode: 32.0 mm): each swimmer beyond two adds this much channel in the
spaced-group runs."""
WINDOWS = (1, 3, 5)
LEFT_OUT = "left out"
"""The level of the ``dphi_pi`` factor: the dphi = +-pi points left out (default: nearest branch)."""


# ------------------------------------------------------------------ case ids
class CaseSet(str, enum.Enum):
    """The sets of cases, each judged by one criterion (the values are the dataset's ``claim`` coordinate)."""

    XI1 = "xi1"
    """xi = 1 pairs, the pairs criterion: model levels, run duration, steady window, dphi = +-pi."""
    XI32 = "xi32"
    """xi = 3/2 pairs, the pairs criterion: links per body and run duration."""
    LINKS = "links"
    """Equal-A pairs per N, the links criterion on the line with lambda = L."""
    LINKS_X = "links-x"
    """The same runs, the line drawn with lambda_x (the bodies' wavelength along the channel)."""
    LINKS_GUIDED = "links-guided"
    """Equal-A pairs with the yaw recoil removed (heading guide), lambda = L."""
    LINKS_GUIDED_X = "links-guided-x"
    """The same runs, lambda = lambda_x."""
    SWIM = "swim"
    """Swimming-ground pairs, the pairs criterion: fluid density, linear drag."""
    GROUPS = "groups"
    """Groups (and their reference pairs), the groups criterion: size and channel width."""
    CONFINEMENT = "confinement"
    """dphi = 0 pairs over d/2A, the confinement criterion: the reading of d (per swimmer; whole width)."""
    IMPULSE = "impulse"
    """The two-period contact impulse over |dphi|, the potential criterion: the ground's linear drag."""


FACTOR_GROUPS: dict[CaseSet, str] = {
    CaseSet.XI32: "xi32", CaseSet.LINKS: "links", CaseSet.LINKS_X: "links", CaseSet.LINKS_GUIDED: "links",
    CaseSet.LINKS_GUIDED_X: "links", CaseSet.CONFINEMENT: "confinement", CaseSet.GROUPS: "groups",
    CaseSet.SWIM: "swimming", CaseSet.IMPULSE: "impulse"}
"""The factor group (a part of the plan: one ``_data_*`` step of :mod:`.sensitivity`) that makes the
cases of each case set: ``xi32``, ``links`` (the equal-A and the guided runs), ``confinement``, ``groups``,
``swimming``, ``impulse``.  An explanation reads the groups of its cases (its ``reads``); the xi = 1 cases
feed no explanation, only the table: they always run."""

SKIPPABLE_GROUPS: tuple[str, ...] = tuple(dict.fromkeys(FACTOR_GROUPS.values()))
"""The factor groups that run only for a needed explanation, in the order the dataset makes them."""


Level = int | float | str

FACTORS: dict[str, type] = {
    "kp_Nm_per_rad": float, "torque_limit_Nm": float, "max_speed_rad_s": float, "contact_timeconst_s": float,
    "drag_N_s_per_m": float, "duration_s": float, "steady_window_periods": int, "dphi_pi": str, "n_links": int,
    "fluid_density_kg_m3": float, "swim_drag_N_s_per_m": float, "n_swimmers": int, "channel_width_m": float,
    "body_width_m": float, "d_reading": str,
}
"""The factors a case id may name, and the type of their levels (SI units as the names say)."""


class UnknownCaseError(UndulateError, KeyError):
    """A case id that is malformed, not made by the sensitivity study, or not declared by the explanation
    that asks for it."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


@dataclass(frozen=True)
class CaseId:
    """One case of the sensitivity study: its :class:`CaseSet` and the levels of the factors that
    define it (names from :data:`FACTORS`, values converted to their type, sorted by name).

    ``str(case_id)`` is its text form (the dataset's ``case_id`` coordinate, the summary's
    ``case_id`` fields), e.g. ``xi32[duration_s=30.0, n_links=8]``; :meth:`parse` reads it back."""

    case_set: CaseSet
    levels: tuple[tuple[str, Level], ...]

    def __post_init__(self):
        try:
            case_set = CaseSet(self.case_set)
        except ValueError:
            raise UnknownCaseError(f"unknown case set {self.case_set!r} (one of {[s.value for s in CaseSet]})") from None
        levels = {}
        for name, value in self.levels:
            if name not in FACTORS:
                raise UnknownCaseError(f"unknown factor {name!r} in a {case_set.value} case id (one of {list(FACTORS)})")
            if name in levels:
                raise UnknownCaseError(f"factor {name!r} given twice in a {case_set.value} case id")
            value = FACTORS[name](value)
            if isinstance(value, str) and any(ch in value for ch in ",=[]"):
                raise UnknownCaseError(f"level {value!r} of {name!r} holds one of ',=[]'")
            levels[name] = value
        if not levels:
            raise UnknownCaseError(f"a {case_set.value} case id names no factor")
        object.__setattr__(self, "case_set", case_set)
        object.__setattr__(self, "levels", tuple(sorted(levels.items())))

    @classmethod
    def of(cls, case_set: CaseSet | str, **levels: Level) -> CaseId:
        """``CaseId.of(CaseSet.SWIM, fluid_density_kg_m3=250.0)``."""
        return cls(case_set, tuple(levels.items()))

    def __getitem__(self, factor: str) -> Level:
        return dict(self.levels)[factor]

    def __str__(self) -> str:
        return f"{self.case_set.value}[" + ", ".join(f"{k}={v!r}" if not isinstance(v, str) else f"{k}={v}"
                                                     for k, v in self.levels) + "]"

    @classmethod
    def parse(cls, text: str) -> CaseId:
        """The case id whose :func:`str` is ``text``."""
        text = str(text)
        head, sep, rest = text.partition("[")
        if not sep or not rest.endswith("]"):
            raise UnknownCaseError(f"not a case id: {text!r}")
        pairs = [item.partition("=") for item in rest[:-1].split(", ")]
        if any(not eq for _, eq, _ in pairs):
            raise UnknownCaseError(f"not a case id: {text!r}")
        return cls(head, tuple((k, v) for k, eq, v in pairs))


# ------------------------------------------------------------------ plan
def _impulse_grid(quick: bool) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """The potential study's impulse grid (:func:`._analysis.impulse_design`) as ``(dphi, phi0)`` tuples."""
    return tuple(tuple(float(v) for v in a) for a in analysis.impulse_design(quick))


_IMPULSE_QUICK = _impulse_grid(True)


@dataclass(frozen=True)
class Plan:
    dphi_rad: tuple[float, ...]
    xi32_links: tuple[int, ...] = (3, 8)
    links: tuple[int, ...] = (3, 5, 7, 9)
    confinement_starts: tuple[float, ...] = (-0.15, 0.0, 0.15)
    confinement_d_over_2A: tuple[float, ...] = (0.9, 1.2)
    group_dphi_rad: tuple[float, ...] = tuple(float(p) for p in analysis.group_phases(True))
    group_draws: int = analysis.GROUP_DRAWS[True]
    impulse_dphi_rad: tuple[float, ...] = _IMPULSE_QUICK[0]
    impulse_phi0_rad: tuple[float, ...] = _IMPULSE_QUICK[1]
    xi1_dphi_rad: tuple[float, ...] | None = None
    """The pair phases of the xi = 1 cases, which feed the table only (no explanation), a subset of
    ``dphi_rad``; None: all of ``dphi_rad``."""

    @property
    def xi1_phases(self) -> tuple[float, ...]:
        """The xi = 1 cases' pair phases (:attr:`xi1_dphi_rad`, or all of ``dphi_rad``)."""
        return self.dphi_rad if self.xi1_dphi_rad is None else self.xi1_dphi_rad


def spaced_channel_m(n_swimmers: int) -> float:
    """Channel width (m) that gives ``n_swimmers`` neighbours the reference pairs' lateral spacing:
    ``0.13 m + (n - 2)`` :data:`PAIR_SPACING_M`."""
    return round(PAIR_CHANNEL_M + (int(n_swimmers) - 2) * PAIR_SPACING_M, 6)


def thinned_plan(p: Plan, k: int, k_dphi: int | None = None, k_xi1: int | None = None) -> Plan:
    """``p`` on every ``k``-th value of its groups' and impulse grids, ``k_dphi``-th (default ``k``)
    of its pair phases and ``k_xi1``-th (default ``k_dphi``) of its xi = 1 cases' phases, with ``1/k``
    of its random draws of four: a look of the plan (its values are ``p``'s, bitwise, so the runs are
    the shared ones)."""
    k_dphi = k if k_dphi is None else k_dphi
    k_xi1 = k_dphi if k_xi1 is None else k_xi1
    return dataclasses.replace(p, dphi_rad=p.dphi_rad[::k_dphi], group_dphi_rad=p.group_dphi_rad[::k],
                               group_draws=max(1, p.group_draws // k), impulse_dphi_rad=p.impulse_dphi_rad[::k],
                               impulse_phi0_rad=p.impulse_phi0_rad[::k],
                               xi1_dphi_rad=None if p.xi1_dphi_rad is None else p.xi1_dphi_rad[::k_xi1])


FULL_PAIR_REFINE = 2
"""Full mode's cap of pair phases: the 17 (step pi/8) with every step cut in two, 33 (step pi/16),
reached at the third look (:func:`undulate.studies.sensitivity.stages`).  Sized by the
swimming explanation's check (the pairs criterion at 0.5 N s/m): at the third look, on the second's 17 dphi
(9 distinct |dphi|, +dphi and -dphi resampled together; 97 %), its RMS residual 0.060 [0.029, 0.104] lambda
straddled 0.1 and needed ~1.2x its runs; the next nested grid is 33.  The xi = 1 cases feed the table
only and stay on the 17."""


def plan(quick: bool) -> Plan:
    """Quick: the paper's nine dphi (the xi = 1 cases, which feed the table only, every second: 5),
    xi = 3/2 at N = 3 and 8, the link-number sets at the ends of the range, N = 3 and 9 (the
    explanation's contrast is their fall from 3 to 9; at full's first look it is 8.6-12.6 times the
    two-change set's, so the ends decide it), 3 confinement starts, the groups' and potential's quick
    grids; its first look every second value of them (:func:`~.sensitivity.stages`); full: 33 dphi
    (step pi/16; the xi = 1 cases, which feed the table only, on every second: 17, step pi/8:
    :data:`FULL_PAIR_REFINE`), xi = 3/2 at N = 3, 4, 6, 8, the link-number sets at N = 3, 5, 7, 9,
    5 starts.  The groups cases take the groups study's design (:func:`._analysis.group_phases`,
    :data:`._analysis.GROUP_DRAWS`: quick the nine dphi and 8 draws of four swimmers, thinned to 5 and 4;
    full 33 dphi and 40 draws), so that only the channel differs."""
    if quick:
        nine = tuple(float(p) for p in analysis.paper_phases())
        return Plan(nine, links=(3, 9), xi1_dphi_rad=nine[::2])
    impulse_dphi, impulse_phi0 = _impulse_grid(False)
    dphi = tuple(float(p) for p in analysis.refined(analysis.phase_grid(17), FULL_PAIR_REFINE))
    return Plan(dphi, xi1_dphi_rad=dphi[::FULL_PAIR_REFINE], xi32_links=(3, 4, 6, 8),
                confinement_starts=(-0.3, -0.15, 0.0, 0.15, 0.3),
                group_dphi_rad=tuple(float(p) for p in analysis.group_phases(False)),
                group_draws=analysis.GROUP_DRAWS[False],
                impulse_dphi_rad=impulse_dphi, impulse_phi0_rad=impulse_phi0)


def xi32_durations(n_links: int) -> tuple[float, ...]:
    """The run lengths judged for xi = 3/2 pairs of ``n_links`` links: 30 s; N > 3 also 60 s (one run cut)."""
    return (DEFAULT_S, LONG_S) if n_links > 3 else (DEFAULT_S,)


# ------------------------------------------------------------------ the cases of a plan
def pair_cases(p: Plan) -> tuple[CaseId, ...]:
    """The ids of the dataset's ``case`` dimension, in its order (the pair cases judged against the line)."""
    ids = [CaseId.of(CaseSet.XI1, **over) for _, _, over in MODEL_LEVELS]
    ids += [CaseId.of(CaseSet.XI1, duration_s=D) for D in DURATIONS_S]
    ids += [CaseId.of(CaseSet.XI1, steady_window_periods=w) for w in WINDOWS if w != analysis.STEADY_WINDOW]
    ids.append(CaseId.of(CaseSet.XI1, dphi_pi=LEFT_OUT))
    ids += [CaseId.of(CaseSet.XI32, n_links=n, duration_s=D) for n in p.xi32_links for D in xi32_durations(n)]
    for free, along_x in ((CaseSet.LINKS, CaseSet.LINKS_X), (CaseSet.LINKS_GUIDED, CaseSet.LINKS_GUIDED_X)):
        ids += [CaseId.of(s, n_links=n) for n in p.links for s in (free, along_x)]
    ids += [CaseId.of(CaseSet.SWIM, fluid_density_kg_m3=rho) for rho in FLUID_DENSITIES]
    ids.append(CaseId.of(CaseSet.SWIM, swim_drag_N_s_per_m=SWIM_DRAG_N_S_PER_M))
    return tuple(ids)


def group_case(n_swimmers: int, channel_width_m: float) -> CaseId:
    return CaseId.of(CaseSet.GROUPS, n_swimmers=n_swimmers, channel_width_m=channel_width_m)


def group_cases() -> tuple[tuple[int, float, bool], ...]:
    """``(swimmers, channel width m, the groups study's own channel)`` of the group cases, in order: the
    reference pairs in 0.13 m, then three and four swimmers in the groups study's and the spaced channel."""
    out = [(2, PAIR_CHANNEL_M, True)]
    for n in (3, 4):
        out += [(n, analysis.GROUP_CHANNEL_M[n], True), (n, spaced_channel_m(n), False)]
    return tuple(out)


def confinement_case(d_reading: str = PER_SWIMMER, body_width_m: float = DEFAULT_BODY_M) -> CaseId:
    """The confinement case of one reading of ``d`` (:data:`D_READINGS`) at link width ``body_width_m``."""
    return CaseId.of(CaseSet.CONFINEMENT, body_width_m=body_width_m, d_reading=d_reading)


def impulse_case(drag_N_s_per_m: float) -> CaseId:
    return CaseId.of(CaseSet.IMPULSE, drag_N_s_per_m=drag_N_s_per_m)


def impulse_drags() -> tuple[float, ...]:
    """Every linear drag of the impulse runs, ascending (the default among them)."""
    return tuple(sorted((IMPULSE_DRAG_DEFAULT, *IMPULSE_DRAGS_N_S_PER_M)))


def planned_cases(p: Plan) -> tuple[CaseId, ...]:
    """Every case id the sensitivity dataset of plan ``p`` holds (no run needed): the pair cases
    (:func:`pair_cases`), the group cases, the two readings of d and the impulse drags."""
    return (pair_cases(p) + tuple(group_case(n, w) for n, w, _ in group_cases())
            + tuple(confinement_case(r) for r in D_READINGS)
            + tuple(impulse_case(c) for c in impulse_drags()))


@functools.lru_cache(maxsize=1)
def known_cases() -> frozenset[CaseId]:
    """The case ids of the quick and the full plan."""
    return frozenset(planned_cases(plan(True))) | frozenset(planned_cases(plan(False)))
