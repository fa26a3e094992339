"""Gait-compatibility theory against brute-force geometry and closed forms.

Conventions (undulate.params): y = A sin(2 pi x / lambda - omega t + phi),
a the lower and b the upper neighbour, dx = x_b - x_a, dphi = phi_b - phi_a.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy import integrate

from undulate import theory
from undulate.errors import ParameterError

TWO_PI = 2 * np.pi
OMEGA = TWO_PI * 0.5  # rad/s


def y_a(x, t, A, lam, phi_a):
    """Lower sinusoid, paper Eq. (sin1) with its own phase."""
    return A * np.sin(TWO_PI * x / lam - OMEGA * t + phi_a)


def y_b(x, t, A, lam, phi_a, dx, dphi, dy):
    """Upper sinusoid, paper Eq. (sin2): shifted by dx, dphi, dy."""
    return A * np.sin(TWO_PI * (x - dx) / lam - OMEGA * t + phi_a + dphi) + dy


def random_configs(rng, n):
    A = rng.uniform(0.02, 0.1, n)
    lam = rng.uniform(0.3, 1.0, n)
    return dict(
        A=A, lam=lam,
        phi_a=rng.uniform(0, TWO_PI, n),
        dx=rng.uniform(-1.5, 1.5, n) * lam,
        dphi=rng.uniform(-2 * TWO_PI, 2 * TWO_PI, n),
        dy=rng.uniform(0, 1.2, n) * 2 * A,
    )


# ------------------------------------------------------------ region: brute force
def test_region_matches_brute_force_min_gap():
    """min over x, t of (y_b - y_a) >= 0 exactly where Eq. (fullcompatibility) says so."""
    rng = np.random.default_rng(1)
    c = random_configs(rng, 2000)
    col = {k: v[:, None, None] for k, v in c.items()}
    # incommensurate grids: 101 x 37 samples give 3737 distinct wave phases
    x = np.linspace(0, 1, 101, endpoint=False)[None, :, None] * col["lam"]
    t = np.linspace(0, 2.0, 37, endpoint=False)[None, None, :]
    gap = (y_b(x, t, col["A"], col["lam"], col["phi_a"], col["dx"], col["dphi"], col["dy"])
           - y_a(x, t, col["A"], col["lam"], col["phi_a"]))
    min_gap = gap.min(axis=(1, 2)) / (2 * c["A"])

    ok = theory.is_compatible(c["dphi"], c["dx"], c["dy"], c["A"], c["lam"])
    # distance from the boundary, in units of 2A; grid error is < 5e-4
    margin = np.abs(c["dy"] - theory.min_lateral_separation(c["dphi"], c["dx"], c["A"], c["lam"]))
    clear = margin / (2 * c["A"]) > 1e-3
    assert clear.mean() > 0.95
    assert 0.2 < ok[clear].mean() < 0.8  # both sides well represented
    np.testing.assert_array_equal(min_gap[clear] >= 0, ok[clear])
    # and the closed-form minimum gap itself
    np.testing.assert_allclose(
        min_gap, (c["dy"] - theory.min_lateral_separation(c["dphi"], c["dx"], c["A"], c["lam"]))
        / (2 * c["A"]), atol=5e-4)


def test_standing_wave_region_ignores_dx():
    """lambda = inf: flat curves; compatible iff dy >= 2A |sin(dphi/2)|, whatever dx."""
    t = np.linspace(0, 2, 2001)[:, None]
    dphi = np.linspace(-3, 3, 13)
    A, dy = 0.05, 0.06
    gap = (A * np.sin(-OMEGA * t + dphi) + dy - A * np.sin(-OMEGA * t)).min(axis=0)
    for dx in (-0.3, 0.0, 0.7):
        ok = theory.is_compatible(dphi, dx, dy, A, np.inf)
        np.testing.assert_array_equal(ok, gap >= 0)
    assert np.isnan(theory.compatible_dx(1.0, np.inf))
    assert np.isnan(theory.compatibility_residual(0.2, 1.0, np.inf))
    assert theory.sinusoid_basin_displacement(0.2, 1.0, A, np.inf) == 0.0


def test_region_reduces_to_equality_at_dy_zero():
    rng = np.random.default_rng(2)
    dphi = rng.uniform(-TWO_PI, TWO_PI, 500)
    lam = rng.uniform(0.1, 2.0, 500)
    branch = rng.integers(-3, 4, 500)
    on_line = theory.compatible_dx(dphi, lam, branch)
    np.testing.assert_allclose(on_line, lam * (dphi / TWO_PI + branch))
    assert theory.is_compatible(dphi, on_line, 0.0, 0.05, lam).all()
    assert not theory.is_compatible(dphi, on_line + 1e-4 * lam, 0.0, 0.05, lam).any()
    lo, hi = theory.compatible_dx_interval(dphi, 0.0, 0.05, lam, branch)
    np.testing.assert_allclose(lo, on_line)
    np.testing.assert_allclose(hi, on_line)


def test_every_phase_allowed_once_dy_reaches_2A():
    rng = np.random.default_rng(3)
    A = 0.05
    dphi, dx = rng.uniform(-10, 10, (2, 1000))
    dy = rng.uniform(2 * A, 5 * A, 1000)
    assert theory.is_compatible(dphi, dx, dy, A, 0.54).all()
    assert (theory.min_lateral_separation(dphi, dx, A, 0.54) <= 2 * A + 1e-15).all()
    assert theory.max_phase_mismatch(2 * A, A) == pytest.approx(np.pi)
    lo, hi = theory.compatible_dx_interval(dphi, 2 * A, A, 0.54)
    np.testing.assert_allclose(hi - lo, 0.54)  # intervals of neighbouring branches touch
    # just below 2A some phase is excluded
    assert not theory.is_compatible(np.pi, 0.0, 1.99 * A, A, 0.54)


def test_interval_is_the_region_and_its_ends_are_tangent():
    rng = np.random.default_rng(4)
    c = random_configs(rng, 1000)
    lo, hi = theory.compatible_dx_interval(c["dphi"], c["dy"], c["A"], c["lam"])
    # the ends of the interval are the tangent-contact boundary
    for end in (lo, hi):
        np.testing.assert_allclose(
            theory.min_lateral_separation(c["dphi"], end, c["A"], c["lam"]),
            np.minimum(c["dy"], 2 * c["A"]), atol=1e-12)
    # dx is compatible iff it falls in the interval of some branch
    n = np.round((c["dx"] - (lo + hi) / 2) / c["lam"])
    inside = (c["dx"] - n * c["lam"] >= lo - 1e-12) & (c["dx"] - n * c["lam"] <= hi + 1e-12)
    np.testing.assert_array_equal(inside, theory.is_compatible(c["dphi"], c["dx"], c["dy"], c["A"], c["lam"]))


def test_residual_is_distance_to_nearest_branch():
    rng = np.random.default_rng(5)
    c = random_configs(rng, 1000)
    r = theory.compatibility_residual(c["dx"], c["dphi"], c["lam"])
    assert ((r > -c["lam"] / 2) & (r <= c["lam"] / 2)).all()
    # dx - r lies on a branch ...
    assert theory.is_compatible(c["dphi"], c["dx"] - r, 0.0, c["A"], c["lam"]).all()
    # ... the nearest one
    for k in range(-4, 5):
        assert (np.abs(r) <= np.abs(c["dx"] - theory.compatible_dx(c["dphi"], c["lam"], k)) + 1e-12).all()
    assert theory.compatibility_residual(0.5, 0.0, 1.0) == 0.5  # the half-open end
    assert theory.compatibility_residual(-0.5, 0.0, 1.0) == 0.5


# ------------------------------------------------------ tangent point and push
def _tangent_configs(rng, n):
    c = random_configs(rng, n)
    psi = theory.phase_mismatch(c["dphi"], c["dx"], c["lam"])
    keep = (np.abs(psi) > 0.05) & (np.abs(psi) < np.pi - 0.05)
    c = {k: v[keep] for k, v in c.items()}
    c["dy"] = theory.min_lateral_separation(c["dphi"], c["dx"], c["A"], c["lam"])  # just touching
    return c


def test_tangent_point_touches_with_equal_slopes_and_is_the_closest_approach():
    rng = np.random.default_rng(6)
    c = _tangent_configs(rng, 300)
    t = rng.uniform(0, 10, len(c["A"]))
    xs = theory.tangent_contact_x(t, c["dx"], c["dphi"], c["lam"], OMEGA, c["phi_a"])
    assert ((xs >= 0) & (xs < c["lam"])).all()
    args = (c["A"], c["lam"], c["phi_a"])
    bargs = (*args, c["dx"], c["dphi"], c["dy"])
    np.testing.assert_allclose(y_b(xs, t, *bargs), y_a(xs, t, *args), atol=1e-12)
    h = 1e-7 * c["lam"]
    slope_a = (y_a(xs + h, t, *args) - y_a(xs - h, t, *args)) / (2 * h)
    slope_b = (y_b(xs + h, t, *bargs) - y_b(xs - h, t, *bargs)) / (2 * h)
    np.testing.assert_allclose(slope_a, slope_b, atol=1e-6)
    # brute force: the minimum of the gap over one wavelength is at x*
    x = np.linspace(0, 1, 20001)[None, :] * c["lam"][:, None]
    gap = y_b(x, t[:, None], *(v[:, None] for v in bargs)) - y_a(x, t[:, None], *(v[:, None] for v in args))
    x_min = x[np.arange(len(t)), gap.argmin(axis=1)]
    d = (x_min - xs + c["lam"] / 2) % c["lam"] - c["lam"] / 2
    assert np.abs(d / c["lam"]).max() < 1e-3
    # the point travels toward +x at the wave speed lambda omega / 2 pi
    xs2 = theory.tangent_contact_x(t + 0.01, c["dx"], c["dphi"], c["lam"], OMEGA, c["phi_a"])
    np.testing.assert_allclose((xs2 - xs) % c["lam"], c["lam"] * OMEGA * 0.01 / TWO_PI, rtol=1e-9)


def test_contact_normal_pushes_toward_nearest_branch():
    """Brute force: the contact normal at the deepest overlap drives dx by -2 y_a'."""
    rng = np.random.default_rng(7)
    c = _tangent_configs(rng, 400)
    x = np.linspace(0, 1, 4001)[None, :] * c["lam"][:, None]
    col = {k: v[:, None] for k, v in c.items()}
    gap = y_b(x, 0.0, col["A"], col["lam"], col["phi_a"], col["dx"], col["dphi"], col["dy"]) \
        - y_a(x, 0.0, col["A"], col["lam"], col["phi_a"])
    x_min = x[np.arange(len(c["A"])), gap.argmin(axis=1)]
    h = 1e-7 * c["lam"]
    slope = (y_a(x_min + h, 0.0, c["A"], c["lam"], c["phi_a"])
             - y_a(x_min - h, 0.0, c["A"], c["lam"], c["phi_a"])) / (2 * h)
    push = theory.contact_push_direction(c["dx"], c["dphi"], c["lam"])
    np.testing.assert_array_equal(push, -np.sign(slope))
    # ... which is toward the nearest compatible branch
    np.testing.assert_array_equal(push, -np.sign(theory.compatibility_residual(c["dx"], c["dphi"], c["lam"])))


