r"""Study ``potential`` (paper Fig. 10): contact force against detuning, and cohesion stiffness.

(a) Pairs in the 0.13 m channel start at ``dx0 = 0`` with ``dphi`` across
``[-pi, pi]``; the swimmer-swimmer contact impulse over the first two
periods (``observables.contact_impulse(ds, 0, 2T)``) is fitted by
``a |dphi| + b`` (least squares; R^2 reported).  The start from straight
bodies makes the first two periods depend on the common phase too (a
``dphi`` run and its mirror image ``-dphi`` differ by a common phase
shift), so each ``dphi`` is run at several phases ``phi0`` of the lower
swimmer and the impulse is averaged over them.

(b-d) A ``dphi = 0`` pair settles for :data:`SETTLE_S` at compatibility
(``dx = 0``), then equal and opposite longitudinal forces ``-dF`` (lower
swimmer, toward -x) and ``+dF`` (upper, toward +x) switch on
(``Scene.forces_N``, ``force_onset_s``) and stay on.  ``dx`` is the mean of
the last 3 periods minus the mean of the period before the onset.  A pair
*broke apart* when ``dx / lambda > BREAK`` or when its period means still
drift (range over the last 3 periods > ``DRIFT`` lambda); those points are
left out of the fit :func:`fit_stiffness`, ``dF = k (dx - dx0)``.  Done for
every ``d / 2A`` and ``beta`` in {30, 45, 60} degrees, with ``A`` measured
per beta on a free swimmer.

Design of the force runs: which channels, which forces
-----------------------------------------------------
``d`` is the wall distance per swimmer (a pair's channel is ``W = 2 d``, docs/confinement_d.md), and
what this part measures, the restoring force of a compatible pair, exists only where the settled pair
touches.  The design follows the cohesion scan of a settled ``beta = 45`` deg pair under these runs'
own rules (``explorations/d_thresholds.py --cohesion``, ``explorations/results/d_cohesion.json``,
forces 5 mN to 0.3 N, d/2A 0.5 to 1.2):

* below d/2A = 0.48 (W = 101 mm) an in-phase pair's gait is obstructed: the grid starts at 0.5, just
  above it (the paper's "d/2A < 0.5 ... obstructed"), and takes in the lower part of the paper's range
  [0.6, 1.2];
* at 0.5 and 0.6 the pair holds every force of the scan (dx/lambda up to 0.04 and 0.18 at 0.3 N);
  at 0.7 it holds 5 and 20 mN and breaks at 0.1 N; at 0.8 it holds 20 mN (0.22 lambda) and breaks at
  0.1 N; from 0.9 it does not touch, and every force slides it away (the same 0.099 lambda after 5 mN
  from 0.8 to 1.2: the free slide across the neutral band).  Cohesion ends between 0.8 and 0.9, and
  where it exists the holding force falls from above 0.3 N to between 20 and 100 mN.

So the d/2A grid runs from 0.5 to where cohesion ends (:data:`D_OVER_2A_FULL`: 0.5 to 0.9 in steps of
0.025, the last widths measuring its end; :data:`D_OVER_2A_QUICK`: 0.5, 0.6, 0.7), the same d/2A
for every beta (each normalised by its own free swimmer's ``A``, so each beta's channels are its own).
The forces are one geometric ladder, doubling from a few mN (:data:`FORCES_N_FULL`: 5 to 80 mN;
:data:`FORCES_N_QUICK`: 5 to 40 mN, the rungs below the narrowest holding force of the scan): its low
rungs lie in every touching channel's linear regime, its high rungs find where the wider channels let
go.  A stiffness is fitted from the rungs that held; the holding force (largest rung held, the next rung
broken) is reported per (beta, d/2A) (``summary["per_beta"][beta]["cohesion"]``).  A (beta, d/2A) at
which no rung held has no cohesion: the summary reports ``k = 0`` there, as measured, and no fit (the
claims read the fits; such widths are listed beside them, not fed to them).

Compatibility model of ``dx0`` (:func:`model_dx0_m`)
----------------------------------------------------
Full compatibility region (paper Eq. fullcompatibility), at ``dphi = 0``:
two sinusoids of amplitude ``A`` at lateral offset ``dy`` never touch for

    |2 pi dx / lambda| <= 2 arcsin(min(dy / 2A, 1)),

a band of neutral offsets of half-width ``(lambda / pi) arcsin(dy / 2A)``
around ``dx = 0``.  The settled pair sits in the middle of that band; the
pulling forces slide it freely to the band's edge, so the model's offset
is that half-width.  The lateral room ``dy`` is what the walls leave:

* sinusoids (zero thickness): each centre line keeps ``A`` from its wall,
  so ``dy <= W - 2A`` in a channel ``W`` wide; with the paper's ``d`` the
  wall distance per swimmer (``W = 2 d`` for a pair,
  :func:`undulate.theory.channel_width_m`, docs/confinement_d.md) that is
  ``dy / 2A = 2 d / 2A - 1``: ``dx0 = (lambda / pi) arcsin(clip(2 d / 2A - 1, 0, 1))``;
* bodies of width ``w``: each body edge keeps ``A + w / 2`` from its wall
  and the two bodies need ``w`` between centre lines, so the clearance
  between the curves is ``W - 2A - 2w`` (:func:`lateral_clearance_m`).

Both are drawn; the measured offset is expected between or below them
(three-link bodies do not fill the sinusoid's envelope).

Release runs (paper Fig. 10b: "for small dF this position was sustained until the force was removed")
----------------------------------------------------------------------------------------------------
The force runs keep the force on to their end, so they cannot show what happens when it is removed.
A few more ``dphi = 0`` pairs (:data:`RELEASE_FORCE_N`, the ladder's smallest rung, which both modes
apply, at every ``d / 2A`` of the quick grid: one beta in quick, every beta in full) settle for :data:`SETTLE_S`, feel
``+-dF`` for :data:`RELEASE_HOLD_S` and run :data:`RELEASE_AFTER_S` more without it
(``Scene.force_offset_s``).  From their period means of ``dx / lambda`` (:func:`release_response`):
the separation ``D`` (hold window minus the periods before the onset), the drift over the hold window
(a line through its period means, over 3 periods) and the way back after the force is removed (hold
window minus the last periods).  :func:`_sustained` judges them.

Impulse across amplitudes (paper Sec. III.G: "Increasing amplitude caused larger contact force interactions")
-------------------------------------------------------------------------------------------------------------
The impulse runs of (a) are at the default beta (:data:`IMPULSE_BETA_DEG`) and are shared with other
studies, so they stay as they are.  The same runs (function, 0.13 m channel, two periods, ``dx0 = 0``) at
the plan's other betas are their own sweep (:data:`AMPLITUDE_PART`) over a subset of each look's impulse
starts (:data:`AMPLITUDE_DPHI_STRIDE`); the default beta's are read from the shared runs at the same
starts.  :func:`impulse_by_amplitude` compares them over the detuned starts (``dphi != 0``), the steps in
beta paired start by start.  The sentence's other half, "a larger projection of interaction surface
along the longitudinal direction", is not measured.  One channel for every beta is one W, so the larger
amplitudes are also the tighter confinements: with the free swimmers' A (35.8, 52.3, 67.2 mm at 30, 45,
60 deg) the 0.13 m channel is d/2A 0.91, 0.62 and 0.48, the last at the in-phase obstruction (0.48).
"""

from __future__ import annotations

import functools
import math
import warnings
from typing import Any

import numpy as np

from .. import stats, theory
from ..errors import ParameterError
from ..params import Gait, SwimmerGeometry
from ._criteria import PAIR_CHANNEL_M, R2_MIN
from . import _analysis as analysis
from ._context import StudyContext
from ._protocol import Claim, Study, Verdict
from ._registry import register
from ._stages import strides
from ..stopping import SteadyStop
from ._runners import pair_point
from ._shared import impulse_sweep
from . import _potential_evidence as _figures

__all__ = [
    "cohesion",
    "lateral_clearance_m",
    "model_dx0_m",
    "fit_stiffness",
    "fit_abs_linear",
    "stiffness_fit",
    "impulse_by_amplitude",
    "PotentialPlan",
    "plan",
    "dataset",
    "summary",
    "CLAIMS",
]

SETTLE_S = 6.0
"""Settling time before the forces switch on, s (3 periods)."""
DURATION_S = 50.0
BREAK = 0.45
"""dx / lambda beyond which the pair has broken apart (left its compatible state)."""
DRIFT = 0.005
"""Range of the last 3 period means (lambda) above which dx is still drifting."""
FORCE_STOP = SteadyStop(tol=2 * DRIFT, window=3, extra_periods=2, min_periods=8, drift_frac=0.5, spread_frac=0.25,
                        leave=BREAK, leave_after_s=SETTLE_S)
"""The force runs' stopping rule: the last 3 period means of dx/lambda within DRIFT / 2 of their mean
(so their range is at most :data:`DRIFT`: a stopped run is never "still drifting") in 3 consecutive
windows, no trend that would move them by DRIFT by the end of the run, never before 8 periods
(the force switches on after 3); or, a pair the force pulls apart, once each of its last 3 period
means lies more than :data:`BREAK` from the settled offset before the force and they span more than
2 DRIFT (still sliding): the analysis reads such a run as broken (its drift exceeds DRIFT), as it would
the whole run (in full mode the 54 broken runs of 663, all of them, met this at 14-28 s, and
had slid 1.7-12.7 lambda by 50 s; no run that held met it).  A pair that creeps runs the whole duration."""
SLIDING_FROM = 0.5
"""d/2A from which the collapse of k is also measured on its own: in narrower channels
the two bodies are wedged between the walls (an in-phase pair's gait is obstructed below
d/2A = 0.48, W = 101 mm: docs/confinement_d.md; the paper's "d/2A < 0.5 ... obstructed"),
the pair barely moves under any force and k is large but erratic."""

