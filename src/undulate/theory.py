r"""Closed-form gait compatibility of sinusoidal swimmers, and packing.

Pure, vectorised numpy functions (arguments broadcast against each other).
SI units: lengths in m, angles in rad, times in s.

Conventions (those of :mod:`undulate.params`)
---------------------------------------------
A swimmer's body is the travelling wave ``y = A sin(2 pi x / lambda - omega t
+ phi)``, moving toward **+x**.  For two lateral neighbours ``a`` (lower y)
and ``b`` (upper y)::

    dx = x_b - x_a,   dphi = phi_b - phi_a,   dy = y_b - y_a > 0

    y_a(x, t) = A sin(k x - omega t + phi_a)
    y_b(x, t) = A sin(k (x - dx) - omega t + phi_a + dphi) + dy,  k = 2 pi / lambda

(paper Eqs. (sin1), (sin2)).  Everything below depends on the configuration
only through the **phase mismatch**

    psi = wrap(dphi - k dx)  in (-pi, pi]   (:func:`wrap_phase`)

because ``y_b - y_a = dy + 2 A sin(psi / 2) cos(theta + psi / 2)`` with
``theta = k x - omega t + phi_a``.  Hence the smallest gap between the two
curves, over all x and t, is ``dy - 2 A |sin(psi / 2)|``, and

* compatibility (paper Eq. (compatibility)): ``psi = 0``, i.e.
  ``dx = lambda (dphi / 2 pi + n)`` for any integer branch ``n``;
* full compatibility region (paper Eq. (fullcompatibility)): the curves never
  cross iff ``|psi| <= 2 arcsin(|dy| / 2A)``; every ``dphi`` is allowed once
  ``|dy| >= 2A``;
* required lateral separation (paper Eq. (sep), generalised to dx != 0):
  ``dy_min = 2 A |sin(psi / 2)|``.

Only ``|dy|`` matters: swapping which swimmer is called ``a`` flips the signs
of ``dx``, ``dphi`` and ``psi`` together, leaving ``|sin(psi / 2)|`` alone.

The standing wave (``xi = 0``) has ``lambda = inf``: then ``k = 0`` and
``psi = wrap(dphi)``, so the region and the separation are still defined
(they no longer depend on dx) while the compatible dx itself is not (NaN).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .errors import ParameterError

__all__ = [
    "wrap_phase",
    "phase_mismatch",
    "compatible_dx",
    "compatibility_residual",
    "max_phase_mismatch",
    "is_compatible",
    "compatible_dx_interval",
    "min_lateral_separation",
    "tangent_contact_x",
    "contact_push_direction",
    "sinusoid_basin_displacement",
    "packing_spacing",
    "packing_density",
    "DensityEstimate",
    "packing_density_mc",
    "channel_width_m",
    "confinement_d_over_2A",
    "lateral_clearance_m",
    "neutral_offset_m",
    "walled_packing_density",
]

TWO_PI = 2.0 * np.pi


# ----------------------------------------------------------------- validation
def _positive(name: str, value, unit: str, allow_inf: bool = False) -> np.ndarray:
    v = np.asarray(value, dtype=float)
    bad = ~(v > 0) | (np.isinf(v) & (not allow_inf))
    if np.any(bad):
        allowed = f"> 0 {unit}" + (" (inf allowed)" if allow_inf else ", finite")
        raise ParameterError(name, allowed, value)
    return v


def _wavenumber(wavelength_m) -> np.ndarray:
    """k = 2 pi / lambda, rad/m; 0 for the standing wave (lambda = inf)."""
    lam = _positive("wavelength_m", wavelength_m, "m", allow_inf=True)
    return TWO_PI / lam


# -------------------------------------------------------------- compatibility
def wrap_phase(angle_rad):
    """Wrap an angle (rad) into ``(-pi, pi]``: the package's one wrapping convention.

    Half a period reads ``+pi`` (never ``-pi``), as the paper writes its phase
    differences (``dphi in [-pi, pi]`` with the grids' ends at ``+pi``), so a pair
    started at ``dphi = pi`` is reported at ``pi``.  Every wrapped angle in the
    package goes through here (:func:`undulate.observables.wrap_angle` is this
    function).  ``-((pi - a) mod 2 pi - pi)`` keeps the observables' values bit
    for bit as they were (including ``wrap_phase(0.0) == -0.0``); the theory's
    own results were ``[-pi, pi)`` before and differ only at ``psi = -pi``
    (now ``+pi``: every function of psi here is even or equal at +-pi there)
    and by at most 2 ulp of pi elsewhere.
    """
    return -((np.pi - np.asarray(angle_rad, dtype=float)) % TWO_PI - np.pi)


def phase_mismatch(dphi_rad, dx_m, wavelength_m):
    """Phase mismatch ``psi = wrap(dphi - 2 pi dx / lambda)``, rad, in ``(-pi, pi]``.

    The left side of paper Eq. (fullcompatibility), wrapped.  ``dphi_rad``:
    phase difference phi_b - phi_a, rad; ``dx_m``: x_b - x_a, m;
    ``wavelength_m``: lambda, m (inf allowed: then ``psi = wrap(dphi)``).
    ``psi = 0`` is compatibility; ``psi > 0`` means the nearest compatible
    dx is larger than ``dx`` (b lags behind its compatible place).
    """
    k = _wavenumber(wavelength_m)
    return wrap_phase(np.asarray(dphi_rad, dtype=float) - k * np.asarray(dx_m, dtype=float))


def compatible_dx(dphi_rad, wavelength_m, branch=0):
    """Compatible longitudinal offset ``dx = lambda (dphi / 2 pi + n)``, m.

    Paper Eq. (compatibility), with the branch ``n`` (integer) made explicit:
    branches repeat every wavelength.  ``dphi_rad``: phi_b - phi_a, rad;
    ``wavelength_m``: lambda, m.  For the standing wave (``lambda = inf``)
    there is no compatible dx: returns NaN (the region is then independent of
    dx, see :func:`is_compatible`).
    """
    lam = _positive("wavelength_m", wavelength_m, "m", allow_inf=True)
    u = np.asarray(dphi_rad, dtype=float) / TWO_PI + np.asarray(branch, dtype=float)
    with np.errstate(invalid="ignore"):
        return np.where(np.isinf(lam), np.nan, lam * u)


def compatibility_residual(dx_m, dphi_rad, wavelength_m):
    """Signed distance (m) of an observed dx from the **nearest** compatible branch.

    ``r = dx - lambda (dphi / 2 pi + n*)`` with ``n*`` chosen so that
    ``r`` lies in ``(-lambda / 2, lambda / 2]``.  Equivalently
    ``r = -lambda psi / 2 pi`` with psi the :func:`phase_mismatch` (up to the
    half-open end).  ``dx_m``: x_b - x_a, m; ``dphi_rad``: phi_b - phi_a, rad;
    ``wavelength_m``: lambda, m.  NaN for the standing wave (lambda = inf),
    which has no compatible dx.
    """
    lam = _positive("wavelength_m", wavelength_m, "m", allow_inf=True)
    with np.errstate(invalid="ignore"):
        u = np.asarray(dx_m, dtype=float) / lam - np.asarray(dphi_rad, dtype=float) / TWO_PI
        r = lam * (u - np.ceil(u - 0.5))
        return np.where(np.isinf(lam), np.nan, r)


def max_phase_mismatch(dy_m, amplitude_m):
    """Half-width of the compatible band in psi: ``2 arcsin(min(|dy| / 2A, 1))``, rad.

    Right side of paper Eq. (fullcompatibility).  ``dy_m``: lateral offset
    y_b - y_a, m; ``amplitude_m``: A, m.  Equals pi once ``|dy| >= 2A``
    (every phase allowed); 0 at ``dy = 0`` (only the equality).
    """
    a = _positive("amplitude_m", amplitude_m, "m")
    s = np.minimum(np.abs(np.asarray(dy_m, dtype=float)) / (2.0 * a), 1.0)
    return 2.0 * np.arcsin(s)


def is_compatible(dphi_rad, dx_m, dy_m, amplitude_m, wavelength_m, atol_rad: float = 1e-9):
    """True where two sinusoids never cross, paper Eq. (fullcompatibility).

    ``|wrap(dphi - 2 pi dx / lambda)| <= 2 arcsin(min(|dy| / 2A, 1))``, i.e.
    ``min over x, t of (y_b - y_a) >= 0`` for ``dy > 0``.  Tangential contact
    (the boundary) counts as compatible, within ``atol_rad`` of phase
    mismatch so that rounding does not exclude the ``dy = 0`` line itself.
    ``dphi_rad``: phi_b - phi_a, rad; ``dx_m``: x_b - x_a, m; ``dy_m``:
    y_b - y_a, m; ``amplitude_m``: A, m; ``wavelength_m``: lambda, m (inf
    allowed).
    """
    psi = phase_mismatch(dphi_rad, dx_m, wavelength_m)
    return np.abs(psi) <= max_phase_mismatch(dy_m, amplitude_m) + atol_rad


def compatible_dx_interval(dphi_rad, dy_m, amplitude_m, wavelength_m, branch=0):
    """Allowed dx range ``(lo, hi)``, m, around compatible branch ``n``.

    From paper Eq. (fullcompatibility)::

        dx in lambda (dphi / 2 pi + n) -/+ (lambda / pi) arcsin(min(|dy| / 2A, 1))

    The boundary of the region is ``lo`` and ``hi``; at ``dy = 0`` both equal
    :func:`compatible_dx`; once ``|dy| >= 2A`` the half-width is lambda / 2 and
    neighbouring branches' intervals touch (every dx allowed).  For the
    standing wave (lambda = inf) returns ``(-inf, inf)`` where the phase is
    allowed (``|wrap(dphi)| <= 2 arcsin(...)``) and ``(nan, nan)`` elsewhere.
    """
    lam = _positive("wavelength_m", wavelength_m, "m", allow_inf=True)
    half_psi = max_phase_mismatch(dy_m, amplitude_m)
    dphi = np.asarray(dphi_rad, dtype=float)
    with np.errstate(invalid="ignore"):
        centre = lam * (dphi / TWO_PI + np.asarray(branch, dtype=float))
        half = lam * half_psi / TWO_PI
        lo, hi = centre - half, centre + half
        standing = np.isinf(lam)
        ok = np.abs(wrap_phase(dphi)) <= half_psi
        lo = np.where(standing, np.where(ok, -np.inf, np.nan), lo)
        hi = np.where(standing, np.where(ok, np.inf, np.nan), hi)
    return lo, hi


def min_lateral_separation(dphi_rad, dx_m, amplitude_m, wavelength_m):
    """Smallest ``dy`` (m) at which the sinusoids do not cross: ``2 A |sin(psi / 2)|``.

    Paper Eq. (sep) (written there for dx = 0 as ``dy / 2A = sin(dphi / 2)``),
    here for any dx through the mismatch ``psi = dphi - 2 pi dx / lambda``.
    ``dphi_rad``: rad; ``dx_m``: m; ``amplitude_m``: A, m; ``wavelength_m``:
    lambda, m.  Lies in ``[0, 2A]``.
    """
    a = _positive("amplitude_m", amplitude_m, "m")
    psi = phase_mismatch(dphi_rad, dx_m, wavelength_m)
    return 2.0 * a * np.abs(np.sin(psi / 2.0))


# ---------------------------------------------------------- contact and basins
def _tangent_phase(psi):
    """Wave phase theta* = k x* - omega t + phi_a of the closest approach.

    ``y_b - y_a = dy + 2A sin(psi/2) cos(theta + psi/2)`` is smallest where
    ``cos(theta + psi/2) = -sign(sin(psi/2))``:  theta* = pi - psi/2 for
    psi > 0, theta* = -psi/2 for psi < 0 (undefined at psi = 0, where the two
    curves are parallel copies).
    """
    return np.where(psi > 0, np.pi - psi / 2.0, np.where(psi < 0, -psi / 2.0, np.nan))


def tangent_contact_x(t_s, dx_m, dphi_rad, wavelength_m, angular_frequency_rad_s, phi_a_rad=0.0):
    r"""Where two sinusoids first touch: the tangent contact point ``x*(t)``, m, in ``[0, lambda)``.

    At the tangent point ``y_a = y_b`` and ``y_a' = y_b'`` (the conditions that
    give paper Eq. (fullcompatibility)); it is the closest approach of the two
    curves for any ``dy``, and repeats every lambda.  Under our conventions::

        x*(t) = dx / 2 - lambda dphi / 4 pi + lambda (omega t - phi_a) / 2 pi
                + (lambda / 2) [psi > 0]        (mod lambda)

    with ``psi`` the :func:`phase_mismatch`.  The paper prints
    ``x* = Delta / 2 pi - dphi lambda / 4 pi - omega t``; our ``dx/2`` and
    ``-lambda dphi / 4 pi`` terms match its first two, and the point travels
    with the wave at ``+lambda omega / 2 pi`` (toward +x; the paper's
    ``-omega t`` lacks the ``lambda / 2 pi`` and has the sign of a wave
    travelling toward -x).  The extra half wavelength picks the trough side:
    for psi > 0 the curves meet where a descends (slope < 0), for psi < 0
    where it ascends.

    ``t_s``: time, s; ``dx_m``: m; ``dphi_rad``: rad; ``wavelength_m``:
    lambda, m; ``angular_frequency_rad_s``: omega, rad/s; ``phi_a_rad``: phase
    of the lower swimmer, rad.  NaN where ``psi = 0`` (parallel curves, no
    single point) or lambda = inf (flat curves).
    """
    lam = _positive("wavelength_m", wavelength_m, "m", allow_inf=True)
    psi = phase_mismatch(dphi_rad, dx_m, lam)
    theta = _tangent_phase(psi)
    with np.errstate(invalid="ignore"):
        x = lam * (theta + np.asarray(angular_frequency_rad_s, float) * np.asarray(t_s, float)
                   - np.asarray(phi_a_rad, float)) / TWO_PI
        return np.where(np.isinf(lam), np.nan, np.mod(x, lam))


def contact_push_direction(dx_m, dphi_rad, wavelength_m):
    """Sign (-1, 0, +1) in which contact at the tangent point drives ``dx``.

    The contact force is along the common normal ``n = (-y', 1) / sqrt(1 +
    y'^2)`` (pointing from a to b), so it pushes b by ``-y'`` and a by ``+y'``
    along x: ``d(dx)/dt ~ -2 y'(x*)``, with the common slope
    ``y'(x*) = A k cos(theta*)``.  Substituting theta* gives
    ``sign(d dx / dt) = sign(psi)``: contact always pushes toward the nearest
    compatible branch.  0 at ``psi = 0`` (compatible) and ``psi = -pi``
    (slope 0 at contact: a purely lateral push, the unstable point between
    two basins), and for the standing wave (flat curves).
    """
    k = _wavenumber(wavelength_m)
    psi = phase_mismatch(dphi_rad, dx_m, wavelength_m)
    cos_t = np.cos(_tangent_phase(psi))
    slope_over_A = k * np.where(np.abs(cos_t) < 1e-12, 0.0, cos_t)  # y'(x*) / A, 1/m
    return np.nan_to_num(-np.sign(slope_over_A), nan=0.0) + 0.0


def sinusoid_basin_displacement(dx0_m, dphi_rad, amplitude_m, wavelength_m, dy_m=0.0,
                                target: str = "line"):
    """Longitudinal displacement ``dx_f - dx0`` (m) that contact imposes on two sinusoids.

    The paper's sinusoidal basin model (section "Compatible configurations
    have a broad basin of attraction", Fig. 8b right): the amplitude of two
    infinitely long sinusoids (paper Eqs. (sin1), (sin2)) at fixed lateral
    offset ``dy`` grows from 0 to ``amplitude_m``.

    1. If ``|psi0| <= 2 arcsin(|dy| / 2A)`` the curves never touch: 0.
    2. Otherwise they first touch at the tangent point
       (:func:`tangent_contact_x`), whose normal pushes dx in the direction
       :func:`contact_push_direction` = ``sign(psi0)``, i.e. toward the
       nearest compatible branch; the push continues as the amplitude grows.
    3. ``target="line"`` (the paper): the pair ends on "the large amplitude
       compatibility condition" Eq. (compatibility), the nearest branch in
       the push direction, so ``dx_f - dx0 = lambda psi0 / 2 pi =
       -compatibility_residual(dx0)``.  ``target="boundary"``: the
       quasi-static alternative, stopping where contact ends at the final
       amplitude, ``|psi_f| = 2 arcsin(|dy| / 2A)``.

    Basins are bands ``|psi| < pi`` around each branch: their boundaries
    ``dx = lambda (dphi / 2 pi + n + 1/2)`` have the compatibility slope (as
    the paper notes).  On a boundary (``psi = -pi``) the push is purely
    lateral and the displacement is 0.  The standing wave (lambda = inf) has
    flat curves and no longitudinal push: 0.

    ``dx0_m``: initial x_b - x_a, m; ``dphi_rad``: phi_b - phi_a, rad;
    ``amplitude_m``: final A, m; ``wavelength_m``: lambda, m; ``dy_m``:
    y_b - y_a, m.
    """
    if target not in ("line", "boundary"):
        raise ParameterError("target", "'line' or 'boundary'", target)
    lam = _positive("wavelength_m", wavelength_m, "m", allow_inf=True)
    psi0 = phase_mismatch(dphi_rad, dx0_m, lam)
    half = max_phase_mismatch(dy_m, amplitude_m)
    touches = ~is_compatible(dphi_rad, dx0_m, dy_m, amplitude_m, lam)
    direction = contact_push_direction(dx0_m, dphi_rad, lam)
    psi_f = direction * half if target == "boundary" else 0.0
    with np.errstate(invalid="ignore"):
        shift = lam * np.abs(psi0 - psi_f) / TWO_PI * direction
    return np.where(touches & np.isfinite(lam), np.nan_to_num(shift), 0.0)


# -------------------------------------------------------------------- packing
def _phi_max(phi_max_rad) -> np.ndarray:
    p = np.asarray(phi_max_rad, dtype=float)
    if np.any(~((p >= 0) & (p <= TWO_PI))):
        raise ParameterError("phi_max_rad", "in [0, 2 pi] rad", phi_max_rad)
    return p


def packing_spacing(phi_max_rad):
    r"""Expected required lateral gap between neighbours, ``y~ / 2A`` (dimensionless).

    Paper Eq. (packing; the lines before Eq. (rho_tilde))::

        y~ / 2A = E |sin(D / 2)| = (4 / phi_max^2) (phi_max - 2 sin(phi_max / 2))

    where ``D = |phi_i - phi_j|`` for two phases drawn uniformly from
    ``[0, phi_max]`` has the triangular pdf ``(2 / phi_max)(1 - D / phi_max)``
    and ``2A |sin(D / 2)|`` is the separation Eq. (sep) needed at dx = 0.
    ``phi_max_rad`` in [0, 2 pi] rad; small phi_max uses the series
    ``phi/6 - phi^3/480`` (0 at phi_max = 0).  Increasing on [0, 2 pi].
    """
    p = _phi_max(phi_max_rad)
    small = p < 1e-3
    ps = np.where(small, 1.0, p)
    exact = 4.0 / ps**2 * (ps - 2.0 * np.sin(ps / 2.0))
    series = p / 6.0 - p**3 / 480.0
    return np.where(small, series, exact)


def packing_density(phi_max_rad, w_over_2A):
    """Normalised lateral density ``rho~ = 2AN/Y = 1 / (y~/2A + w/2A)``, paper Eq. (rho_tilde).

    ``phi_max_rad``: phase spread, rad in [0, 2 pi]; ``w_over_2A``: body
    width over peak-to-peak amplitude, >= 0.  The density at which N
    swimmers with phases uniform in [0, phi_max] just fit without contact,
    in expectation (Y = N y~ + N w).  ``rho~ -> 2A / w`` as phi_max -> 0.
    Larger phase spread needs larger spacing, so rho~ decreases with phi_max.
    """
    w = np.asarray(w_over_2A, dtype=float)
    if np.any(~(w >= 0)) or np.any(np.isinf(w)):
        raise ParameterError("w_over_2A", ">= 0, finite", w_over_2A)
    with np.errstate(divide="ignore", over="ignore"):
        return 1.0 / (packing_spacing(phi_max_rad) + w)


class DensityEstimate(NamedTuple):
    """A Monte-Carlo estimate of rho~ and its standard error (both dimensionless)."""

    mean: np.ndarray
    stderr: np.ndarray


def packing_density_mc(phi_max_rad, w_over_2A, n_swimmers: int = 50, n_samples: int = 2000,
                       seed: int = 0, *, closure: str = "periodic",
                       estimator: str = "ratio_of_means") -> DensityEstimate:
    """Monte-Carlo estimate of the compatible packing density rho~ (paper Fig. 7b, red).

    Each sample draws ``n_swimmers`` phases uniform in ``[0, phi_max]``,
    stacks the swimmers laterally in the drawn order at dx = 0 with each
    neighbour gap the Eq. (sep) separation ``2A |sin((phi_{i+1} - phi_i)/2)|``
    plus one body width w each, giving ``Y / 2A = sum gaps / 2A + N w / 2A``.

    * ``closure="periodic"`` (default): N gaps, the last swimmer also
      neighbouring the first (a laterally periodic group).  Every gap has
      the triangular-pdf phase difference, so ``E[Y] = N y~ + N w`` exactly:
      the quantity of the closed form.  ``"open"``: N - 1 gaps (a group
      between walls); differs from the closed form by O(1/N).
    * ``estimator="ratio_of_means"`` (default): ``rho~ = 2AN / mean(Y)`` with
      the delta-method standard error; this is what the closed form
      :func:`packing_density` computes (it is ``1 / E[Y/2AN]``).
      ``"mean_of_ratios"``: ``mean(2AN / Y)``, the density averaged over
      configurations; by Jensen it exceeds the closed form by
      ``~ rho~^3 Var(Y/2AN)`` (small for large N; visible at N ~ 10).

    ``phi_max_rad`` (rad, [0, 2 pi]) and ``w_over_2A`` broadcast (arrays
    give array results; all phi_max share the same uniform draws, scaled).
    ``seed`` makes the draw reproducible (a private ``numpy.random.Generator``).
    """
    if closure not in ("periodic", "open"):
        raise ParameterError("closure", "'periodic' or 'open'", closure)
    if estimator not in ("ratio_of_means", "mean_of_ratios"):
        raise ParameterError("estimator", "'ratio_of_means' or 'mean_of_ratios'", estimator)
    if int(n_swimmers) != n_swimmers or n_swimmers < 2:
        raise ParameterError("n_swimmers", "an integer >= 2", n_swimmers)
    if int(n_samples) != n_samples or n_samples < 2:
        raise ParameterError("n_samples", "an integer >= 2", n_samples)
    p = _phi_max(phi_max_rad)
    packing_density(p, w_over_2A)  # validates w_over_2A
    w = np.asarray(w_over_2A, dtype=float)
    n = int(n_swimmers)

    u = np.random.default_rng(seed).random((int(n_samples), n))  # unit-uniform draws
    du = np.diff(u, axis=1, append=u[:, :1]) if closure == "periodic" else np.diff(u, axis=1)
    # |sin(p du / 2)| summed over gaps, for every phi_max: shape (n_samples,) + p.shape
    gaps = np.abs(np.sin(np.multiply.outer(du, p) / 2.0)).sum(axis=1)
    y_over_2an = gaps / n + w  # Y / 2AN per sample, broadcast with w
    if estimator == "ratio_of_means":
        m = y_over_2an.mean(axis=0)
        se_m = y_over_2an.std(axis=0, ddof=1) / np.sqrt(n_samples)
        with np.errstate(divide="ignore", invalid="ignore"):
            rho = 1.0 / m
            return DensityEstimate(rho, rho * se_m / m)
    with np.errstate(divide="ignore"):
        r = 1.0 / y_over_2an
    return DensityEstimate(r.mean(axis=0), r.std(axis=0, ddof=1) / np.sqrt(n_samples))


# ------------------------------------------------ walls: clearance and neutral offset
def _n_side_by_side(n_swimmers) -> int:
    if isinstance(n_swimmers, bool) or not isinstance(n_swimmers, (int, np.integer)) or n_swimmers < 1:
        raise ParameterError("n_swimmers", "an integer >= 1 (swimmers side by side across the channel)", n_swimmers)
    return int(n_swimmers)


def channel_width_m(d_over_2A, amplitude_m, n_swimmers: int):
    """Wall-to-wall channel width ``W`` (m) of the paper's confinement ``d/2A`` for ``n_swimmers`` side by side:
    ``W = n_swimmers * d``, ``d = (d/2A) * 2A`` (``A``, m: the gait amplitude of a free swimmer).

    The paper's ``d`` is the wall distance *per swimmer*, so ``d/2A = W / (2A n) = 1 / rho~``, the
    inverse of its packing density ``rho~ = 2AN/Y``.  This reading is the one the model supports
    (``explorations/d_thresholds.py``, docs/confinement_d.md): for a pair of default 3-link swimmers
    (``2A = 104.5 mm``, 15 mm links) an in-phase pair's gait is obstructed (mean joint error above a lone
    swimmer's by the paper's 0.01 rad) below ``W = 101 mm``, ``d/2A = 0.48`` (paper: "d/2A < 0.5 are not
    possible because the undulatory gait is obstructed"), and a pair started side by side in contact
    pushes itself apart and stops touching for every detuning tested (pi/4 to pi) from ``W = 225 mm``,
    ``d/2A = 1.08`` (paper: "when d/2A > 1 swimmers through initial contact can push each other away");
    the paper's 13 cm basins channel, where "swimmers cannot push each other away laterally", is
    ``d/2A = 0.62``.  Read as the whole width, the same widths would be ``d/2A`` = 0.97, 2.15 and 1.24,
    each at odds with the sentence it should meet.  For zero-thickness sinusoids the two statements are exact
    under this reading: an in-phase pair just fits at ``W = 2A`` (``d/2A = 0.5``) and two bands sit side
    by side without touching at ``W = 4A`` (``d/2A = 1``).

    ``d_over_2A`` (> 0) and ``amplitude_m`` (> 0, m) broadcast; ``n_swimmers``: an integer >= 1.
    Inverse: :func:`confinement_d_over_2A`.
    """
    n = _n_side_by_side(n_swimmers)
    r = _positive("d_over_2A", d_over_2A, "")
    a = _positive("amplitude_m", amplitude_m, "m")
    return n * r * 2.0 * a


def confinement_d_over_2A(channel_width_m, amplitude_m, n_swimmers: int):
    """The paper's confinement ``d/2A = W / (2A n)`` of a channel ``W`` m wide holding ``n_swimmers`` side by
    side (``A``, m: the gait amplitude of a free swimmer); the inverse of :func:`channel_width_m`, whose
    docstring gives the measurement that fixes this reading."""
    n = _n_side_by_side(n_swimmers)
    w = _positive("channel_width_m", channel_width_m, "m")
    a = _positive("amplitude_m", amplitude_m, "m")
    return w / (2.0 * a * n)


def lateral_clearance_m(d_m, amplitude_m, width_m=0.0):
    """Lateral clearance ``max(0, W - 2A - 2w)`` (m) that two swimmers' centre-line
    curves can keep in a channel ``W = d_m`` m wide, wall to wall (the channel's
    whole width, not the paper's per-swimmer ``d``: :func:`channel_width_m` maps
    ``d/2A`` to ``W``, ``W = 2 (d/2A) 2A`` for a pair).

    Each body edge keeps ``A + w/2`` from its wall and the two bodies need
    ``w`` between centre lines; ``width_m = 0`` gives zero-thickness
    sinusoids (``W - 2A``: ``dy/2A = W/2A - 1 = 2 d/2A - 1`` for a pair, so the
    curves first clear each other at ``d/2A = 0.5`` and clear by a whole ``2A``
    at ``d/2A = 1``).
    """
    return np.maximum(0.0, np.asarray(d_m, float) - 2 * np.asarray(amplitude_m, float)
                      - 2 * np.asarray(width_m, float))


def neutral_offset_m(d_m, amplitude_m, wavelength_m, width_m=0.0):
    """Half-width (m) of the band of neutral offsets of a ``dphi = 0`` pair between walls ``W = d_m`` m
    apart (the whole channel width; :func:`channel_width_m` gives it from ``d/2A``):
    ``(lambda / pi) arcsin(min(dy / 2A, 1))`` with ``dy = lateral_clearance_m(W, A, w)``.

    From the full compatibility region at ``dphi = 0``: two sinusoids at
    lateral offset ``dy`` never touch for ``|2 pi dx / lambda| <= 2
    arcsin(dy / 2A)``; forces slide a settled pair freely to the band's edge.
    """
    dy = lateral_clearance_m(d_m, amplitude_m, width_m)
    return np.asarray(wavelength_m, float) / np.pi * np.arcsin(
        np.minimum(dy / (2 * np.asarray(amplitude_m, float)), 1.0))


def walled_packing_density(phi_max_rad, w_over_2A, n_swimmers: int = 50):
    """Closed-form density with the side walls' room, dimensionless.

    A swimmer next to a wall needs ``A + w/2`` to it, so ``N`` swimmers need
    ``Y = (N - 1) y~ + N w + 2A`` and ``rho~_walls = 1 / ((N - 1)/N y~/2A +
    w/2A + 1/N)`` (``y~`` of :func:`packing_spacing`).
    """
    n = float(n_swimmers)
    return 1.0 / ((n - 1) / n * packing_spacing(phi_max_rad) + np.asarray(w_over_2A) + 1.0 / n)