# ---------------------------------------------------------------------- basins
def _quasi_static(dx0, dphi, dy, A_f, lam, n_amp=80, n_x=512):
    """Independent model: grow A in steps; while the curves overlap, move dx a
    small step along -sign(y_a') at the deepest overlap (the contact normal).
    An overlap smaller than one step can remove counts as resolved."""
    step = lam / 1000
    tol = 1.01 * TWO_PI * step / lam
    dx = np.array(dx0, float)
    x = np.linspace(0, lam, n_x, endpoint=False)[None, :]
    k = TWO_PI / lam
    rows = np.arange(len(dx))
    for A in np.linspace(0, A_f, n_amp)[1:]:
        for _ in range(2000):
            gap = A * np.sin(k * (x - dx[:, None]) + dphi[:, None]) + dy[:, None] - A * np.sin(k * x)
            i = gap.argmin(axis=1)
            over = gap[rows, i] < -tol * A
            if not over.any():
                break
            slope = A * k * np.cos(k * x[0, i])
            dx[over] -= np.sign(slope[over]) * step
    return dx


@pytest.mark.parametrize("dy_over_2A", [0.0, 0.3])
def test_basin_map_matches_quasi_static_growth(dy_over_2A):
    rng = np.random.default_rng(8)
    lam, A = 0.54, 0.06
    dx0 = rng.uniform(-lam, lam, 300)
    dphi = rng.uniform(-np.pi, np.pi, 300)
    psi = theory.phase_mismatch(dphi, dx0, lam)
    keep = np.abs(psi) < np.pi - 0.05  # away from the unstable basin boundary
    dx0, dphi = dx0[keep], dphi[keep]
    dy = np.full_like(dx0, dy_over_2A * 2 * A)
    final = _quasi_static(dx0, dphi, dy, A, lam)
    model = theory.sinusoid_basin_displacement(dx0, dphi, A, lam, dy, target="boundary")
    np.testing.assert_allclose(final - dx0, model, atol=2.5 * lam / 1000)
    if dy_over_2A == 0:  # the boundary and the paper's line coincide at dy = 0
        line = theory.sinusoid_basin_displacement(dx0, dphi, A, lam, dy)
        np.testing.assert_allclose(model, line, atol=1e-12)