D_OVER_2A_QUICK = (0.5, 0.6, 0.7)
"""Quick mode's d/2A (per swimmer): from just above the obstruction (0.48) into the paper's range, the
widths at which the cohesion scan's pair held the quick ladder's rungs (module docstring, "Design").  Not
0.8: there the pair creeps across its neutral band under the low rungs for the whole run (held at one
or two rungs of four in each beta, so no fit), which cost a third of the quick force runs' simulated time
(547 of 1 530 s) and would take quick mode past the potential study's former cost; full mode measures
0.8 to 0.9."""
D_OVER_2A_FULL = tuple(float(v) for v in np.round(np.linspace(0.5, 0.9, 17), 10))
"""Full mode's d/2A: 0.5 to 0.9 in steps of 0.025 (17, for a rank correlation's interval per beta), up
to the first width of the cohesion scan with no contact (0.9), so the end of cohesion is measured."""
FORCES_N_FULL = (0.005, 0.01, 0.02, 0.04, 0.08)
"""Full mode's force ladder dF, N: doubling from 5 mN (the cohesion scan's smallest force, inside the
linear regime at every touching width) to 80 mN, into the holding force of d/2A 0.7 and 0.8 (between
20 and 100 mN in the scan).  A rung above it would find nothing new (the narrow channels hold 0.3 N) at
3 x 17 runs: the study's full runs stay within about 4 minutes on 2 cores."""
FORCES_N_QUICK = FORCES_N_FULL[:4]
"""Quick mode's ladder, N: its four lowest rungs (5 to 40 mN), up to about the holding force of the
widest touching channels (module docstring, "Design")."""
RELEASE_FORCE_N = min(FORCES_N_QUICK[0], FORCES_N_FULL[0])
"""dF of the release runs, N: the paper's "small dF" read as the smallest rung of the force ladder, which
both modes apply; fixed from the design, before any release run."""
RELEASE_HOLD_S = 20.0
"""How long the release runs hold the force, s (10 periods: twice the 5 periods after the onset from
which :data:`FORCE_STOP` may call a force run steady)."""
RELEASE_AFTER_S = 10.0
"""How long the release runs go on after the force is removed, s (5 periods)."""
RELEASE_WINDOWS = (2, 4, 3)
"""Periods in the release runs' windows: before the onset (the settled offset), the last of the hold
(the held offset and its drift: 4 period means give a slope on 2 degrees of freedom), and the last after
the removal (where the pair went back to)."""
SUSTAIN_FRAC = 0.1
"""The tolerance of "sustained", as a share of the separation ``D`` the force made: held, the offset
moves by less than this over 3 periods; released, it goes back by more than this (a change "sustained"
would not allow)."""
IMPULSE_BETA_DEG = round(math.degrees(Gait().amplitude_rad), 9)
"""Joint amplitude beta of the shared contact-impulse runs (the default gait's), degrees."""
AMPLITUDE_PART = "impulse_amplitude"
"""The plan part of the contact-impulse runs at the plan's other joint amplitudes (sweep
``impulse_amplitude``; the shared ``impulse`` sweep gives :data:`IMPULSE_BETA_DEG`'s)."""
AMPLITUDE_DPHI_STRIDE = {True: 1, False: 8}
"""Stride over the mode's impulse dphi of the impulse runs at the other amplitudes (True: quick).  Quick:
the quick impulse grid itself (9 dphi x 4 phi0: 32 detuned starts a beta, 36 runs).  Full: every eighth
dphi of the cap (10 dphi, 2 pi / 9 apart, x 8 phi0: 80 runs a beta, all detuned), not the cap's
73 x 8 = 584 a beta: the cap's dphi resolution was sized for the R^2 of the impulse's line on |dphi|
(about 57 |dphi|), while a mean over the detuned starts needs starts, not resolution in dphi; 160 runs
of 2 periods (about 0.2 s of physics each) instead of 1 168."""

lateral_clearance_m = theory.lateral_clearance_m
model_dx0_m = theory.neutral_offset_m
channel_width_m = theory.channel_width_m


def stiffness_fit(dF, dx, valid=None, min_points: int = 3) -> dict[str, stats.Estimate]:
    """Least squares ``dF = k (dx - dx0)`` with uncertainties: ``{"k", "dx0", "r2"}`` Estimates.

    ``dF``: applied forces (N); ``dx``: steady extra separations (m, or any
    unit: ``k`` is then N per that unit and ``dx0`` in it); ``valid``: points
    to use (e.g. not broken apart); non-finite points are ignored too.  Fits
    ``dF = k dx + c`` (``scipy.stats.linregress``: ``k`` with its standard
    error and t interval), ``dx0 = -c / k`` and R^2 with seeded paired
    bootstrap intervals.  NaNs when fewer than ``min_points`` usable points
    or no spread in ``dx``.
    """
    f = np.asarray(dF, float).ravel()
    x = np.asarray(dx, float).ravel()
    use = np.isfinite(f) & np.isfinite(x)
    if valid is not None:
        use &= np.asarray(valid, bool).ravel()
    f, x = f[use], x[use]
    nan = {k: stats.Estimate(float("nan"), n=int(f.size)) for k in ("k", "dx0", "r2")}
    if f.size < max(2, min_points) or np.ptp(x) == 0:
        return nan
    fit = stats.line_fit(x, f)
    k, c = fit.slope.value, fit.intercept.value
    if k == 0:
        return nan

    def dx0_of(a, b):
        if np.ptp(a) == 0:
            return float("nan")
        kk, cc = np.polyfit(a, b, 1)
        return float(-cc / kk) if kk != 0 else float("nan")

    se, lo, hi = stats.bootstrap(dx0_of, x, f)
    return {"k": fit.slope, "dx0": stats.Estimate(float(-c / k), se, lo, hi, int(f.size), "bootstrap BCa",
                                stats.level(), int(f.size), int(f.size) - 1),
            "r2": fit.r2}


def fit_stiffness(dF, dx, valid=None, min_points: int = 3) -> tuple[float, float, float]:
    """``(k, dx0, r2)`` of :func:`stiffness_fit` (values only)."""
    e = stiffness_fit(dF, dx, valid, min_points)
    return e["k"].value, e["dx0"].value, e["r2"].value


def fit_abs_linear(dphi, y) -> tuple[float, float, float]:
    """Least squares ``y = a |dphi| + b``; returns ``(a, b, r2)`` (NaNs if < 3 points);
    :func:`undulate.stats.line_fit` of ``y`` on ``|dphi|`` gives their uncertainties."""
    p = np.abs(np.asarray(dphi, float).ravel())
    v = np.asarray(y, float).ravel()
    ok = np.isfinite(p) & np.isfinite(v)
    p, v = p[ok], v[ok]
    if p.size < 3 or np.ptp(p) == 0:
        return (float("nan"),) * 3
    a, b = np.polyfit(p, v, 1)
    ss = np.sum((v - v.mean()) ** 2)
    r2 = 1.0 - np.sum((v - a * p - b) ** 2) / ss if ss > 0 else float("nan")
    return float(a), float(b), float(r2)


class PotentialPlan:
    """Grids of the potential study."""

    def __init__(self, impulse_dphi, betas_deg, d_over_2A, forces_N, duration_s: float = DURATION_S,
                 impulse_phi0=(0.0, np.pi / 2, np.pi, 3 * np.pi / 2), release=((), (), ()),
                 amplitude_betas_deg=(), amplitude_dphi=None, amplitude_phi0=None):
        self.impulse_dphi = [float(v) for v in impulse_dphi]
        self.impulse_phi0 = [float(v) for v in impulse_phi0]
        self.amplitude_betas_deg = [float(v) for v in amplitude_betas_deg]
        """Joint amplitudes (degrees) of the contact-impulse runs beside :data:`IMPULSE_BETA_DEG`'s (sweep
        :data:`AMPLITUDE_PART`); none: the impulse is compared across no amplitudes."""
        self.amplitude_dphi = list(self.impulse_dphi if amplitude_dphi is None else map(float, amplitude_dphi))
        """dphi (rad) of those runs, a subset of :attr:`impulse_dphi` (the default beta's runs are read there)."""
        self.amplitude_phi0 = list(self.impulse_phi0 if amplitude_phi0 is None else map(float, amplitude_phi0))
        """phi0 (rad) of those runs, a subset of :attr:`impulse_phi0`."""
        self.betas_deg = [float(v) for v in betas_deg]
        self.d_over_2A = [float(v) for v in d_over_2A]
        self.forces_N = sorted(float(v) for v in forces_N)
        self.duration_s = float(duration_s)
        b, r, f = release
        self.release = (tuple(float(v) for v in b), tuple(float(v) for v in r), tuple(float(v) for v in f))
        """The release runs' (betas in degrees, d/2A, forces in N): every combination, one run each."""


def plan(quick: bool) -> PotentialPlan:
    """The mode's cap (module docstring, "Design").  Full: 73 dphi (step pi/36) x 8 common phases; 3 beta x
    17 d/2A (:data:`D_OVER_2A_FULL`) x 5 forces (:data:`FORCES_N_FULL`) = 255 force runs.  Quick: 9 dphi x 4
    phases; 3 x 3 x 4 = 36 force runs.  Release runs (:data:`RELEASE_FORCE_N` at the quick grid's 3 d/2A): 1
    beta in quick (3 runs), 3 in full (9 runs).  The third full look's impulse grid (37 x 8) is
    :func:`._analysis.impulse_design`, shared with the studies that rerun these runs (``sensitivity``).  The
    impulse runs at the other betas (30 and 60 degrees): quick 9 x 4, full 10 x 8 a beta
    (:data:`AMPLITUDE_DPHI_STRIDE`)."""
    dphi, phi0 = analysis.impulse_design(quick)
    if quick:
        p = PotentialPlan(dphi, [30, 45, 60], D_OVER_2A_QUICK, FORCES_N_QUICK, impulse_phi0=phi0)
    else:
        p = PotentialPlan(analysis.refined(dphi, 2), [30, 45, 60], D_OVER_2A_FULL, FORCES_N_FULL, impulse_phi0=phi0)
    # release runs: the quick grid's d/2A at the default beta (quick) or every beta (full), dF = RELEASE_FORCE_N
    widths = p.d_over_2A if quick else plan(True).d_over_2A
    p.release = ((45.0,) if quick else tuple(p.betas_deg), tuple(widths), (RELEASE_FORCE_N,))
    # the impulse at the plan's other joint amplitudes (AMPLITUDE_DPHI_STRIDE: why full mode thins dphi)
    p.amplitude_betas_deg = [b for b in p.betas_deg if not math.isclose(b, IMPULSE_BETA_DEG)]
    p.amplitude_dphi = p.impulse_dphi[::AMPLITUDE_DPHI_STRIDE[quick]]
    p.amplitude_phi0 = list(p.impulse_phi0)
    return p


def sweep_plan(p: PotentialPlan, impulse: PotentialPlan, force: PotentialPlan,
               amplitude: PotentialPlan | None = None) -> PotentialPlan:
    """``p`` with the impulse sweep's grids ``impulse``'s, the force sweep's ``force``'s and the impulse runs
    at the other amplitudes ``amplitude``'s (the plans the parts ``"impulse"``, ``"force"`` and
    :data:`AMPLITUDE_PART` follow; None: ``p``'s); the release runs are the same in every plan."""
    a = p if amplitude is None else amplitude
    return PotentialPlan(impulse.impulse_dphi, force.betas_deg, force.d_over_2A, force.forces_N, p.duration_s,
                         impulse_phi0=impulse.impulse_phi0, release=p.release, amplitude_betas_deg=a.amplitude_betas_deg,
                         amplitude_dphi=a.amplitude_dphi, amplitude_phi0=a.amplitude_phi0)