def test_basin_map_basic_properties():
    lam, A = 0.54, 0.06
    assert theory.sinusoid_basin_displacement(0.0, 0.0, A, lam) == 0.0
    dx0 = np.linspace(-0.49, 0.49, 99) * lam
    d = theory.sinusoid_basin_displacement(dx0, 0.0, A, lam)
    np.testing.assert_allclose(dx0 + d, 0.0, atol=1e-15)  # pulled back to dx = 0
    far = np.linspace(0.51, 0.99, 49) * lam
    np.testing.assert_allclose(far + theory.sinusoid_basin_displacement(far, 0.0, A, lam), lam)
    # with dphi: ends on the branch dx = lambda dphi / 2 pi
    dphi = 1.3
    dx_f = dx0 + theory.sinusoid_basin_displacement(dx0, dphi, A, lam)
    near = np.abs(dx0 - lam * dphi / TWO_PI) < lam / 2
    np.testing.assert_allclose(dx_f[near], lam * dphi / TWO_PI, atol=1e-15)
    # the basin edge itself: a purely lateral push
    assert theory.sinusoid_basin_displacement(lam / 2, 0.0, A, lam) == 0.0
    # already compatible: no contact, no motion
    rng = np.random.default_rng(9)
    dx, dphi = rng.uniform(-1, 1, 200) * lam, rng.uniform(-np.pi, np.pi, 200)
    assert (theory.sinusoid_basin_displacement(dx, dphi, A, lam, dy_m=2 * A) == 0).all()
    dy = theory.min_lateral_separation(dphi, dx, A, lam) * 1.01
    assert (theory.sinusoid_basin_displacement(dx, dphi, A, lam, dy_m=dy) == 0).all()
    # never further than half a wavelength
    assert (np.abs(theory.sinusoid_basin_displacement(dx, dphi, A, lam)) <= lam / 2).all()
    with pytest.raises(ParameterError):
        theory.sinusoid_basin_displacement(0.1, 0.0, A, lam, target="nearest")