def dataset(ctx: StudyContext, p: PotentialPlan):
    """Run the potential study on plan ``p``: the impulse sweep, free swimmers per beta, the force sweep,
    each sweep on the plan its part follows (:meth:`~._context.StudyContext.plan_for`: ``impulse`` feeds
    the first claim, ``force`` the others but the release claim, whose runs are the same at every look)."""
    import xarray as xr

    p = sweep_plan(p, ctx.plan_for("impulse", p), ctx.plan_for("force", p), ctx.plan_for(AMPLITUDE_PART, p))
    geo = SwimmerGeometry()
    lam = Gait().wavelength_m(geo.length_m)
    (imp_all, impulse, fit_a), (amps, g), rel, other = ctx.together(
        lambda: _impulse_part(ctx, p), lambda: _force_sweep(ctx, p), lambda: _release_sweep(ctx, p),
        lambda: _amplitude_sweep(ctx, p))
    resp = _steady_response(g, (len(p.betas_deg), len(p.d_over_2A), len(p.forces_N)))
    est, n_used = _stiffness_fits(p, resp["dx"], resp["broken"], lam)
    R = np.asarray(p.d_over_2A)
    one = {"units": "1"}
    ds = xr.Dataset(
        {
            "impulse": (("dphi",), impulse, {
                "units": "N s", "long_name": "pair contact impulse over the first 2 periods, mean over phi0"}),
            "impulse_all": (("dphi", "phi0"), imp_all, {
                "units": "N s", "long_name": "pair contact impulse over the first 2 periods"}),
            **_response_vars(resp),
            **_fit_vars(est, n_used, lam),
            "model_dx0_thin": (("beta", "d_over_2A"), np.array([model_dx0_m(channel_width_m(R, a, 2), a, lam) / lam
                                                         for a in amps]), {
                **one, "long_name": "compatibility model dx0 / lambda, sinusoids (dy = W - 2A, W = 2 d)"}),
            "model_dx0_bodies": (("beta", "d_over_2A"),
                                 np.array([model_dx0_m(channel_width_m(R, a, 2), a, lam, geo.width_m) / lam for a in amps]), {
                **one, "long_name": "compatibility model dx0 / lambda, bodies of width w (dy = W - 2A - 2w)"}),
            "amplitude": (("beta",), amps, {"units": "m", "long_name": "gait amplitude A of a free swimmer"}),
            **_release_vars(rel),
            "impulse_by_beta": (("impulse_beta", "impulse_beta_dphi", "impulse_beta_phi0"),
                                _impulse_by_beta(p, imp_all, other), {
                "units": "N s", "long_name": "pair contact impulse over the first 2 periods at each joint amplitude "
                                            "(the impulse runs' channel and start, dx0 = 0)"}),
        },
        coords={**_coords(p, amps, g["period_time"].values), **_amplitude_coords(p)},
        attrs={
            "title": "contact force against detuning; cohesion stiffness of the compatible state (paper Fig. 10)",
            "impulse_channel_width_m": PAIR_CHANNEL_M,
            "settle_s": SETTLE_S,
            "duration_s": p.duration_s,
            "impulse_fit_abs": list(fit_a),
            "wavelength_m": lam,
            "interval_level": float(stats.level()),
            "release_force_onset_s": SETTLE_S,
            "release_force_offset_s": SETTLE_S + RELEASE_HOLD_S,
        },
    )
    return ds


def _release_sweep(ctx: StudyContext, p: PotentialPlan) -> dict[str, np.ndarray]:
    """The release runs (module docstring): every (beta, d/2A, dF) of ``p.release``, the force on from
    :data:`SETTLE_S` for :data:`RELEASE_HOLD_S`, then off for :data:`RELEASE_AFTER_S`; no stopping rule.
    Their points are built as the force sweep's (``d_over_2A`` with the free swimmer's ``amplitude_m``:
    the one mapping to a channel, :func:`._runners.pair_scene`)."""
    from ..sweep import Grid

    betas, widths, forces = p.release
    amps = [float(ctx.lone_swimmer(amplitude_rad=math.radians(b))["amplitude_m"]) for b in betas]
    rows = [(b, a, r, f) for b, a in zip(betas, amps) for r in widths for f in forces]
    out = {"beta": np.array([r[0] for r in rows], float), "d_over_2A": np.array([r[2] for r in rows], float),
           "force": np.array([r[3] for r in rows], float)}
    if not rows:
        return {**out, "dx_period": np.zeros((0, 0)), "period_time": np.zeros(0), "failed": np.zeros(0, bool)}
    points = [{"amplitude_rad": math.radians(b), "amplitude_m": a, "d_over_2A": r, "force_N": f} for b, a, r, f in rows]
    fn = functools.partial(pair_point, duration_s=SETTLE_S + RELEASE_HOLD_S + RELEASE_AFTER_S,
                           force_onset_s=SETTLE_S, force_offset_s=SETTLE_S + RELEASE_HOLD_S)
    g = ctx.sweep("release", fn, Grid(points=points, seed=ctx.seed)).isel(replicate=0)
    return {**out, "dx_period": g["dx_period_over_lambda"].values.reshape(len(rows), -1),
            "period_time": g["period_time"].values, "failed": g["run_failed"].values.astype(bool).ravel()}


def _release_vars(rel: dict) -> dict:
    """Data variables of the release runs (dim ``release``: one run each)."""
    one = {"units": "1"}
    return {
        "release_beta": (("release",), rel["beta"], {"units": "degree", "long_name": "joint amplitude beta"}),
        "release_d_over_2A": (("release",), rel["d_over_2A"], {**one, "long_name": "d/2A of the release run"}),
        "release_force": (("release",), rel["force"], {"units": "N", "long_name": "dF, on from settle_s until "
                                                                                   "release_force_offset_s"}),
        "release_period_time": (("release_period_time",), rel["period_time"], {
            "units": "s", "long_name": "middle of the gait period (release runs)"}),
        "release_dx_period": (("release", "release_period_time"), rel["dx_period"], {
            **one, "long_name": "period mean of dx / lambda, force on then removed"}),
        "release_failed": (("release",), rel["failed"], {}),
    }


def _difference(a, b) -> stats.Estimate:
    """``mean(a) - mean(b)`` with Welch's t interval at the current level (Welch-Satterthwaite degrees of
    freedom, ``scipy.stats.t``; the same interval as ``scipy.stats.ttest_ind(a, b, equal_var=False)``,
    without its precision warning on nearly equal period means); an exact interval when neither sample
    varies (a deterministic run settled to rounding)."""
    from scipy import stats as st

    a, b = np.asarray(a, float), np.asarray(b, float)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    n = int(a.size + b.size)
    if a.size < 2 or b.size < 2:
        return stats.Estimate(float(a.mean() - b.mean()) if a.size and b.size else math.nan, n=n,
                              method="Welch t interval")
    d = float(a.mean() - b.mean())
    va, vb = a.var(ddof=1) / a.size, b.var(ddof=1) / b.size  # centred sums: no cancellation on settled runs
    se = math.sqrt(va + vb)
    if se == 0:
        return stats.Estimate(d, 0.0, d, d, n, "exact (no spread)", stats.level(), n, n - 2)
    dof = (va + vb) ** 2 / (va ** 2 / (a.size - 1) + vb ** 2 / (b.size - 1))  # Welch-Satterthwaite
    q = float(st.t.ppf((1 + stats.level()) / 2, dof))
    return stats.Estimate(d, se, d - q * se, d + q * se, n, "Welch t interval", stats.level(), n, float(dof))


def _slope(t, y) -> stats.Estimate:
    """Least-squares slope of ``y`` on ``t`` (``scipy.stats.linregress``) with its t interval at the
    current level on ``n - 2`` degrees of freedom."""
    from scipy import stats as st

    t, y = np.asarray(t, float), np.asarray(y, float)
    ok = np.isfinite(t) & np.isfinite(y)
    t, y = t[ok], y[ok]
    n = int(t.size)
    if n < 3 or np.ptp(t) == 0:
        return stats.Estimate(math.nan, n=n, method="linregress, t interval")
    r = st.linregress(t, y)
    q = float(st.t.ppf((1 + stats.level()) / 2, n - 2))
    se = float(r.stderr)
    return stats.Estimate(float(r.slope), se, r.slope - q * se, r.slope + q * se, n, "linregress, t interval",
                          stats.level(), n, n - 2)


def release_response(dx_period, period_time, onset_s: float, offset_s: float,
                     windows: tuple[int, int, int] = RELEASE_WINDOWS) -> dict[str, stats.Estimate]:
    """What one release run did (``dx_period``: its period means of dx / lambda at ``period_time``, s;
    the force on from ``onset_s`` to ``offset_s``, s; ``windows``: periods before the onset, at the end
    of the hold, at the end of the run).  ``separation``: held minus settled offset (the force's ``D``,
    Welch); ``drift_3T``: the slope of the hold window's period means times 3 periods (t interval);
    ``back``: held minus final offset (how far it went back once the force was removed, Welch); all in
    lambda."""
    x = np.asarray(dx_period, float)
    t = np.asarray(period_time, float)
    if t.size < 2:
        raise ParameterError("period_time", "at least 2 periods", t.size)
    T = float(t[1] - t[0])
    n_pre, n_hold, n_after = windows
    pre = (t < onset_s) & (t > onset_s - n_pre * T)
    hold = (t < offset_s) & (t > offset_s - n_hold * T)
    after_idx = np.flatnonzero((t > offset_s) & np.isfinite(x))[-n_after:]
    after = np.zeros(t.size, bool)
    after[after_idx] = True
    return {"separation": _difference(x[hold], x[pre]), "drift_3T": _slope(t[hold], x[hold]).scaled(3 * T),
            "back": _difference(x[hold], x[after])}


def _impulse_part(ctx: StudyContext, p: PotentialPlan):
    """(a) contact impulse over the first two periods against dphi, for several common phases:
    every run ``(dphi, phi0)``, their mean over phi0 and its ``|dphi|`` fit."""
    imp_all = ctx.shared_sweep("impulse", *impulse_sweep(p.impulse_dphi, p.impulse_phi0, ctx.seed)
                               ).isel(replicate=0)["impulse_2T_Ns"].values  # (dphi, phi0)
    impulse = np.nanmean(imp_all, axis=1)
    return imp_all, impulse, fit_abs_linear(np.asarray(p.impulse_dphi), impulse)


def _amplitude_sweep(ctx: StudyContext, p: PotentialPlan) -> np.ndarray:
    """The contact-impulse runs at ``p.amplitude_betas_deg`` (the shared impulse runs' function, channel and
    duration, :func:`._shared.impulse_sweep`, with the joint amplitude an axis before dphi and phi0) over
    ``p.amplitude_dphi`` x ``p.amplitude_phi0``: their impulse, N s, (beta, dphi, phi0); none: (0, ., .)."""
    if not p.amplitude_betas_deg:
        return np.zeros((0, len(p.amplitude_dphi), len(p.amplitude_phi0)))
    fn, grid = impulse_sweep(p.amplitude_dphi, p.amplitude_phi0, ctx.seed,
                             amplitude_rad=[math.radians(b) for b in p.amplitude_betas_deg])
    return ctx.sweep(AMPLITUDE_PART, fn, grid).isel(replicate=0)["impulse_2T_Ns"].values