# ------------------------------------------------------------ property tests
phases = st.floats(-3 * np.pi, 3 * np.pi, allow_nan=False)
lengths = st.floats(-2.0, 2.0, allow_nan=False)
wavelengths = st.floats(0.1, 2.0)
amps = st.floats(0.01, 0.2)
fracs = st.floats(0.0, 1.5)


@settings(max_examples=200, deadline=None)
@given(dphi=phases, dx=lengths, lam=wavelengths, A=amps, s=fracs, n=st.integers(-3, 3))
def test_region_symmetry_and_periodicity(dphi, dx, lam, A, s, n):
    dy = s * 2 * A
    sep = theory.min_lateral_separation(dphi, dx, A, lam)
    assert theory.min_lateral_separation(-dphi, -dx, A, lam) == pytest.approx(sep, abs=1e-12)
    assert theory.min_lateral_separation(dphi, dx + n * lam, A, lam) == pytest.approx(sep, abs=1e-9)
    assert theory.min_lateral_separation(dphi + n * TWO_PI, dx, A, lam) == pytest.approx(sep, abs=1e-9)
    assume(abs(sep - min(dy, 2 * A)) > 1e-8 * A)  # off the boundary, the predicate is robust
    ok = theory.is_compatible(dphi, dx, dy, A, lam)
    assert theory.is_compatible(-dphi, -dx, dy, A, lam) == ok
    assert theory.is_compatible(dphi, dx + n * lam, dy, A, lam) == ok
    assert theory.is_compatible(dphi + n * TWO_PI, dx, dy, A, lam) == ok
    assert ok == (sep <= dy)