def _amplitude_betas(p: PotentialPlan) -> list[float]:
    """The joint amplitudes (degrees, ascending) the impulse is compared across: the shared runs' and
    ``p.amplitude_betas_deg``."""
    return sorted([IMPULSE_BETA_DEG, *p.amplitude_betas_deg])


def _impulse_by_beta(p: PotentialPlan, imp_all, other) -> np.ndarray:
    """The impulse (N s) at every beta of :func:`_amplitude_betas` over the same starts
    (``p.amplitude_dphi`` x ``p.amplitude_phi0``): :data:`IMPULSE_BETA_DEG`'s read from the shared impulse
    runs ``imp_all`` (dphi, phi0) at those starts, the others' from ``other`` (:func:`_amplitude_sweep`)."""
    rows = analysis.positions(p.impulse_dphi, p.amplitude_dphi)
    cols = analysis.positions(p.impulse_phi0, p.amplitude_phi0)
    base = np.asarray(imp_all, float)[np.ix_(rows, cols)]
    by_beta = {IMPULSE_BETA_DEG: base, **{b: np.asarray(v, float) for b, v in zip(p.amplitude_betas_deg, other)}}
    return np.stack([by_beta[b] for b in _amplitude_betas(p)])


def _amplitude_coords(p: PotentialPlan) -> dict:
    """Coordinates of the impulse runs compared across joint amplitudes."""
    return {
        "impulse_beta": ("impulse_beta", np.asarray(_amplitude_betas(p)), {
            "units": "degree", "long_name": "joint amplitude beta of the impulse runs"}),
        "impulse_beta_dphi": ("impulse_beta_dphi", np.asarray(p.amplitude_dphi), {
            "units": "rad", "long_name": "phase difference phi_b - phi_a of the impulse runs across amplitudes"}),
        "impulse_beta_phi0": ("impulse_beta_phi0", np.asarray(p.amplitude_phi0), {
            "units": "rad", "long_name": "phase phi_a of the impulse runs across amplitudes"}),
    }


def _force_sweep(ctx: StudyContext, p: PotentialPlan):
    """Amplitudes per beta (free swimmers), then every (beta, d/2A, dF) in one sweep: ``(amps, sweep)``."""
    from ..sweep import Grid

    betas = [math.radians(b) for b in p.betas_deg]
    amps = np.array([float(ds["amplitude_m"]) for ds in ctx.together(
        *(functools.partial(ctx.lone_swimmer, amplitude_rad=b) for b in betas))])
    points = [{"amplitude_rad": beta, "amplitude_m": float(amp), "d_over_2A": r, "force_N": f}
              for beta, amp in zip(betas, amps) for r in p.d_over_2A for f in p.forces_N]
    fn = functools.partial(pair_point, duration_s=p.duration_s, force_onset_s=SETTLE_S, stop=FORCE_STOP)
    return amps, ctx.sweep("force", fn, Grid(points=points, seed=ctx.seed)).isel(replicate=0)


def _last_periods(pm: np.ndarray, n: int) -> np.ndarray:
    """The last ``n`` period means each run stepped (``pm``: (..., period), NaN after a stop)."""
    stepped = np.isfinite(pm).sum(axis=-1, keepdims=True)  # periods before the stop (all: whole run)
    idx = np.clip(stepped - n + np.arange(n), 0, pm.shape[-1] - 1)
    return np.take_along_axis(pm, idx, axis=-1)


def _steady_response(g, shape) -> dict[str, np.ndarray]:
    """Per (beta, d/2A, dF): period means of dx / lambda, the settled value before the force, the
    steady extra separation (mean of the last 3 periods minus it), their drift, and what broke."""
    pm = g["dx_period_over_lambda"].values.reshape(*shape, -1)
    pt = g["period_time"].values
    k_before = int(np.flatnonzero(pt < SETTLE_S)[-1])
    last = _last_periods(pm, 3)
    before = pm[..., k_before]
    dxl = last.mean(axis=-1) - before
    drift = np.ptp(last, axis=-1)
    failed = g["run_failed"].values.astype(bool).reshape(shape)
    with np.errstate(invalid="ignore"):
        broken = failed | ~np.isfinite(dxl) | (dxl > BREAK) | (drift > DRIFT)
    return {"dx_period": pm, "dx_before": before, "dx": dxl, "drift": drift, "failed": failed, "broken": broken}


def _stiffness_fits(p: PotentialPlan, dxl, broken, lam: float):
    """:func:`stiffness_fit` per (beta, d/2A) on the runs that held: ``({k, dx0, r2}: (value, stderr,
    low, high) arrays, points used)``."""
    n_b, n_r = dxl.shape[:2]
    est = {q: np.full((n_b, n_r, 4), np.nan) for q in ("k", "dx0", "r2")}  # value, stderr, low, high
    n_used = (~broken).sum(axis=-1)
    for i in range(n_b):
        for j in range(n_r):
            fit = stiffness_fit(p.forces_N, dxl[i, j] * lam, ~broken[i, j])
            for q, e in fit.items():
                est[q][i, j] = (e.value, e.stderr, e.low, e.high)
    return est, n_used


def _response_vars(resp: dict) -> dict:
    """Data variables of the force sweep's runs (beta x d/2A x dF)."""
    one = {"units": "1"}
    fdims = ("beta", "d_over_2A", "force")
    return {
        "dx": (fdims, resp["dx"], {**one, "long_name": "steady extra separation dx / lambda under +-dF"}),
        "dx_before": (fdims, resp["dx_before"], {**one, "long_name": "settled dx / lambda"}),
        "drift": (fdims, resp["drift"], {**one, "long_name": "range of the last 3 period means of dx / lambda"}),
        "broken": (fdims, resp["broken"], {
            "long_name": f"broke apart (dx/lambda > {BREAK}, still drifting, or failed)"}),
        "run_failed": (fdims, resp["failed"], {}),
        "dx_period": ((*fdims, "period_time"), resp["dx_period"], {**one, "long_name": "period mean of dx / lambda"}),
    }


def _fit_vars(est: dict, n_used, lam: float) -> dict:
    """Data variables of the stiffness fits per (beta, d/2A)."""
    one = {"units": "1"}
    bound = ("beta", "d_over_2A", "bound")
    return {
        "stiffness": (("beta", "d_over_2A"), est["k"][..., 0], {"units": "N/m", "long_name": "k in dF = k (dx - dx0)"}),
        "dx0": (("beta", "d_over_2A"), est["dx0"][..., 0] / lam, {**one, "long_name": "offset dx0 / lambda of the fit"}),
        "fit_r2": (("beta", "d_over_2A"), est["r2"][..., 0], {**one, "long_name": "R^2 of the fit"}),
        "stiffness_stderr": (("beta", "d_over_2A"), est["k"][..., 1], {
            "units": "N/m", "long_name": "standard error of k (linregress)"}),
        "stiffness_ci95": (bound, est["k"][..., 2:], {
            "units": "N/m", "long_name": "interval of k (t) at attrs['interval_level']"}),
        "dx0_ci95": (bound, est["dx0"][..., 2:] / lam, {
            **one, "long_name": "interval of dx0 / lambda (bootstrap) at attrs['interval_level']"}),
        "fit_r2_ci95": (bound, est["r2"][..., 2:], {
            **one, "long_name": "interval of R^2 (bootstrap) at attrs['interval_level']"}),
        "fit_n": (("beta", "d_over_2A"), n_used, {**one, "long_name": "points in the fit"}),
    }


def _coords(p: PotentialPlan, amps, period_time) -> dict:
    """Coordinates of the study's Dataset."""
    one = {"units": "1"}
    R = np.asarray(p.d_over_2A)
    return {
        "dphi": ("dphi", np.asarray(p.impulse_dphi), {"units": "rad", "long_name": "phase difference phi_b - phi_a"}),
        "phi0": ("phi0", np.asarray(p.impulse_phi0), {"units": "rad", "long_name": "phase phi_a"}),
        "beta": ("beta", np.asarray(p.betas_deg), {"units": "degree", "long_name": "joint amplitude beta"}),
        "d_over_2A": ("d_over_2A", R, {**one, "long_name": "wall distance per swimmer over peak-to-peak "
                                                            "amplitude"}),
        "force": ("force", np.asarray(p.forces_N), {"units": "N", "long_name": "applied force dF"}),
        "period_time": ("period_time", period_time, {"units": "s", "long_name": "middle of the gait period"}),
        "channel_width": (("beta", "d_over_2A"), np.array([channel_width_m(R, a, 2) for a in amps]), {
            "units": "m", "long_name": "channel width W = 2 d, wall to wall (undulate.theory.channel_width_m)"}),
        "bound": ("bound", ["low", "high"], {"long_name": "bounds of an interval at attrs['interval_level']"}),
    }


def cohesion(forces_N, broken) -> dict[str, Any]:
    """What one (beta, d/2A)'s force ladder says about the pair's cohesion (``forces_N``: the rungs, N;
    ``broken``: per rung, the run broke apart or still drifted).  ``held_N``: the rungs that held;
    ``holds_up_to_N``: the largest of them (NaN if none); ``breaks_from_N``: the first rung above it,
    which broke (NaN if the largest rung held: the holding force lies above the ladder); ``cohesive``:
    some rung held.  A width where none held has no cohesion, and its stiffness is reported as
    ``k_N_per_m = 0`` (measured: any force there slides the pair away), not fitted; elsewhere
    ``k_N_per_m`` is NaN here (the fit gives it).  Rungs below ``holds_up_to_N`` that broke
    (``slid_below_hold_N``) are the small forces that creep across a neutral band for the whole run."""
    f = np.asarray(forces_N, float).ravel()
    b = np.asarray(broken, bool).ravel()
    if f.shape != b.shape:
        raise ParameterError("broken", f"one flag per force ({f.size})", b.size)
    order = np.argsort(f)
    f, b = f[order], b[order]
    held = f[~b]
    top = float(held.max()) if held.size else math.nan
    above = f[(f > top) & b] if held.size else f[b]
    breaks = float(above.min()) if held.size and above.size else (float(f.min()) if not held.size and f.size
                                                                     else math.nan)
    return {"held_N": [float(v) for v in held], "holds_up_to_N": top, "breaks_from_N": breaks,
            "slid_below_hold_N": [float(v) for v in f[b & (f < top)]] if held.size else [],
            "cohesive": bool(held.size), "k_N_per_m": math.nan if held.size else 0.0}


def _collapse_rms_value(x, logk) -> float:
    x, logk = np.asarray(x, float).ravel(), np.asarray(logk, float).ravel()
    ok = np.isfinite(x) & np.isfinite(logk)
    if ok.sum() < 4:
        return float("nan")
    return float(_collapse_rms_rows(x[ok], logk[ok]))


def _collapse_rms_rows(x, logk, axis: int = -1) -> np.ndarray:
    """:func:`_collapse_rms_value` of each row of 2-D ``x``, ``logk`` (finite values; the bootstrap's
    resamples at once): the least-squares quadratic in the centred and scaled ``x`` (a well-conditioned
    fit) by its normal equations, NaN for a row with fewer than 3 distinct ``x``."""
    x, logk = np.moveaxis(np.asarray(x, float), axis, -1), np.moveaxis(np.asarray(logk, float), axis, -1)
    shape = x.shape[:-1]  # a 1-D pair gives a scalar
    x, logk = x.reshape(-1, x.shape[-1]), logk.reshape(-1, logk.shape[-1])
    if x.shape[-1] < 4:
        return np.full(shape, np.nan)
    std = x.std(axis=-1, keepdims=True)
    u = (x - x.mean(axis=-1, keepdims=True)) / np.where(std > 0, std, 1.0)
    design = np.stack([u * u, u, np.ones_like(u)], axis=-1)  # rows x points x 3
    gram = np.einsum("rpi,rpj->rij", design, design)
    rhs = np.einsum("rpi,rp->ri", design, logk)
    distinct = 1 + np.count_nonzero(np.diff(np.sort(x, axis=-1), axis=-1) > 0, axis=-1)
    good = distinct >= 3
    coef = np.full(rhs.shape, np.nan)
    if good.any():
        coef[good] = np.linalg.solve(gram[good], rhs[good][..., None])[..., 0]
    resid = logk - np.einsum("rpi,ri->rp", design, coef)
    return np.where(good, np.sqrt(np.mean(resid ** 2, axis=-1)), np.nan).reshape(shape)


def _collapse_rms(x, logk) -> stats.Estimate:
    """RMS of log10 k about one quadratic in ``x`` pooled over every beta, with a bootstrap interval."""
    x, logk = np.asarray(x, float).ravel(), np.asarray(logk, float).ravel()
    ok = np.isfinite(x) & np.isfinite(logk)
    v = _collapse_rms_value(x, logk)
    se, lo, hi = stats.bootstrap(_collapse_rms_rows, x[ok], logk[ok], vectorized=True)
    return stats.Estimate(v, se, lo, hi, int(ok.sum()), "bootstrap BCa", stats.level(), int(ok.sum()),
                          int(ok.sum()) - 1)


def _r2_without_scatter_value(x, y, noise_var) -> float:
    """R^2 of the line of ``y`` on ``x`` with the measurement noise of ``y`` taken out of both the
    residual and the total variance (``noise_var``: each point's noise variance): the share of the
    variance of the noise-free ``y`` the line would explain (the correction for attenuation), at most 1."""
    slope, intercept, _ = fit_abs_linear(x, y)  # x >= 0 here: the line on |dphi|; NaN when degenerate
    noise = float(np.mean(noise_var))
    res = float(np.mean((y - (slope * x + intercept)) ** 2)) - noise
    tot = float(np.var(y)) - noise
    # a share: a residual below the noise is 1 (np.minimum keeps a NaN a NaN, as min() would not)
    return float(np.minimum(1.0, 1.0 - res / tot)) if tot > 0 else math.nan


def _split_half_means(dphi, impulse_all) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per distinct |dphi|: ``(|dphi|, mean of its runs, the mean's error variance)``, the variance from
    two interpenetrating halves of its runs, ``((m1 - m2) / 2) ** 2``: the runs at +dphi and those at
    -dphi (two phase grids shifted against each other: the pair at -dphi from phi0 is the pair at +dphi
    from phi0 + dphi + pi), or the even and odd common phases of one row where only one row holds the
    |dphi| (dphi = 0) or the two rows are the same runs (the shift is a whole number of grid steps, as
    at +-pi: equal to rounding, compared sorted).  The common phases are equally spaced, not drawn, so a
    mean over them is far more exact than var(phi0) / n says; two interpenetrating systematic halves
    estimate the error of their mean without that assumption (Mahalanobis's interpenetrating
    subsamples; one run a half will do).  A |dphi| with a half whose runs all failed is left out."""
    keys = analysis.abs_dphi_keys(dphi)
    a = np.asarray(impulse_all, float).reshape(keys.size, -1)
    out = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a half whose runs all failed
        for k in np.unique(keys):
            rows = a[keys == k]
            same = len(rows) == 2 and np.allclose(np.sort(rows[0]), np.sort(rows[1]), rtol=1e-9, atol=0.0,
                                                  equal_nan=True)
            halves = (rows[0], rows[1]) if len(rows) == 2 and not same else (rows[0][::2], rows[0][1::2])
            if min(np.isfinite(h).sum() for h in halves) < 1:
                continue
            m1, m2 = (float(np.nanmean(h)) for h in halves)
            out.append((float(k), float(np.nanmean(rows)), ((m1 - m2) / 2.0) ** 2))
    x, y, nv = (np.array(v, float) for v in zip(*out)) if out else (np.array([]),) * 3
    return x, y, nv


def impulse_r2_without_phase_scatter(dphi, impulse_all) -> stats.Estimate:
    """R^2 of the impulse's line on |dphi| if each |dphi|'s mean over the common phases were exact: each
    mean's error variance (:func:`_split_half_means`: from its two interpenetrating halves, the runs at
    +dphi and at -dphi) taken out of the residual and the total (:func:`_r2_without_scatter_value`); a
    paired bootstrap over |dphi| at the current level.  ``dphi``: the signed phase differences, one row
    of ``impulse_all`` (dphi, phi0) each.  Tells how much of the line's shortfall is the phases' scatter
    and how much is shape.  Not var(phi0) / n, as if the phases were drawn at random: on the equally
    spaced phases that overstates the error several times (full mode's
    37 |dphi|: 0.86 against 0.82 from four times the phases, whose plain R^2 is 0.815:
    ``explorations/impulse_cap.py``)."""
    x, y, nv = _split_half_means(dphi, impulse_all)
    value = _r2_without_scatter_value(x, y, nv) if x.size >= 3 else math.nan
    se, lo, hi = stats.bootstrap(_r2_without_scatter_value, x, y, nv)
    return stats.Estimate(value, se, lo, hi, int(x.size), "bootstrap BCa over |dphi|", stats.level(), int(x.size),
                          int(x.size) - 1)


def _per_beta_summary(ds, R, k, fit_level: float) -> dict[str, Any]:
    """Per beta: its A, the fits (k, dx0, R^2 with intervals), the rank correlation of k with d, the
    model's dx0 and the cohesion of each width."""
    per_beta = {}
    for i, b in enumerate(ds["beta"].values):
        ok = np.isfinite(k[i])
        def est(v, se, ci, unit=1.0):
            return [stats.Estimate(a * unit, s_ * unit, lo * unit, hi * unit, int(n), m, fit_level).to_dict()
                    for a, s_, (lo, hi), n, m in zip(v, se, ci, ds["fit_n"].values[i],
                                                      [method] * len(v))]

        method = "k: linregress stderr, t interval; dx0, R^2: bootstrap BCa"
        nan = np.full(R.size, np.nan)
        per_beta[f"{b:g}"] = {
            "amplitude_m": float(ds["amplitude"].values[i]),
            "channel_width_m": ds["channel_width"].values[i],
            "stiffness_N_per_m": est(k[i], ds["stiffness_stderr"].values[i], ds["stiffness_ci95"].values[i]),
            "dx0_over_lambda": est(ds["dx0"].values[i], nan, ds["dx0_ci95"].values[i]),
            "fit_r2": est(ds["fit_r2"].values[i], nan, ds["fit_r2_ci95"].values[i]),
            "fit_points": ds["fit_n"].values[i],
            "spearman_k_vs_d": stats.rank_correlation(R[ok], k[i][ok]).to_dict(),
            "model_dx0_thin_over_lambda": ds["model_dx0_thin"].values[i],
            "model_dx0_bodies_over_lambda": ds["model_dx0_bodies"].values[i],
            "cohesion": [{"d_over_2A": float(r), **cohesion(ds["force"].values, ds["broken"].values[i, j])}
                         for j, r in enumerate(R)],
        }
        per_beta[f"{b:g}"]["no_cohesion_d_over_2A"] = [c["d_over_2A"] for c in per_beta[f"{b:g}"]["cohesion"]
                                                       if not c["cohesive"]]
    return per_beta


def summary(ds) -> dict[str, Any]:
    """Pure: the impulse fit (line on |dphi|, standard errors), per beta k, dx0, R^2 with intervals and
    the rank correlation of k with d; the collapse of log10 k against d/2A and against d."""
    dphi = ds["dphi"].values
    impulse = ds["impulse"].values
    # the line on |dphi|: +-dphi are one design point (mirror images), so their runs are pooled
    abs_dphi, pooled = analysis.by_abs_dphi(dphi, ds["impulse_all"].values)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # an all-NaN row: every run there failed
        pooled_mean = np.nanmean(pooled, axis=1)
    fit_a = stats.line_fit(abs_dphi, pooled_mean)
    fit_pos = stats.line_fit(np.abs(dphi[dphi >= 0]), impulse[dphi >= 0])
    fit_neg = stats.line_fit(np.abs(dphi[dphi <= 0]), impulse[dphi <= 0])
    k = ds["stiffness"].values
    R = ds["d_over_2A"].values
    with np.errstate(invalid="ignore", divide="ignore"):
        logk = np.where(k > 0, np.log10(k), np.nan)
    x_scaled = np.broadcast_to(R, k.shape)
    x_metres = ds["channel_width"].values
    sliding = x_scaled >= SLIDING_FROM - 1e-9
    fit_level = float(ds.attrs.get("interval_level", stats.CONFIDENCE))
    per_beta = _per_beta_summary(ds, R, k, fit_level)
    r2_all = ds["fit_r2"].values
    return {
        "impulse_fit": {"slope_Ns_per_rad": fit_a.slope.to_dict(), "intercept_Ns": fit_a.intercept.to_dict(),
                        "r2": fit_a.r2.to_dict(),
                        "r2_without_phase_scatter":
                            impulse_r2_without_phase_scatter(dphi, ds["impulse_all"].values).to_dict(),
                        "n_abs_dphi": int(abs_dphi.size),
                        "positive_dphi": fit_pos.to_dict(),
                        "negative_dphi": fit_neg.to_dict(), "form": "impulse = slope |dphi| + intercept"},
        "impulse_Ns": ds["impulse"].values,
        "dphi_rad": ds["dphi"].values,
        "d_over_2A": R,
        "per_beta": per_beta,
        "median_fit_r2": float(np.nanmedian(r2_all)),
        "fit_r2_ci95_low_median": float(np.nanmedian(ds["fit_r2_ci95"].values[..., 0])),
        "fit_r2_ci95_high_median": float(np.nanmedian(ds["fit_r2_ci95"].values[..., 1])),
        "n_fits": int(np.isfinite(r2_all).sum()),
        "n_fit_points": int(np.sum(np.where(np.isfinite(r2_all), ds["fit_n"].values, 0))),
        "fit_r2_level": fit_level,
        "collapse_rms_log10k_vs_d_over_2A": _collapse_rms(x_scaled.ravel(), logk.ravel()).to_dict(),
        "collapse_rms_log10k_vs_d_m": _collapse_rms(x_metres.ravel(), logk.ravel()).to_dict(),
        "collapse_rms_log10k_vs_d_over_2A_sliding": _collapse_rms(x_scaled[sliding], logk[sliding]).to_dict(),
        "collapse_rms_log10k_vs_d_m_sliding": _collapse_rms(x_metres[sliding], logk[sliding]).to_dict(),
        "sliding_regime": f"d/2A >= {SLIDING_FROM} (below it the pair is wedged between the walls)",
        "no_cohesion": {b: v["no_cohesion_d_over_2A"] for b, v in per_beta.items()},
        "no_cohesion_note": "(beta, d/2A) where no rung of the force ladder held: k = 0 as measured (any "
                            "force slides the pair away), not fitted; the stiffness claims read the fits only",
        "n_points_broken": int(ds["broken"].values.sum()),
        "n_points": int(ds["broken"].size),
        "n_failed": int(ds["run_failed"].values.sum()),
        "k_by_amplitude_at_width": stiffness_by_amplitude(
            ds["beta"].values, ds["amplitude"].values, x_metres, k, ds["stiffness_stderr"].values,
            ds["fit_n"].values),
        "dx0_vs_model": dx0_against_model(ds["dx0"].values, ds["dx0_ci95"].values, ds["model_dx0_thin"].values),
        "impulse_by_amplitude": impulse_by_amplitude(ds["impulse_beta"].values, ds["impulse_beta_dphi"].values,
                                                     ds["impulse_by_beta"].values),
        "release": _release_summary(ds),
        "rules": f"dx: mean of last 3 periods minus the period before onset ({SETTLE_S} s); broken: "
                 f"dx/lambda > {BREAK} or last-3-period range > {DRIFT} lambda; fit by least squares of dF on dx",
    }