@settings(max_examples=200, deadline=None)
@given(dphi=phases, dx=lengths, lam=wavelengths, A=amps, s=fracs, n=st.integers(-3, 3))
def test_basin_symmetry_and_periodicity(dphi, dx, lam, A, s, n):
    r = theory.compatibility_residual(dx, dphi, lam)
    assume(abs(abs(r) - lam / 2) > 1e-9 * lam)  # off the (discontinuous) basin edge
    dy = s * 2 * A
    d = theory.sinusoid_basin_displacement(dx, dphi, A, lam, dy)
    assert theory.sinusoid_basin_displacement(dx + n * lam, dphi, A, lam, dy) == pytest.approx(d, abs=1e-9)
    assert theory.sinusoid_basin_displacement(dx, dphi + n * TWO_PI, A, lam, dy) == pytest.approx(d, abs=1e-9)
    assert theory.sinusoid_basin_displacement(-dx, -dphi, A, lam, dy) == pytest.approx(-d, abs=1e-12)
    assert theory.compatibility_residual(-dx, -dphi, lam) == pytest.approx(-r, abs=1e-12)
    assert theory.compatibility_residual(dx + n * lam, dphi, lam) == pytest.approx(r, abs=1e-9)


@settings(max_examples=200, deadline=None)
@given(p1=st.floats(0, TWO_PI), p2=st.floats(0, TWO_PI), w=st.floats(0.0, 2.0))
def test_density_falls_as_phase_spread_grows(p1, p2, w):
    """Larger phase spread => larger required spacing => smaller rho~."""
    lo, hi = sorted((p1, p2))
    assert theory.packing_spacing(lo) <= theory.packing_spacing(hi) + 1e-12
    assume(w > 0 or lo > 0)
    assert theory.packing_density(lo, w) >= theory.packing_density(hi, w) * (1 - 1e-12)


# --------------------------------------------------------------------- packing
@pytest.mark.parametrize("phi_max", [0.3, 1.0, 2.0, np.pi, 5.0, TWO_PI])
def test_closed_form_spacing_is_the_triangular_pdf_integral(phi_max):
    """E|sin(D/2)| with D = |phi_i - phi_j|, pdf (2/phi_max)(1 - D/phi_max)."""
    val, _ = integrate.quad(lambda d: abs(np.sin(d / 2)) * 2 / phi_max * (1 - d / phi_max), 0, phi_max)
    assert theory.packing_spacing(phi_max) == pytest.approx(val, rel=1e-10)