def _share(k: int, n: int) -> stats.Estimate:
    """The share ``k / n`` with its Clopper-Pearson interval at the current level
    (``scipy.stats.binomtest(...).proportion_ci``)."""
    from scipy import stats as st

    if n == 0:
        return stats.Estimate(math.nan, n=0, method="Clopper-Pearson")
    ci = st.binomtest(int(k), int(n)).proportion_ci(confidence_level=stats.level(), method="exact")
    return stats.Estimate(k / n, math.nan, float(ci.low), float(ci.high), int(n), "Clopper-Pearson", stats.level(),
                          int(n))


def dx0_against_model(dx0, dx0_ci, model) -> dict[str, Any]:
    """Each fit's offset ``dx0`` (``dx0_ci``: its interval, last axis (low, high)) against the compatibility
    model's ``model`` at the same (beta, d/2A), all in lambda.  A fit lies *below* the model when its whole
    interval does, *above* when its whole interval does, else it is unresolved; fits without a finite
    ``dx0`` or interval are left out.  ``share_below``: the share of fits below, ``share_not_above``: the
    share not above (below or unresolved), each with its Clopper-Pearson interval over the fits;
    ``mean_difference``: the mean of ``dx0 - model`` over the fits (t interval), reported."""
    x = np.asarray(dx0, float).ravel()
    ci = np.asarray(dx0_ci, float).reshape(-1, 2)
    m = np.asarray(model, float).ravel()
    ok = np.isfinite(x) & np.isfinite(ci).all(axis=1) & np.isfinite(m)
    lo, hi, mm = ci[ok, 0], ci[ok, 1], m[ok]
    n = int(ok.sum())
    below, above = int(np.sum(hi < mm)), int(np.sum(lo > mm))
    return {"n_fits": n, "n_below": below, "n_above": above, "n_unresolved": n - below - above,
            "share_below": _share(below, n).to_dict(), "share_not_above": _share(n - above, n).to_dict(),
            "mean_difference_over_lambda": stats.mean(x[ok] - mm).to_dict(),
            "model": "compatibility model for sinusoids (model_dx0_thin), the paper's dashed line"}


def stiffness_by_amplitude(betas_deg, amplitudes_m, widths_m, k, k_stderr, k_points) -> dict[str, Any]:
    """k at a fixed channel width, larger amplitude against smaller, for each pair of betas.

    ``betas_deg`` (n_b,), ``amplitudes_m`` (n_b,): each beta's free-swimmer amplitude ``A``, m;
    ``widths_m`` (n_b, n_d): the channel width ``W`` of each (beta, d/2A), m (each beta's own, as its
    d/2A is normalised by its own ``A``); ``k``, ``k_stderr`` (n_b, n_d): the stiffness fits, N/m, and
    their standard errors (``linregress``); ``k_points``: the points in each fit.  A fit is used where
    ``k > 0`` with a finite standard error and at least 3 points.

    For each pair of betas (ordered by amplitude: ``hi`` the larger ``A``), ``ln k`` of each is
    interpolated linearly in ``W`` between its fitted widths, at every fitted width of either beta that
    lies within both betas' fitted ranges; ``log_k_ratio`` is the mean over those widths of
    ``ln k_hi(W) - ln k_lo(W)``.  Its standard error is propagated from the fits' own: ``se(ln k) =
    se(k) / k`` (delta method), the mean a linear combination of the fits' ``ln k``, fits independent
    (separate runs); its t interval at :func:`undulate.stats.level` uses the Welch-Satterthwaite degrees
    of freedom over the fits' ``points - 2``.  No common width (or a single fit per beta): NaN, ``n = 0``.
    """
    from scipy import stats as st

    b = np.asarray(betas_deg, float).ravel()
    amp = np.asarray(amplitudes_m, float).ravel()
    W, kk, se = (np.asarray(a, float) for a in (widths_m, k, k_stderr))
    npts = np.asarray(k_points, float)
    if not (W.ndim == 2 and W.shape[0] == b.size and W.shape == kk.shape == se.shape == npts.shape
            and amp.shape == b.shape):
        raise ParameterError("k", f"widths, k, stderr and points shaped (beta, d/2A) = ({b.size}, n)", kk.shape)
    with np.errstate(invalid="ignore", divide="ignore"):
        ok = np.isfinite(W) & np.isfinite(kk) & (kk > 0) & np.isfinite(se) & (npts >= 3)
        lnk, lse = np.log(np.where(ok, kk, np.nan)), se / kk
    order = np.argsort(amp)
    pairs = {}
    for a_i in range(order.size):
        for a_j in range(a_i + 1, order.size):
            lo_b, hi_b = order[a_i], order[a_j]
            key = f"{b[lo_b]:g}-{b[hi_b]:g}"
            xs = [np.sort(W[i][ok[i]]) for i in (lo_b, hi_b)]
            entry = {"beta_low_deg": float(b[lo_b]), "beta_high_deg": float(b[hi_b]),
                     "amplitude_low_m": float(amp[lo_b]), "amplitude_high_m": float(amp[hi_b]),
                     "at_channel_widths_m": []}
            if min(x.size for x in xs) < 2 or max(x[0] for x in xs) > min(x[-1] for x in xs):
                entry["log_k_ratio"] = stats.Estimate(math.nan, n=0, method="no common width").to_dict()
                pairs[key] = entry
                continue
            w_lo, w_hi = max(x[0] for x in xs), min(x[-1] for x in xs)
            at = np.unique(np.concatenate(xs))
            at = at[(at >= w_lo - 1e-12) & (at <= w_hi + 1e-12)]
            # coefficients of the mean difference on each fit's ln k: +interp weights for hi, - for lo
            coef = np.zeros_like(kk)
            for i, sign in ((hi_b, 1.0), (lo_b, -1.0)):
                idx = np.flatnonzero(ok[i])
                idx = idx[np.argsort(W[i, idx])]
                for w in at:
                    eye = np.eye(idx.size)
                    coef[i, idx] += sign * np.array([np.interp(w, W[i, idx], eye[m]) for m in range(idx.size)]) / at.size
            use = coef != 0
            value = float(np.sum(coef[use] * lnk[use]))
            var_terms = (coef[use] * lse[use]) ** 2
            var = float(var_terms.sum())
            dof = float(var ** 2 / np.sum(var_terms ** 2 / (npts[use] - 2))) if np.all(npts[use] > 2) else math.nan
            q = float(st.t.ppf((1 + stats.level()) / 2, dof)) if math.isfinite(dof) and dof > 0 else math.nan
            sd = math.sqrt(var)
            entry["log_k_ratio"] = stats.Estimate(value, sd, value - q * sd, value + q * sd, int(use.sum()),
                                                  "delta method on the fits' stderr, Welch-Satterthwaite t",
                                                  stats.level(), int(use.sum()), dof).to_dict()
            entry["at_channel_widths_m"] = [float(w) for w in at]
            pairs[key] = entry
    return pairs


def impulse_by_amplitude(betas_deg, dphi, impulse) -> dict[str, Any]:
    """The contact impulse over the first two periods at each joint amplitude, over the detuned starts.

    ``betas_deg`` (n_b,), degrees; ``dphi`` (n_d,), rad; ``impulse`` (n_b, n_d, n_phi0), N s: the same
    starts ``(dphi, phi0)`` at every beta.  The detuned starts are those with ``dphi != 0`` (every phi0);
    a failed run (NaN) is left out.  ``mean_impulse_Ns[beta]``: the mean over a beta's detuned starts (t
    interval, :func:`undulate.stats.mean`); ``steps["lo-hi"]["increase_Ns"]``, for each pair of consecutive
    betas: the mean over the detuned starts run at both of ``impulse(hi) - impulse(lo)``, paired (the same
    dphi and phi0 at both: the start's own share of the impulse cancels), t interval; ``n_starts``: the
    detuned starts a beta."""
    b = np.asarray(betas_deg, float).ravel()
    d = np.asarray(dphi, float).ravel()
    imp = np.asarray(impulse, float)
    if imp.ndim != 3 or imp.shape[:2] != (b.size, d.size):
        raise ParameterError("impulse", f"shaped (beta, dphi, phi0) = ({b.size}, {d.size}, n)", imp.shape)
    order = np.argsort(b)
    b, imp = b[order], imp[order]
    starts = imp[:, np.abs(d) > 1e-9, :].reshape(b.size, -1)  # (beta, detuned start)
    steps = {f"{lo:g}-{hi:g}": {"increase_Ns": stats.mean(starts[i + 1] - starts[i]).to_dict()}
             for i, (lo, hi) in enumerate(zip(b[:-1], b[1:]))}
    return {"betas_deg": b, "mean_impulse_Ns": {f"{v:g}": stats.mean(starts[i]).to_dict() for i, v in enumerate(b)},
            "steps": steps, "n_starts": int(starts.shape[1]),
            "starts": "dphi != 0 at every phi0, from dx0 = 0 in the impulse runs' channel; the same at every beta"}


def _release_summary(ds) -> dict[str, Any]:
    """Per release run: beta, d/2A, dF, failed, and :func:`release_response` (Estimate dicts)."""
    if "release_dx_period" not in ds or ds.sizes.get("release", 0) == 0:
        return {"runs": [], "sustain_frac": SUSTAIN_FRAC, "windows_periods": list(RELEASE_WINDOWS)}
    on, off = float(ds.attrs["release_force_onset_s"]), float(ds.attrs["release_force_offset_s"])
    t = ds["release_period_time"].values
    runs = []
    for i in range(ds.sizes["release"]):
        failed = bool(ds["release_failed"].values[i])
        r = release_response(ds["release_dx_period"].values[i], t, on, off) if not failed else {}
        runs.append({"beta_deg": float(ds["release_beta"].values[i]),
                     "d_over_2A": float(ds["release_d_over_2A"].values[i]),
                     "force_N": float(ds["release_force"].values[i]), "failed": failed,
                     **{k: v.to_dict() for k, v in r.items()}})
    return {"runs": runs, "sustain_frac": SUSTAIN_FRAC, "windows_periods": list(RELEASE_WINDOWS),
            "force_onset_s": on, "force_offset_s": off}


E = stats.Estimate.from_dict


def _impulse_linear(s: dict) -> Verdict:
    f = s["impulse_fit"]
    a, r2 = E(f["slope_Ns_per_rad"]), E(f["r2"])
    clean = E(f["r2_without_phase_scatter"])
    measured = (f"fit impulse = a|dphi| + b over {r2.n} |dphi|: a = {a:.3g} N s/rad, R^2 = {r2:.2f} ({clean:.2f} "
                f"with the common phases' scatter taken out of each |dphi|'s mean; {stats.interval_note(r2.level)})")
    value = {"slope_Ns_per_rad": f["slope_Ns_per_rad"], "r2": f["r2"],
             "r2_without_phase_scatter": f["r2_without_phase_scatter"]}
    if not r2.has_interval:
        return Verdict.none("no interval for R^2 (fewer than 3 dphi)", measured, value)
    return Verdict.of([r2.above(R2_MIN, "R^2"), a.above(0.0, "slope a (N s/rad)")], measured, value)


def _harmonic(s: dict) -> Verdict:
    med, low, high = s["median_fit_r2"], s["fit_r2_ci95_low_median"], s["fit_r2_ci95_high_median"]
    lv = float(s["fit_r2_level"])
    measured = (f"median R^2 of the {s['n_fits']} dF = k (dx - dx0) fits {med:.3f} "
                f"(medians of the bounds {low:.3f}, {high:.3f}; {stats.interval_note(lv)})")
    value = {"median_r2": med, "median_r2_low": low, "median_r2_high": high}
    if s["n_fits"] == 0 or not (np.isfinite(low) and np.isfinite(high)):
        return Verdict.none("no fit with an R^2 interval", measured, value)
    # the typical fit: the median R^2 with the medians of its bounds.  Each fit's interval rests on its
    # own points (forces), so more fits do not narrow it: the runs that would decide it are counted on
    # every point of the fits (more forces per fit), not on the number of fits; a fit's R^2 interval is a
    # bootstrap over its points at the expanded levels, so its quantile is t on the points per fit less one.
    per_fit = round(s["n_fit_points"] / s["n_fits"])
    typical = stats.Estimate(med, float("nan"), low, high, int(s["n_fit_points"]), "medians over the fits", lv,
                             per_fit, per_fit - 1 if per_fit >= 2 else float("nan"))
    return Verdict.of([typical.above(R2_MIN, "median R^2")], measured, value)


def _k_falls(s: dict) -> Verdict:
    rho = {b: E(v["spearman_k_vs_d"]) for b, v in s["per_beta"].items()}
    note = stats.interval_note(next(iter(rho.values())).level if rho else None)
    def shown(r: stats.Estimate) -> str:  # a bootstrap spread without an interval reads as a precision it lacks
        return f"{r:+.2f}" if r.has_interval or not r.finite else f"{r.value:+.2f} (no interval on {r.n} widths)"

    measured = f"Spearman rank correlation of k with d per beta ({note}): " + ", ".join(
        f"{b} deg: {shown(r)}" for b, r in rho.items())
    bare = [r for r in rho.values() if r.finite and not r.has_interval]
    if bare:
        measured += (f"; a rank correlation has an interval from {stats.rank_correlation_points(bare[0].level)} "
                     f"widths at this level (with fewer, too few orderings exist for any data to exclude rho = 0)")
    value = {"spearman_rho": {b: r.to_dict() for b, r in rho.items()},
             "k_N_per_m": {b: _k_curve(v, "d_over_2A", s["d_over_2A"]) for b, v in s["per_beta"].items()}}
    if not rho or any(not r.finite for r in rho.values()):
        return Verdict.none("fewer than 3 stiffnesses for some beta", measured, value)
    return Verdict.of([r.below(0.0, f"Spearman rho at beta = {b} deg") for b, r in rho.items()], measured, value)


def _k_curve(per_beta: dict, x_key: str, x) -> dict[str, list]:
    """One beta's fitted stiffnesses for its evidence figure: ``x_key`` (one x per d/2A), ``k_N_per_m`` and
    the bounds of its interval (NaN where no fit)."""
    k = [E(e) for e in per_beta["stiffness_N_per_m"]]
    return {x_key: [float(v) for v in np.asarray(x, float).ravel()], "k_N_per_m": [e.value for e in k],
            "k_low_N_per_m": [e.low for e in k], "k_high_N_per_m": [e.high for e in k]}


def _collapse(s: dict) -> Verdict:
    a, m = E(s["collapse_rms_log10k_vs_d_over_2A"]), E(s["collapse_rms_log10k_vs_d_m"])
    measured = (f"scatter of log10 k about one curve: {a:.2f} decades against d/2A, {m:.2f} against d "
                f"({stats.interval_note(a.level)})")
    value = {"against_d_over_2A": a.to_dict(), "against_d": m.to_dict()}
    if not (a.finite and m.finite):
        return Verdict.none("too few stiffnesses for the collapse fit", measured, value)
    return Verdict.of([stats.Check.apart(m, a, "scatter against d vs against d/2A (decades)")], measured, value)


def _dx0_below(s: dict) -> Verdict:
    d = s["dx0_vs_model"]
    below, not_above = E(d["share_below"]), E(d["share_not_above"])
    diff = E(d["mean_difference_over_lambda"])
    measured = (f"of {d['n_fits']} fits of dF = k (dx - dx0), dx0 lies below the compatibility model in "
                f"{d['n_below']}, above it in {d['n_above']}, unresolved in {d['n_unresolved']} (each by its "
                f"interval): share below {below:.2f}, share not above {not_above:.2f}; mean dx0 - model "
                f"{diff:+.3f} lambda ({stats.interval_note(below.level)})")
    value = {k: d[k] for k in ("share_below", "share_not_above", "mean_difference_over_lambda", "n_fits")}
    if d["n_fits"] == 0:
        return Verdict.none("no fit with a dx0 interval", measured, value)
    if below.low > 0.5:
        check = stats.Check(True, f"share of fits below the model {below:.2f} above 1/2")
    elif not_above.high < 0.5:
        check = stats.Check(False, f"share of fits not above the model {not_above:.2f} below 1/2")
    else:
        check = stats.Check(None, f"share below {below:.2f} and share not above {not_above:.2f} straddle 1/2")
    return Verdict.of([check], measured, value)


def _sustained(s: dict) -> Verdict:
    rel = s["release"]
    frac = float(rel["sustain_frac"])
    runs = [r for r in rel["runs"] if not r["failed"]]
    checks, parts = [], []
    value: dict[str, Any] = {"run": [], "separation_over_lambda": [], "held_drift_3T_over_D": [],
                             "way_back_over_D": [], "sustain_frac": frac}
    for r in runs:
        at = f"beta {r['beta_deg']:g} deg, d/2A {r['d_over_2A']:g}, dF {r['force_N']:g} N"
        sep, drift, back = E(r["separation"]), E(r["drift_3T"]), E(r["back"])
        checks.append(sep.above(0.0, f"separation D/lambda ({at})"))
        nan = stats.Estimate(math.nan)
        rd, rb = ((drift.scaled(1 / sep.value), back.scaled(1 / sep.value)) if sep.finite and sep.value > 0
                  else (nan, nan))
        if sep.finite and sep.value > 0:  # D's own interval is far narrower than theirs: its value scales them
            checks.append(rd.within(-frac, frac, f"held drift over 3T / D ({at})"))
            checks.append(rb.above(frac, f"way back after removal / D ({at})"))
        parts.append(f"{at}: D = {sep:.3g} lambda, held drift over 3T = {rd:+.2g} D, way back {rb:.2g} D")
        for k, e in (("separation_over_lambda", sep), ("held_drift_3T_over_D", rd), ("way_back_over_D", rb)):
            value[k].append(e.to_dict())
        value["run"].append(at)
    n_failed = len(rel["runs"]) - len(runs)
    measured = "; ".join(parts) + (f"; {n_failed} run(s) failed" if n_failed else "")
    if not runs:
        return Verdict.none("no release run", measured, value)
    return Verdict.of(checks, measured, value)


def _k_grows_with_amplitude(s: dict) -> Verdict:
    pairs = s["k_by_amplitude_at_width"]
    ratios = {key: E(p["log_k_ratio"]) for key, p in pairs.items()}
    note = stats.interval_note(next(iter(ratios.values())).level if ratios else None)
    parts = []
    for key, p in pairs.items():
        r = ratios[key]
        ws = p["at_channel_widths_m"]
        span = (f"over W {1e3 * min(ws):.0f}-{1e3 * max(ws):.0f} mm ({len(ws)} widths)" if ws
                else "no common width")
        parts.append(f"beta {p['beta_high_deg']:g} vs {p['beta_low_deg']:g} deg: mean ln(k_hi / k_lo) = {r:+.2f} {span}")
    measured = f"k at a fixed channel width W, larger amplitude against smaller ({note}): " + "; ".join(parts)
    value = {"log_k_ratio": {key: r.to_dict() for key, r in ratios.items()},
             "k_N_per_m": {b: _k_curve(v, "channel_width_m", v["channel_width_m"]) for b, v in s["per_beta"].items()}}
    compared = {key: r for key, r in ratios.items() if r.finite}
    if not compared:
        return Verdict.none("no pair of betas has fitted stiffnesses at a common channel width", measured, value)
    return Verdict.of([r.above(0.0, f"mean ln(k_hi / k_lo), betas {key} deg") for key, r in compared.items()],
                      measured, value)