def test_monte_carlo_agrees_with_closed_form():
    phi = np.array([0.3, 1.0, 2.0, np.pi, 5.0, TWO_PI])
    for w in (0.05, 0.15):
        est = theory.packing_density_mc(phi, w, n_swimmers=50, n_samples=4000, seed=11)
        z = (est.mean - theory.packing_density(phi, w)) / est.stderr
        assert np.abs(z).max() < 4, z
    # an open stack (walls, N - 1 gaps) needs (N - 1) y~ + N w instead
    n = 10
    est = theory.packing_density_mc(phi, 0.1, n_swimmers=n, n_samples=4000, seed=12, closure="open")
    expected = n / ((n - 1) * theory.packing_spacing(phi) + n * 0.1)
    assert np.abs((est.mean - expected) / est.stderr).max() < 4
    # averaging 2AN/Y per configuration is biased upward (Jensen), not the closed form
    ratio = theory.packing_density_mc(phi, 0.1, n, 4000, seed=13, estimator="mean_of_ratios")
    rom = theory.packing_density_mc(phi, 0.1, n, 4000, seed=13)
    assert (ratio.mean > rom.mean).all()


def test_density_limit_at_zero_phase_spread():
    w = 0.08
    assert theory.packing_density(0.0, w) == pytest.approx(1 / w)  # rho~ = 2A / w
    for p in (1e-9, 1e-6, 1e-4):
        assert theory.packing_density(p, w) == pytest.approx(1 / w, rel=2 * p / w)
    # series and exact branch meet smoothly at the switch
    below, above = theory.packing_spacing([1e-3 * (1 - 1e-9), 1e-3 * (1 + 1e-9)])
    assert below == pytest.approx(above, rel=1e-8)
    est = theory.packing_density_mc(0.0, w, 20, 100, seed=0)
    assert est.mean == pytest.approx(1 / w) and est.stderr == pytest.approx(0, abs=1e-9)


def test_monte_carlo_is_reproducible_and_validates():
    a = theory.packing_density_mc(1.0, 0.1, 20, 500, seed=3)
    b = theory.packing_density_mc(1.0, 0.1, 20, 500, seed=3)
    assert a == b
    for kwargs in ({"phi_max_rad": 7.0}, {"phi_max_rad": -0.1}, {"n_swimmers": 1}, {"w_over_2A": -1.0}):
        args = {"phi_max_rad": 1.0, "w_over_2A": 0.1} | kwargs
        with pytest.raises(ParameterError):
            theory.packing_density_mc(**args, n_samples=10)


def test_invalid_geometry_is_refused():
    with pytest.raises(ParameterError, match="amplitude_m"):
        theory.is_compatible(0.0, 0.0, 0.0, 0.0, 1.0)
    with pytest.raises(ParameterError, match="wavelength_m"):
        theory.phase_mismatch(0.0, 0.0, -1.0)
    with pytest.raises(ParameterError, match="amplitude_m"):
        theory.min_lateral_separation(0.0, 0.0, np.inf, 1.0)


# ------------------------------------------------------------------ wrapping
def test_one_wrapping_convention_half_open_at_plus_pi():
    from undulate.observables import wrap_angle

    assert wrap_angle is theory.wrap_phase  # one implementation under both names
    np.testing.assert_array_equal(theory.wrap_phase([np.pi, -np.pi, 3 * np.pi, -5 * np.pi, 0.5, -0.5]),
                                  [np.pi, np.pi, np.pi, np.pi, 0.5, -0.5])
    a = np.random.default_rng(3).uniform(-30, 30, 10_000)
    w = theory.wrap_phase(a)
    assert ((w > -np.pi) & (w <= np.pi)).all()
    np.testing.assert_allclose(np.cos(w - a), 1.0, atol=1e-12)  # the same angle
    # a configuration half a wave off the line reads psi = +pi, as dphi = pi does
    assert theory.phase_mismatch(-np.pi, 0.0, 1.0) == np.pi
    assert theory.phase_mismatch(0.0, 0.5, 1.0) == np.pi