def _impulse_grows_with_amplitude(s: dict) -> Verdict:
    d = s["impulse_by_amplitude"]
    means = {b: E(v) for b, v in d["mean_impulse_Ns"].items()}
    steps = {key: E(v["increase_Ns"]) for key, v in d["steps"].items()}
    note = stats.interval_note(next(iter(means.values())).level if means else None)
    measured = (f"contact impulse over the first two periods, mean over {d['n_starts']} detuned starts a beta "
                f"({note}): " + ", ".join(f"beta {b} deg {m:.3g} N s" for b, m in means.items())
                + "; mean paired increase a step up in beta: "
                + (", ".join(f"{key} deg {e:+.3g} N s" for key, e in steps.items()) or "none"))
    value = {"mean_impulse_Ns": {b: m.to_dict() for b, m in means.items()},
             "steps": {key: {"increase_Ns": e.to_dict()} for key, e in steps.items()}}
    if len(means) < 2:
        return Verdict.none("impulse runs at fewer than two joint amplitudes", measured, value)
    if any(not e.has_interval for e in steps.values()):
        return Verdict.none("a step in beta without an interval (fewer than 2 detuned starts run at both)",
                            measured, value)
    return Verdict.of([e.above(0.0, f"mean impulse increase, beta {key} deg") for key, e in steps.items()],
                      measured, value)


AMPLITUDE_CLAIM = "at a fixed channel width the cohesion stiffness k grows with the gait amplitude"
IMPULSE_AMPLITUDE_CLAIM = "the contact impulse over the first two periods grows with the gait amplitude"
DX0_CLAIM = "the neutral offset dx0 lies below the compatibility model's"
RELEASE_CLAIM = "under a small dF the pair holds a separation, and goes back once the force is removed"

CLAIMS = (
    Claim("the contact force over the first two periods grows linearly with |dphi|",
          "cumulative contact forces over the first two periods are linearly dependent on dphi",
          f"the lower 95 % bound of R^2 of impulse = a|dphi| + b is >= {R2_MIN} and that of a is > 0 (fails if "
          f"the upper bound of R^2 is below {R2_MIN} or that of a below 0; undecided if an interval straddles "
          "its bound)", _impulse_linear,
          quote=(r"The cumulative contact forces over the first two periods of oscillation are linearly dependent "
                 r"on the detuning phase difference, $\Delta \phi$, between the two swimmers "
                 r"(Fig.~\ref{fig:potential}a)."),
          where="Sec. III.G, Fig. 10a", bands={"r2": (R2_MIN, None), "slope_Ns_per_rad": (0.0, None)},
          reads=("impulse",)),
    Claim("dF against dx is linear (a harmonic well around compatibility)",
          "a linear relationship between the applied force and the steady separation",
          f"the median over (beta, d/2A) of the lower 95 % bound of R^2 of dF = k (dx - dx0) is >= {R2_MIN} "
          f"(fails if the median of the upper bounds is below {R2_MIN}; undecided between)", _harmonic,
          quote=(r"We observed a linear relationship between the applied force and the steady state separation "
                 r"suggesting that compatible configurations act like a simple harmonic potential "
                 r"(Fig.~\ref{fig:potential}c)."),
          where="Sec. III.G, Fig. 10c", bands={"median_r2": (R2_MIN, None)}, reads=("force",)),
    Claim("the cohesion stiffness k falls as the channel widens",
          "stiffness decreases with increasing wall width",
          "the bootstrap 95 % interval of Spearman's rho of k with d lies below 0 for every beta (fails if one "
          "lies wholly above 0; undecided if one straddles 0, as it can with 3-9 widths)", _k_falls,
          quote=(r"We found that the cohesion stiffness of the compatible state decreases with increasing wall "
                 r"width and becomes increasingly large as the confining wall spacing decreases "
                 r"(Fig.~\ref{fig:potential}d)."),
          where="Sec. III.G, Fig. 10d", bands={"spearman_rho": (None, 0.0)}, reads=("force",),
          evidence=_figures.stiffness_against_confinement),
    Claim("stiffness curves for different amplitudes collapse when d is scaled by 2A",
          "when we normalise the wall width by gait amplitude the stiffness curves follow a similar trend",
          "the bootstrap 95 % interval of the scatter of log10 k about one quadratic against d/2A lies wholly "
          "below that against d (fails if wholly above; undecided if they overlap)", _collapse,
          quote=(r"However, when we normalize the wall width by gait amplitude the stiffness curves follow a "
                 r"similar trend (Fig.~\ref{fig:potential}d)."),
          where="Sec. III.G, Fig. 10d", reads=("force",)),
    Claim(AMPLITUDE_CLAIM,
          "larger amplitudes increase the stiffness of separation for a fixed wall width",
          "for each pair of betas (each its own amplitude A, so one d/2A is a different channel width W per "
          "beta), ln k of each is interpolated linearly in W between its fitted widths, at the fitted widths "
          "of either that lie within both betas' fitted ranges; the mean over them of ln(k of the larger A) - "
          "ln(k of the smaller A) has a 95 % t interval from the fits' own standard errors (delta method, "
          "Welch-Satterthwaite degrees of freedom).  Holds if that interval lies above 0 for every pair with a "
          "common width; fails if one lies wholly below 0; undecided if one straddles 0; no result if no "
          "pair shares a width (pairs without one are listed, not judged).  Only fits enter: a width where no "
          "rung held (k = 0, no cohesion) or with under 3 held rungs is skipped", _k_grows_with_amplitude,
          quote=r"Thus, larger amplitudes increase the stiffness of separation for a fixed wall width.",
          where="Sec. III.G, Fig. 10d", bands={"log_k_ratio": (0.0, None)}, reads=("force",),
          evidence=_figures.stiffness_at_fixed_width),
    Claim(DX0_CLAIM,
          "the neutral region dx0 likely lies below the compatibility model's prediction (three-link geometry)",
          "each (beta, d/2A) fit's dx0 is below the sinusoid model's (its bootstrap interval wholly below), above "
          "(wholly above) or unresolved.  Holds if the Clopper-Pearson interval of the share of fits below lies "
          "above 1/2; fails if that of the share not above (below or unresolved) lies below 1/2; undecided "
          "between.  'likely' is read as a tendency over the confinements (most fits), not every one; the "
          "cause the paper offers (the three-link geometry) is not judged", _dx0_below,
          quote=(r"The neutral region, $\delta x_0$, likely lies below the prediction from the compatibility model "
                 r"due to the three-link geometry of the swimmers."),
          where="Sec. III.G, Fig. 10d", bands={"share_below": (0.5, None), "share_not_above": (0.5, None)},
          reads=("force",)),
    Claim(RELEASE_CLAIM,
          "the swimmers separate by dx under dF, and for small dF the position is sustained until the force "
          "is removed",
          f"in every release run (dF = {RELEASE_FORCE_N:g} N, the smallest force both modes apply): the "
          f"separation D the force makes has its Welch interval above 0; held, the drift of dx over 3 periods "
          f"(line through the last {RELEASE_WINDOWS[1]} period means before the removal, t interval) lies "
          f"within +-{SUSTAIN_FRAC:g} D; released, the way back (held minus the last {RELEASE_WINDOWS[2]} "
          f"period means) exceeds {SUSTAIN_FRAC:g} D.  Fails if one interval lies wholly outside its region; "
          "undecided if one straddles", _sustained,
          quote=(r"We observed that the swimmers separated by a longitudinal distance $\delta x$ in the presence "
                 r"of this force and for small $\delta F$ this position was sustained until the force was removed "
                 r"(Fig.~\ref{fig:potential}b)."),
          where="Sec. III.G, Fig. 10b",
          bands={"separation_over_lambda": (0.0, None), "held_drift_3T_over_D": (-SUSTAIN_FRAC, SUSTAIN_FRAC),
                 "way_back_over_D": (SUSTAIN_FRAC, None)}),
    Claim(IMPULSE_AMPLITUDE_CLAIM,
          "increasing amplitude caused larger contact force interactions between swimmers",
          "the contact impulse over the first two periods (the impulse runs: pairs from dx0 = 0 in the 0.13 m "
          "channel) at each of the plan's joint amplitudes beta, over the same detuned starts (dphi != 0, every "
          "phi0); for each step up in beta (consecutive betas), the mean over the starts of the paired "
          "difference impulse(larger beta) - impulse(smaller beta) at the same (dphi, phi0), with its 95 % t "
          "interval.  Holds if every step's interval lies above 0; fails if one lies wholly below 0; undecided "
          "otherwise (no result with fewer than two betas).  Only the contact-force half of the sentence is "
          "judged: the 'larger projection of interaction surface along the longitudinal direction' is not "
          "measured", _impulse_grows_with_amplitude,
          quote=(r"Increasing amplitude caused larger contact force interactions between swimmers and a larger "
                 r"projection of interaction surface along the longitudinal direction."),
          where="Sec. III.G", bands={"increase_Ns": (0.0, None)}, reads=("impulse", AMPLITUDE_PART),
          evidence=_figures.impulse_by_amplitude),
)


def figure(ds):
    from ..plotting.potential import plot_potential

    return plot_potential(ds)


FULL_LOOKS = ((8, 4, 8, 1), (4, 2, 4, 1), (2, 1, 4, 1), (1, 1, 1, 1))
"""Full mode's looks: strides over the cap's (impulse dphi, common phases, d/2A, forces): 10 dphi x 2
phases and 3 x 3 x 5 force runs; 19 x 4 and 3 x 5 x 5; 37 x 8 and 3 x 5 x 5; 73 x 8 and 3 x 17 x 5.  The
force ladder is never thinned: a fit and a holding force need all its rungs.  The impulse strides size
the impulse R^2 (~57 dphi at 97 %); the cap's 17 d/2A per beta are what a rank correlation of k with d
needed for an interval on the earlier grids (~12-26 widths), within the band where the pair touches
(module docstring, "Design")."""


def stages(quick: bool) -> tuple[PotentialPlan, ...]:
    """The plan in looks (:mod:`._stages`).  Quick: the impulse grid (dphi and common phases) thinned,
    the 3 x 5 force grid kept (a fit needs them).  Full: :data:`FULL_LOOKS`."""
    p = plan(quick)
    looks = ([(k, k, 1, 1) for k in strides(quick)] if quick else FULL_LOOKS)
    s = AMPLITUDE_DPHI_STRIDE[quick]  # the impulse runs at the other amplitudes: each look's within its impulse grid
    return tuple(PotentialPlan(p.impulse_dphi[::a], p.betas_deg, p.d_over_2A[::c], p.forces_N[::d], p.duration_s,
                               impulse_phi0=p.impulse_phi0[::b], release=p.release,
                               amplitude_betas_deg=p.amplitude_betas_deg, amplitude_dphi=p.amplitude_dphi[::max(a // s, 1)],
                               amplitude_phi0=p.amplitude_phi0[::b]) for a, b, c, d in looks)


register(Study(
    name="potential", paper_figure="10", plan=plan, stages=stages, dataset=dataset, summary=summary, claims=CLAIMS,
    figure=figure,
    description="Contact impulse over the first two periods against dphi; equal and opposite "
                "forces on a settled dphi = 0 pair: dF = k (dx - dx0) per d/2A and beta, with "
                "the compatibility model's dx0."))