def test_wrapping_keeps_the_observables_values_bit_for_bit():
    """The observables wrapped with -((-a + pi) mod 2 pi - pi) before the two conventions
    became one; dphi, phases and every result built on them are unchanged."""
    a = np.concatenate([np.random.default_rng(4).uniform(-20, 20, 10_000), np.arange(-16, 17) * np.pi / 8])
    before = -((-a + np.pi) % TWO_PI - np.pi)
    np.testing.assert_array_equal(theory.wrap_phase(a), before)
    assert np.signbit(theory.wrap_phase(0.0)) == np.signbit(before[a == 0.0][0])



# ------------------------------------------------ confinement d/2A and the channel width
def test_d_over_2A_is_the_wall_distance_per_swimmer():
    """For zero-thickness sinusoids a pair's channel W = 2A is where an in-phase pair just fits (d/2A = 0.5)
    and W = 4A where two bands sit side by side without touching (d/2A = 1): the paper's two statements."""
    A = 0.05226
    assert float(theory.channel_width_m(0.5, A, 2)) == pytest.approx(2 * A)
    assert float(theory.channel_width_m(1.0, A, 2)) == pytest.approx(4 * A)
    # at d/2A = 0.5 two sinusoids have no clearance; at 1 a whole 2A: every dphi is compatible
    assert float(theory.lateral_clearance_m(theory.channel_width_m(0.5, A, 2), A)) == pytest.approx(0.0)
    assert float(theory.lateral_clearance_m(theory.channel_width_m(1.0, A, 2), A)) == pytest.approx(2 * A)
    assert float(theory.min_lateral_separation(np.pi, 0.0, A, 0.54)) == pytest.approx(2 * A)  # the worst dphi
    # d/2A = 1/rho~ (rho~ = 2AN/Y), the paper's packing normalisation, for any number side by side
    for n in (1, 2, 5):
        assert float(theory.confinement_d_over_2A(0.3, A, n)) == pytest.approx(1.0 / (2 * A * n / 0.3))
    # the paper's range and its 13 cm basins channel
    assert float(theory.channel_width_m(0.6, A, 2)) == pytest.approx(0.1254, abs=1e-4)
    assert float(theory.channel_width_m(1.2, A, 2)) == pytest.approx(0.2508, abs=1e-4)
    assert float(theory.confinement_d_over_2A(0.13, A, 2)) == pytest.approx(0.622, abs=1e-3)


@given(r=st.floats(0.05, 20.0), a=st.floats(1e-3, 1.0), n=st.integers(1, 60))
def test_channel_width_round_trip(r, a, n):
    w = theory.channel_width_m(r, a, n)
    assert float(theory.confinement_d_over_2A(w, a, n)) == pytest.approx(r, rel=1e-12)
    assert float(w) == pytest.approx(n * r * 2 * a, rel=1e-12)


@pytest.mark.parametrize("n", [0, -2, 1.5, "2", None, True])
def test_channel_width_rejects_a_bad_number_of_swimmers(n):
    with pytest.raises(ParameterError, match="n_swimmers"):
        theory.channel_width_m(1.0, 0.05, n)
    with pytest.raises(ParameterError, match="n_swimmers"):
        theory.confinement_d_over_2A(0.2, 0.05, n)


@pytest.mark.parametrize("call, name", [
    (lambda: theory.channel_width_m(0.0, 0.05, 2), "d_over_2A"),
    (lambda: theory.channel_width_m(1.0, -0.05, 2), "amplitude_m"),
    (lambda: theory.confinement_d_over_2A(float("nan"), 0.05, 2), "channel_width_m"),
])
def test_channel_width_rejects_bad_lengths(call, name):
    with pytest.raises(ParameterError, match=name):
        call()
