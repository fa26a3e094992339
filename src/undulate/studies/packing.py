"""Study ``packing`` (paper Fig. 7): phase spread against lateral density in a group of 50.

Setup (paper section "Gait compatibility influences spatial packing"):
``N = 50`` three-link swimmers side by side in the short channel (end walls
``1.1 L`` apart), all heads toward -x, phases drawn uniformly from
``[0, phi_max]`` in random lateral order.  The channel width ``Y`` is set
from the normalised density ``rho~ = 2 A N / Y`` (``A`` the gait amplitude
of a free swimmer, ``StudyContext.lone_swimmer``: the one definition), and the
swimmers start straight, evenly spread across it: centre lines ``Y / N``
apart (``Scene.lateral_gap_m = Y / N - w``), so each outer swimmer has half
a pitch to its wall.

Contact metric: the mean joint error ``|alpha - alpha_cmd|`` over every
swimmer and joint and over ``t >= SKIP_S`` (the first period, the start from
straight bodies, is left out; the lone swimmer is averaged the same way).
The *simulated compatibility threshold* for one phase draw is the lowest
density at which that mean exceeds the lone swimmer's by ``0.01 rad``
(:func:`density_threshold`): interpolated linearly in ``rho~`` between the
last grid density below and the first above.  No run is expected to
diverge (the simulator keeps jammed packs below 1 mm of interpenetration:
docs/contact.md); a run that does is stored flagged ``diverged``, left out
of the threshold search, and a threshold whose bracket contains one is
NaN rather than guessed.  Uncertainty: the threshold over the phase draws
(replicates) with an interval from the draws' bracket ends and their
spread, on the scale of the densities a scene can have
(:func:`threshold_estimate`: inside ``(0, 2A/w)``); the rank correlation of the per-draw thresholds with
``phi_max`` (Spearman, ties averaged) with a seeded bootstrap interval.

Common random numbers: replicate ``r`` draws its unit-uniform numbers
``u`` once from ``numpy.random.default_rng([seed, r])`` (``seed`` the study
seed) and uses ``phases = phi_max * u`` at every ``(phi_max, rho~)``, so a
replicate's threshold along ``rho~`` is measured on one phase set.

Theory on the same axes (:mod:`undulate.theory`): the closed form
``packing_density(phi_max, w / 2A)`` (paper Eq. rho_tilde), its Monte-Carlo
estimate ``packing_density_mc`` with ``N = 50``, and, dotted, the closed
form with the room the side walls take: a swimmer next to a wall needs
``A + w / 2`` to it, so ``N`` swimmers need ``Y = (N - 1) y~ + N w + 2 A``
and ``rho~_walls = 1 / ((N - 1) / N * y~/2A + w/2A + 1/N)``.  At
``phi_max = 0`` this is the jamming density of an in-phase stack between
walls (~6.1 at the defaults instead of ``2A / w`` ~ 7).

"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from .. import stats, theory
from ..params import Channel, Scene, SimOptions, SwimmerGeometry
from ..stopping import ExcessStop
from ._points import PackingPoint
from ._context import StudyContext
from ._protocol import Claim, Study, Verdict
from ._registry import register


__all__ = [
    "N_SWIMMERS",
    "THRESHOLD_RAD",
    "PackingPlan",
    "plan",
    "packing_point",
    "packing_continue",
    "Resumes",
    "density_threshold",
    "threshold_estimate",
    "walled_packing_density",
    "dataset",
    "summary",
    "CLAIMS",
]

N_SWIMMERS = 50
THRESHOLD_RAD = 0.01
"""Mean joint error above the lone swimmer's that counts as contact, rad (paper: 0.01 rad)."""
SHORT_CHANNEL_OVER_L = 1.1
DURATION_S = 10.0
SKIP_S = 2.0
"""Joint error is averaged over t >= SKIP_S (one gait period), s."""
SAMPLE_RATE_HZ = 10.0
PACKING_STOP = ExcessStop(confidence=0.99, batch_s=1.0, min_batches=3)
"""The probes' stopping rule: a run ends once its mean joint error after SKIP_S is decided above or
below the lone swimmer's + THRESHOLD_RAD at one-sided 99 % (batch means over 1 s, at least 3).  The
two runs that bracket a threshold are then continued from where they stopped to the full length
(:func:`_rerun_brackets`, :func:`packing_continue`), so the interpolated threshold uses the same values
as without stopping."""


# --------------------------------------------------------------------- the study
class PackingPlan:
    """Grids of the packing study.

    ``phi_max_rad`` x ``rho_tilde`` x ``draws``: the densities along which each
    phase draw's threshold is searched; ``heatmap_rho`` x ``heatmap_draws``: the
    runs done at every ``phi_max`` for the heatmap (default: the whole threshold
    grid, every draw).  Where the heatmap does not cover the threshold grid, the
    threshold of each (phi_max, draw) is found by bisection over ``rho_tilde``
    (:func:`bisection_probes`), reusing the heatmap's runs.
    """

    def __init__(self, phi_max_rad, rho_tilde, draws: int, n_swimmers: int = N_SWIMMERS,
                 duration_s: float = DURATION_S, heatmap_rho=None, heatmap_draws: int | None = None):
        self.phi_max_rad = [float(v) for v in phi_max_rad]
        self.rho_tilde = sorted(float(v) for v in rho_tilde)
        self.draws = int(draws)
        self.n_swimmers = int(n_swimmers)
        self.duration_s = float(duration_s)
        self.heatmap_rho = self.rho_tilde if heatmap_rho is None else sorted(float(v) for v in heatmap_rho)
        self.heatmap_draws = self.draws if heatmap_draws is None else int(heatmap_draws)
        if not 1 <= self.heatmap_draws <= self.draws:
            raise ValueError(f"heatmap_draws must be 1..{self.draws}")


def plan(quick: bool) -> PackingPlan:
    """Full: 13 phase spreads (0 to 2 pi in pi/6); thresholds over 19 densities (0.5; 1 to 4
    in 0.25, where the thresholds lie; 4.5 to 6.5 in 0.5) for 5 phase draws, found by
    bisection; heatmap at 7 densities (0.5 to 6.5 in 1) for the first 2 draws: 50
    swimmers, 10 s each (about 400 runs instead of the 1235 of the whole grid; same
    thresholds: docs/performance.md).  Quick: 4 phase spreads x 5 densities x 2 draws of 8 s, the
    heatmap at 3 densities for the first draw, the thresholds by bisection (about 28 runs of 40)."""
    if quick:
        return PackingPlan([0.0, np.pi / 2, np.pi, 2 * np.pi], [1.5, 2.5, 3.5, 4.5, 5.5], draws=2,
                           duration_s=8.0, heatmap_rho=[1.5, 3.5, 5.5], heatmap_draws=1)
    rho = np.round(np.r_[0.5, np.arange(1.0, 4.01, 0.25), np.arange(4.5, 6.51, 0.5)], 10)
    return PackingPlan(np.linspace(0, 2 * np.pi, 13), rho, draws=5,
                       heatmap_rho=np.round(np.arange(0.5, 6.51, 1.0), 10), heatmap_draws=2)


def bisection_probes(known: dict[int, bool | None], m: int) -> list[int]:
    """The next density indices to run for one (phi_max, draw) threshold; ``[]``: found.

    ``known``: index into the threshold grid (``m`` densities) -> whether the
    run there is above the threshold (True), below (False) or failed/diverged
    (None).  While the runs known are monotone (every one below lies below
    every one above) and none failed, one probe halves the bracket between
    the highest index below and the lowest above; the search ends when they
    are neighbours (or the lowest density is above, or the highest below):
    the same two runs, hence the same interpolated threshold, as the whole
    column gives when the joint error's crossing is monotone in density (it
    is in all 65 columns of the full grid: docs/performance.md).  A failed
    run or a non-monotone column asks for every remaining density, so
    :func:`density_threshold` then sees the whole column, as without bisection.
    """
    rest = [j for j in range(m) if j not in known]
    if any(v is None for v in known.values()):
        return rest
    lo = max((j for j, v in known.items() if not v), default=-1)
    hi = min((j for j, v in known.items() if v), default=m)
    if lo > hi:  # not monotone: look at the whole column
        return rest
    if hi == lo + 1 or lo == m - 1 or hi == 0:
        return []
    return [(lo + hi) // 2]


def _pack(point: dict, *, amplitude_m: float, base_seed: int, n_swimmers: int) -> tuple[Scene, float]:
    """The scene of packing point ``point`` (see :func:`packing_point`) and its channel width Y, m."""
    geo = SwimmerGeometry()
    n = int(n_swimmers)
    pt = PackingPoint.of(point)
    u = np.random.default_rng([int(base_seed), pt.draw]).random(n)
    width = 2.0 * amplitude_m * n / pt.rho_tilde
    scene = Scene(
        phases_rad=tuple(pt.phi_max_rad * u),
        channel=Channel(width_m=width, end_walls_m=SHORT_CHANNEL_OVER_L * geo.length_m),
        lateral_gap_m=width / n - geo.width_m,
    )
    return scene, width


def _options(duration_s: float) -> SimOptions:
    """Only what is measured here: no swimmer-swimmer force sensors (49 of them scan every contact)."""
    return SimOptions(duration_s=duration_s, sample_rate_hz=SAMPLE_RATE_HZ,
                      record=("joint_error", "contact_force_wall", "penetration"))


def _series(ds) -> dict[str, np.ndarray]:
    """A run's per-sample record: time (s), mean joint error over swimmers and joints (rad), force on
    each wall (N) and deepest interpenetration (m)."""
    t = ds["time"].values
    return {"time": t, "joint_error": ds["joint_error"].values.reshape(len(t), -1).mean(axis=1),
            "wall_force": ds["contact_force_wall"].values,
            "penetration": ds["penetration"].values.reshape(len(t), -1).max(axis=1)}


def _measures(sr: dict[str, np.ndarray], skip_s: float) -> tuple[float, float, float, float]:
    """Mean and largest joint error over the samples at t >= skip (the mean over swimmers and joints of
    each sample, then over samples: every sample has the same count), mean wall force summed over the
    walls (samples after skip: sample t holds the mean over (t - interval, t]) and deepest penetration."""
    t = sr["time"]
    je, wall = sr["joint_error"][t >= skip_s], sr["wall_force"][t > skip_s + 1e-12]
    if not len(je) or not len(wall):  # a run no longer than the skip: nothing to average
        return float("nan"), float("nan"), float("nan"), float(sr["penetration"].max())
    return float(je.mean()), float(je.max()), float(wall.mean(axis=0).sum()), float(sr["penetration"].max())


def packing_point(point: dict, seed: int, *, amplitude_m: float, base_seed: int,
                  n_swimmers: int = N_SWIMMERS, duration_s: float = DURATION_S,
                  skip_s: float = SKIP_S, stop: ExcessStop | None = None, lone_error_rad: float = 0.0):
    """One packing run (sweep function).

    ``point``: ``phi_max_rad`` (phase spread, rad), ``rho_tilde`` (normalised
    density 2AN/Y, dimensionless), ``draw`` (phase-draw number).  Phases are
    ``phi_max * u`` with ``u ~ U[0, 1)^N`` from ``default_rng([base_seed,
    draw])`` (the sweep's per-run ``seed`` is not used: see the module
    docstring).  ``amplitude_m``: A, m.  A run that blows up
    (:class:`~undulate.errors.DivergenceError`: dense, jammed packs do) is a
    result, not a failure: ``diverged`` is True and the measurements are NaN,
    so a resumed sweep does not redo it.  ``stop``: a stopping rule (e.g. :data:`PACKING_STOP`;
    None: the whole duration) at the level ``lone_error_rad + THRESHOLD_RAD``; the means are then over
    the run as stepped (``stopped_at_s``), and the run's per-sample record and end state are kept
    (``series_*``, ``end_*``) so that :func:`packing_continue` can go on from where it stopped.
    """
    from ..errors import DivergenceError
    from ..simulation import Checkpoint, simulate

    scene, width = _pack(point, amplitude_m=amplitude_m, base_seed=base_seed, n_swimmers=n_swimmers)
    monitor = None if stop is None else stop.monitor(float(lone_error_rad) + THRESHOLD_RAD, skip_s)
    rule = "none" if monitor is None else monitor.rule
    try:
        ds = simulate(scene, _options(duration_s), stop=monitor)
    except DivergenceError:
        return _result(scene, duration_s, width, None, None, skip_s, rule)
    return _result(scene, duration_s, width, _series(ds), Checkpoint.of(ds), skip_s, rule)


def packing_continue(point: dict, seed: int, *, amplitude_m: float, base_seed: int, resume: "Resumes",
                     n_swimmers: int = N_SWIMMERS, duration_s: float = DURATION_S, skip_s: float = SKIP_S):
    """A stopped packing run continued to the whole ``duration_s`` (sweep function): its record up to the
    stop and its end state from ``resume`` (:class:`Resumes`, keyed by point), then the rest of the run
    stepped from that state (:class:`~undulate.simulation.Checkpoint`): bitwise the Dataset
    :func:`packing_point` gives without a stopping rule (``tests/test_stopping.py``), for only the
    steps after the stop."""
    from ..errors import DivergenceError
    from ..simulation import Checkpoint, simulate

    scene, width = _pack(point, amplitude_m=amplitude_m, base_seed=base_seed, n_swimmers=n_swimmers)
    before, end = resume.get(point)
    try:
        ds = simulate(scene, _options(duration_s), start=end)
    except DivergenceError:
        return _result(scene, duration_s, width, None, None, skip_s, "none")
    after = _series(ds)
    sr = {k: np.concatenate([before[k], after[k]]) for k in before}
    return _result(scene, duration_s, width, sr, Checkpoint.of(ds), skip_s, "none")


def _result(scene: Scene, duration_s: float, width: float, sr, end, skip_s: float, rule: str):
    """A packing run's Dataset from its per-sample record ``sr`` and end state ``end`` (None: diverged)."""
    import xarray as xr

    n = int(round(duration_s * SAMPLE_RATE_HZ)) + 1
    diverged = sr is None
    if diverged:
        sr, end = _nan_run(scene, duration_s)
        je_mean = je_max = wall_f = pen = stopped_at = float("nan")
    else:
        je_mean, je_max, wall_f, pen = _measures(sr, skip_s)
        stopped_at = float(sr["time"][-1])

    def pad(a):
        return np.concatenate([a, np.full((n - len(a), *a.shape[1:]), np.nan)])

    return xr.Dataset(
        {
            "mean_joint_error_rad": ((), je_mean, {
                "units": "rad", "long_name": "mean joint error over swimmers, joints and t >= skip"}),
            "max_joint_error_rad": ((), je_max, {
                "units": "rad", "long_name": "largest group-mean joint error over time"}),
            "channel_width_m": ((), width, {"units": "m", "long_name": "channel width Y"}),
            "mean_wall_force_N": ((), wall_f, {
                "units": "N", "long_name": "time-mean contact force on all walls"}),
            "max_penetration_m": ((), pen, {"units": "m", "long_name": "deepest interpenetration"}),
            "diverged": ((), diverged, {"long_name": "the simulation blew up (DivergenceError)"}),
            "stopped_at_s": ((), stopped_at, {"units": "s", "long_name": "last sample (the duration unless the "
                                              "stopping rule ended the run)", "stop_rule": rule}),
            "series_time_s": (("sample",), pad(sr["time"]), {"units": "s", "long_name": "sample time; "
                                                              "NaN after the run ended"}),
            "series_joint_error_rad": (("sample",), pad(sr["joint_error"]), {
                "units": "rad", "long_name": "mean joint error over swimmers and joints, per sample"}),
            "series_wall_force_N": (("sample", "wall"), pad(sr["wall_force"]), {
                "units": "N", "long_name": "contact force on each wall, mean over the sample interval"}),
            "series_penetration_m": (("sample",), pad(sr["penetration"]), {
                "units": "m", "long_name": "deepest interpenetration in the sample interval"}),
            "end_state": (("state",), end.state, {"units": "mixed: s, m, rad, m s-1, rad s-1 (mjSTATE_FULLPHYSICS)",
                                                  "long_name": "MuJoCo's full physics state where the run "
                                                  "ended (time first)"}),
            "end_warmstart": (("dof",), end.warmstart, {"units": "m s-2 or rad s-2",
                                                        "long_name": "the solver's warm start there"}),
        }
    )


def _nan_run(scene: Scene, duration_s: float):
    """A NaN per-sample record and end state of the run's shapes (for a run that diverged)."""
    from ..simulation import Checkpoint, compile_scene, resolve_options, state_layout

    cs = compile_scene(scene, resolve_options(scene, _options(duration_s)))
    nan = np.full(1, np.nan)
    sr = {"time": nan, "joint_error": nan, "penetration": nan,
          "wall_force": np.full((1, len(cs.index.wall_names)), np.nan)}
    return sr, Checkpoint(np.full(state_layout(cs.model)[1], np.nan), np.full(cs.model.nv, np.nan))


class Resumes:
    """Stopped packing runs to go on from (:func:`packing_continue`), by point: each one's per-sample
    record up to its stop and its end state.  Its ``repr`` is a hash of that content, so it is part of
    the continuing sweep's identity: changed stopped runs make the continued ones stale."""

    def __init__(self, runs: dict[tuple[float, float, int], Any]):
        self._runs = {k: self._take(ds) for k, ds in runs.items()}

    @staticmethod
    def key(point: dict) -> tuple[float, float, int]:
        pt = PackingPoint.of(point)
        return round(pt.phi_max_rad, 9), round(pt.rho_tilde, 9), int(pt.draw)

    @staticmethod
    def _take(run) -> tuple[dict[str, np.ndarray], tuple[np.ndarray, np.ndarray]]:
        n = int(np.isfinite(run["series_time_s"].values).sum())
        sr = {"time": run["series_time_s"].values[:n], "joint_error": run["series_joint_error_rad"].values[:n],
              "wall_force": run["series_wall_force_N"].values[:n], "penetration": run["series_penetration_m"].values[:n]}
        return sr, (run["end_state"].values.copy(), run["end_warmstart"].values.copy())

    def get(self, point: dict):
        """``(record, Checkpoint)`` of the stopped run at ``point``."""
        from ..simulation import Checkpoint

        sr, (state, warm) = self._runs[self.key(point)]
        return sr, Checkpoint(state, warm)

    @property
    def sha256(self) -> str:
        """The hex digest of every stopped run's content, keys included."""
        import hashlib

        h = hashlib.sha256()
        for k in sorted(self._runs):
            sr, end = self._runs[k]
            h.update(repr(k).encode())
            for a in (*(sr[n] for n in sorted(sr)), *end):
                h.update(np.ascontiguousarray(a, dtype=float).tobytes())
        return h.hexdigest()

    def __repr__(self) -> str:
        return f"Resumes(sha256={self.sha256[:16]}, runs={len(self._runs)})"


def density_threshold(rho_tilde, excess, failed=None) -> tuple[float, float, float]:
    """Lowest density at which contact appears, along one phase draw.

    ``rho_tilde``: increasing densities; ``excess``: mean joint error minus
    the lone swimmer's minus the threshold (rad; > 0 means contact);
    ``failed``: runs that diverged or failed (left out of the search; their
    ``excess`` may be NaN).
    Returns ``(threshold, lo, hi)``: the first crossing among the runs that
    completed, interpolated linearly between the last density below and the
    first above, and the bracket ``[lo, hi]``; the threshold is NaN when a
    failed run lies inside the bracket (the crossing could be there).
    ``(nan, nan, rho[0])`` if the lowest density is already above;
    ``(nan, rho[-1], nan)`` if none is (``rho[-1]`` of the completed runs).
    """
    r_all = np.asarray(rho_tilde, dtype=float)
    e_all = np.asarray(excess, dtype=float)
    bad = np.zeros(r_all.shape, bool) if failed is None else np.asarray(failed, dtype=bool)
    ok = ~bad & np.isfinite(e_all)
    r, e = r_all[ok], e_all[ok]
    if len(r) == 0:
        return float("nan"), float("nan"), float("nan")
    above = e > 0
    if not above.any():
        return float("nan"), float(r[-1]), float("nan")
    i = int(np.argmax(above))
    if i == 0:
        return float("nan"), float("nan"), float(r[0])
    lo, hi = r[i - 1], r[i]
    if (~ok & (r_all > lo) & (r_all < hi)).any():
        return float("nan"), float(lo), float(hi)
    e0, e1 = e[i - 1], e[i]
    t = lo + (hi - lo) * (0.0 - e0) / (e1 - e0)
    return float(t), float(lo), float(hi)


THRESHOLD_INTERVAL_METHOD = "bracket ends, t on the draws' spread, scaled logit of rho~ / (2A/w)"


def threshold_estimate(threshold, lo, hi, rho_max: float) -> stats.Estimate:
    """The threshold density of one phase spread over its phase draws, with an interval inside the
    densities a scene can have, ``(0, rho_max)`` (``rho_max = 2A/w``: at ``rho~ = 2AN/Y = 2A/w`` the
    ``N`` straight bodies of width ``w`` fill the channel; a density is never negative).

    ``threshold``, ``lo``, ``hi``: per draw, the interpolated threshold and its bracket (the last grid
    density without contact and the first with, :func:`density_threshold`); draws without a finite
    threshold are left out.  On the scaled logit ``z(rho) = log(rho / (rho_max - rho))``: the value is
    ``z^-1(mean z(threshold))``; the interval is ``[z^-1(mean z(lo) - q s), z^-1(mean z(hi) + q s)]``,
    ``s`` the standard error of ``mean z(threshold)`` over the draws and ``q`` Student's t quantile on
    ``n - 1`` degrees of freedom at the level of this look (:func:`undulate.stats.level`).

    Why this method (the draws are few: 1 to 5 per spread; at one full-mode look, 2 at 99.5 %, the
    previous t interval of the plain mean, 3.42 [-2.02, 8.86], left the domain on both sides):

    * a bootstrap over 2 to 5 draws cannot reach beyond their range (with 2 draws the range covers the
      median draw half the time, whatever level it is given), whereas Student's t keeps its level on
      few draws where their spread is near normal;
    * a density lies in ``(0, rho_max)``, and near either end its spread is squeezed: on the scaled
      logit the interval maps back inside that domain whatever its width, and it is the plain t
      interval where the thresholds lie far from both ends (the logit is nearly linear there);
    * the crossing of each draw lies somewhere in its bracket ``[lo, hi]`` whatever the interpolation,
      so the bracket ends bound the mean's position (the lower end from the lower ends, the upper
      from the upper ones: the grid's resolution), while the draws' spread is read from the
      interpolated thresholds: their bracket ends tie on the grid (two draws 0.08 apart in one
      0.25-wide bracket), and a spread read from them would be zero.  Draws that agree exactly (every
      draw at ``phi_max = 0`` is the same in-phase group) leave the bracket itself.

    No interval with fewer than 2 draws, or where a bracket end lies outside ``(0, rho_max)``."""
    from scipy import stats as st

    t, a, b = (np.asarray(v, float).ravel() for v in (threshold, lo, hi))
    ok = np.isfinite(t) & np.isfinite(a) & np.isfinite(b)
    t, a, b = t[ok], a[ok], b[ok]
    n, method = int(t.size), THRESHOLD_INTERVAL_METHOD
    if n == 0:
        return stats.Estimate(float("nan"), n=0, method=method)
    rho_max = float(rho_max)
    inside = bool(np.all((a > 0) & (b < rho_max) & (t > 0) & (t < rho_max)))
    if n < 2 or not inside:
        return stats.Estimate(float(np.mean(t)), n=n, method=method if inside else
                              method + "; a bracket outside (0, 2A/w): no interval")

    def z(r):
        return np.log(r / (rho_max - r))

    def back(v):
        return float(rho_max / (1.0 + np.exp(-v)))

    zt = z(t)
    s = float(zt.std(ddof=1) / np.sqrt(n))
    conf = stats.level()
    q = float(st.t.ppf((1 + conf) / 2, n - 1))
    value = back(zt.mean())
    low, high = back(z(a).mean() - q * s), back(z(b).mean() + q * s)
    return stats.Estimate(value, float(t.std(ddof=1) / np.sqrt(n)), low, high, n, method, conf, n, n - 1)


def _thresholds(p: PackingPlan, excess: np.ndarray, failed: np.ndarray):
    """:func:`density_threshold` for every (phi_max, draw): ``(threshold, lo, hi)`` arrays."""
    nphi, ndraw = excess.shape[0], excess.shape[2]
    thr, lo, hi = (np.full((nphi, ndraw), np.nan) for _ in range(3))
    for i in range(nphi):
        for k in range(ndraw):
            thr[i, k], lo[i, k], hi[i, k] = density_threshold(p.rho_tilde, excess[i, :, k], failed[i, :, k])
    return thr, lo, hi


def _stopped_brackets(p: PackingPlan, thr, lo, hi, stopped_at) -> list[tuple[int, int, int]]:
    """(phi_max, rho, draw) indices of the runs an interpolated threshold uses that stopped early."""
    col = {round(r, 9): j for j, r in enumerate(p.rho_tilde)}
    out = []
    for i, k in zip(*np.nonzero(np.isfinite(thr))):
        for r in (lo[i, k], hi[i, k]):
            j = col[round(float(r), 9)]
            if stopped_at[i, j, k] < p.duration_s - 1e-9:
                out.append((int(i), j, int(k)))
    return out


def walled_packing_density(phi_max_rad, w_over_2A, n_swimmers: int = N_SWIMMERS):
    """Closed-form density with the side walls' room (:func:`undulate.theory.walled_packing_density`)."""
    return theory.walled_packing_density(phi_max_rad, w_over_2A, n_swimmers)


class _Runs:
    """The runs known so far on the threshold grid (phi_max x rho~ x draw): their values and flags."""

    NAMES = ("mean_joint_error_rad", "channel_width_m", "max_penetration_m", "stopped_at_s")

    def __init__(self, p: PackingPlan, base_err: float):
        shape = (len(p.phi_max_rad), len(p.rho_tilde), p.draws)
        self.base_err, self.duration_s = base_err, p.duration_s
        self.stopped: dict[tuple[int, int, int], Any] = {}
        self.continued = 0  # runs continued from their stop to full length
        self.vals = {k: np.full(shape, np.nan) for k in self.NAMES}
        self.evaluated = np.zeros(shape, bool)
        self.diverged = np.zeros_like(self.evaluated)
        self.failed = np.zeros_like(self.evaluated)

    def take(self, i, j, k, run) -> None:
        """Record sweep result ``run`` at grid indices ``(i, j, k)`` (a run that stopped early is kept
        whole, to be continued if it brackets a threshold)."""
        if float(run["stopped_at_s"]) < self.duration_s - 1e-9:
            self.stopped[(i, j, k)] = run
        self.evaluated[i, j, k] = True
        self.diverged[i, j, k] = bool(run["diverged"] == 1)
        self.failed[i, j, k] = bool(run["run_failed"]) or self.diverged[i, j, k]
        for name in self.NAMES:
            self.vals[name][i, j, k] = float(run[name])

    def take_sweep(self, got, where) -> None:
        """Record a point sweep's results, ``where[n]`` the grid indices of its point ``n``."""
        for n, (i, j, k) in enumerate(where):
            self.take(i, j, k, got.isel(point=n))

    def excess(self):
        """Mean joint error above the lone swimmer's plus the threshold (rad; > 0: contact)."""
        return self.vals["mean_joint_error_rad"] - self.base_err - THRESHOLD_RAD

    def state(self, i, k) -> dict[int, bool | None]:
        """What :func:`bisection_probes` knows of (phi_max ``i``, draw ``k``)."""
        e = self.vals["mean_joint_error_rad"][i, :, k] - self.base_err - THRESHOLD_RAD
        return {j: (None if self.failed[i, j, k] or not np.isfinite(e[j]) else bool(e[j] > 0))
                for j in range(e.size) if self.evaluated[i, j, k]}


def _points(p: PackingPlan, where) -> list[dict]:
    """Sweep points of the grid indices ``where`` (``(i, j, k)``: phi_max, rho~, draw)."""
    return [{"phi_max_rad": p.phi_max_rad[i], "rho_tilde": p.rho_tilde[j], "draw": k} for i, j, k in where]


def _take_heatmap(runs: _Runs, p: PackingPlan, heat) -> None:
    """Reuse the heatmap's runs at the densities it shares with the threshold grid."""
    col = {round(r, 9): j for j, r in enumerate(p.rho_tilde)}
    for jh, r in enumerate(p.heatmap_rho):
        if round(r, 9) in col:
            for i in range(len(p.phi_max_rad)):
                for k in range(p.heatmap_draws):
                    runs.take(i, col[round(r, 9)], k, heat.isel(phi_max_rad=i, rho_tilde=jh, draw=k))


def _bisect(ctx: StudyContext, p: PackingPlan, fn, runs: _Runs) -> int:
    """Bisection over density, all (phi_max, draw) searches side by side, one sweep a round;
    returns the number of rounds."""
    from ..sweep import Grid

    nphi, nrho, ndraw = len(p.phi_max_rad), len(p.rho_tilde), p.draws
    rounds = 0
    while True:
        probes = [(i, j, k) for i in range(nphi) for k in range(ndraw) for j in bisection_probes(runs.state(i, k), nrho)]
        if not probes:
            return rounds
        rounds += 1
        got = ctx.sweep(f"bisection-{rounds}", fn, Grid(points=_points(p, probes), seed=ctx.seed))
        runs.take_sweep(got.isel(replicate=0), probes)


def _rerun_brackets(ctx: StudyContext, p: PackingPlan, cont, runs: _Runs):
    """Continue to full length, from where they stopped (``cont``: :func:`packing_continue` bound but
    for ``resume``), the runs that bracket a threshold and stopped early; returns the rounds of
    continuations and the final ``(threshold, lo, hi)``."""
    from ..sweep import Grid

    reruns = 0
    while True:
        thr, lo, hi = _thresholds(p, runs.excess(), runs.failed)
        todo = _stopped_brackets(p, thr, lo, hi, runs.vals["stopped_at_s"])
        if not todo:
            return reruns, (thr, lo, hi)
        reruns += 1
        points = _points(p, todo)
        resume = Resumes({Resumes.key(pt): runs.stopped[w] for pt, w in zip(points, todo)})
        # one store per set of stopped runs: a later look continues more of them (more draws), and a
        # shared store would hold one look's continuations at a time, each look discarding the other's
        got = ctx.sweep(f"brackets-{reruns}-{resume.sha256[:12]}", functools.partial(cont, resume=resume),
                        Grid(points=points, seed=ctx.seed))
        runs.take_sweep(got.isel(replicate=0), todo)
        runs.continued += len(todo)


def dataset(ctx: StudyContext, p: PackingPlan):
    """Run the packing study on plan ``p``: the free swimmer, then every (phi_max, rho~, draw)."""
    from ..sweep import Grid

    seed = ctx.seed
    lone = ctx.lone_swimmer()
    amp = float(lone["amplitude_m"])
    base_err = float(lone["mean_joint_error_rad"])

    full = functools.partial(packing_point, amplitude_m=amp, base_seed=int(seed),
                             n_swimmers=p.n_swimmers, duration_s=p.duration_s)
    fn = full if PACKING_STOP is None else functools.partial(full, stop=PACKING_STOP, lone_error_rad=base_err)
    # the heatmap: every phi_max at the heatmap densities, the first heatmap_draws draws (the
    # whole threshold grid by default, then this is the only sweep)
    grid = Grid(axes={"phi_max_rad": p.phi_max_rad, "rho_tilde": p.heatmap_rho,
                      "draw": list(range(p.heatmap_draws))}, seed=seed)
    heat = ctx.sweep("groups", fn, grid).isel(replicate=0)
    runs = _Runs(p, base_err)
    _take_heatmap(runs, p, heat)
    rounds = _bisect(ctx, p, fn, runs)
    cont = functools.partial(packing_continue, amplitude_m=amp, base_seed=int(seed),
                             n_swimmers=p.n_swimmers, duration_s=p.duration_s)
    reruns, thresholds = _rerun_brackets(ctx, p, cont, runs)
    return _assemble(p, runs, heat, thresholds, amp, int(seed), rounds, reruns)


def _assemble(p: PackingPlan, runs: _Runs, heat, thresholds, amp: float, seed: int, rounds: int, reruns: int):
    """The study's Dataset: the runs, the heatmap, the thresholds and the theory curves."""
    import xarray as xr

    geo = SwimmerGeometry()
    w2a = geo.width_m / (2 * amp)
    phi_fine = np.linspace(0.0, 2 * np.pi, 181)
    return xr.Dataset(
        {**_run_vars(runs, heat), **_threshold_vars(thresholds), **_theory_vars(p, phi_fine, w2a, seed),
         "lone_mean_joint_error": ((), runs.base_err, {"units": "rad",
                                                       "long_name": "mean joint error, lone swimmer"}),
         "amplitude": ((), amp, {"units": "m", "long_name": "gait amplitude A of a free swimmer"})},
        coords=_coords(p, phi_fine),
        attrs={
            "title": "packing of 50 swimmers: joint error over phase spread and density (paper Fig. 7)",
            "n_swimmers": p.n_swimmers,
            "threshold_rad": THRESHOLD_RAD,
            "w_over_2A": w2a,
            "duration_s": p.duration_s,
            "bisection_rounds": rounds,
            "stop_rule": "none" if PACKING_STOP is None else PACKING_STOP.rule,
            "runs_stopped_early": int((runs.vals["stopped_at_s"] < p.duration_s - 1e-9).sum()),
            "bracket_reruns": reruns,
            "bracket_runs_continued": runs.continued,
            "threshold_search": "whole grid" if bool(runs.evaluated.all()) else
                                "bisection over rho_tilde (heatmap runs reused; a failed run or a non-monotone "
                                "column: the whole column)",
            "short_channel_m": SHORT_CHANNEL_OVER_L * geo.length_m,
        },
    )


def _run_vars(runs: _Runs, heat) -> dict:
    """Data variables of the runs: on the threshold grid, then on the heatmap grid."""
    dims = ("phi_max", "rho_tilde", "draw")
    hdims = ("phi_max", "rho_heatmap", "heatmap_draw")
    return {
        "mean_joint_error": (dims, runs.vals["mean_joint_error_rad"], {
            "units": "rad", "long_name": "mean joint error (swimmers, joints, t >= 2 s); "
                                         "NaN: run failed or not run (see evaluated)"}),
        "evaluated": (dims, runs.evaluated, {"long_name": "run done (heatmap or threshold bisection)"}),
        "run_failed": (dims, runs.failed, {"long_name": "run diverged (DivergenceError) or failed"}),
        "diverged": (dims, runs.diverged, {"long_name": "run diverged (DivergenceError)"}),
        "channel_width": (dims, runs.vals["channel_width_m"], {
            "units": "m", "long_name": "channel width Y (2 A N / rho~)"}),
        "max_penetration": (dims, runs.vals["max_penetration_m"], {
            "units": "m", "long_name": "deepest interpenetration"}),
        "heatmap_joint_error": (hdims, heat["mean_joint_error_rad"].values, {
            "units": "rad", "long_name": "mean joint error on the heatmap grid; NaN: run failed"}),
        "heatmap_failed": (hdims, heat["run_failed"].values.astype(bool) | (heat["diverged"].values == 1), {
            "long_name": "heatmap run diverged or failed"}),
    }


def _threshold_vars(thresholds) -> dict:
    """Data variables of the simulated thresholds per (phi_max, draw) and their brackets."""
    thr, lo, hi = thresholds
    one = {"units": "1"}
    return {
        "threshold_rho_tilde": (("phi_max", "draw"), thr, {
            **one, "long_name": "simulated compatibility threshold (first rho~ with excess joint error)"}),
        "threshold_lo": (("phi_max", "draw"), lo, {**one, "long_name": "last density below threshold"}),
        "threshold_hi": (("phi_max", "draw"), hi, {**one, "long_name": "first density above threshold"}),
    }


def _theory_vars(p: PackingPlan, phi_fine, w2a: float, seed: int) -> dict:
    """Data variables of the theory on ``phi_fine``: closed form, Monte Carlo, closed form with walls."""
    mc = theory.packing_density_mc(phi_fine, w2a, n_swimmers=p.n_swimmers, n_samples=4000, seed=seed)
    one = {"units": "1"}
    return {
        "rho_closed_form": (("phi_fine",), theory.packing_density(phi_fine, w2a), {
            **one, "long_name": "closed-form compatible density (paper Eq. rho_tilde)"}),
        "rho_monte_carlo": (("phi_fine",), mc.mean, {
            **one, "long_name": f"Monte-Carlo compatible density, N = {p.n_swimmers}"}),
        "rho_monte_carlo_stderr": (("phi_fine",), mc.stderr, {**one, "long_name": "its standard error"}),
        "rho_closed_form_walls": (("phi_fine",), walled_packing_density(phi_fine, w2a, p.n_swimmers), {
            **one, "long_name": "closed form with the side walls' room 2A"}),
    }


def _coords(p: PackingPlan, phi_fine) -> dict:
    """Coordinates of the study's Dataset."""
    one = {"units": "1"}
    return {
        "phi_max": ("phi_max", np.asarray(p.phi_max_rad), {"units": "rad", "long_name": "phase spread phi_max"}),
        "rho_tilde": ("rho_tilde", np.asarray(p.rho_tilde), {**one, "long_name": "normalised density 2AN/Y"}),
        "draw": ("draw", np.arange(p.draws), {**one, "long_name": "phase draw (replicate)"}),
        "rho_heatmap": ("rho_heatmap", np.asarray(p.heatmap_rho), {**one, "long_name": "heatmap density 2AN/Y"}),
        "heatmap_draw": ("heatmap_draw", np.arange(p.heatmap_draws), {**one, "long_name": "heatmap phase draw"}),
        "phi_fine": ("phi_fine", phi_fine, {"units": "rad", "long_name": "phase spread phi_max (theory)"}),
    }


def summary(ds) -> dict[str, Any]:
    """Pure: thresholds per phi_max (over the draws, :func:`threshold_estimate`), their rank correlation with
    phi_max (bootstrap interval), theory on the same phi_max, failures by phi_max."""
    thr = ds["threshold_rho_tilde"]
    mean, std = thr.mean("draw", skipna=True), thr.std("draw", skipna=True)
    phi = ds["phi_max"].values
    n_sw = int(ds.attrs["n_swimmers"])
    cf = theory.packing_density(phi, float(ds.attrs["w_over_2A"]))
    mc_on = np.interp(phi, ds["phi_fine"].values, ds["rho_monte_carlo"].values)
    walls = walled_packing_density(phi, float(ds.attrs["w_over_2A"]), n_sw)
    per_draw_phi = np.broadcast_to(phi[:, None], thr.shape)
    rel_all = (np.abs(ds["rho_closed_form"] - ds["rho_monte_carlo"]) / ds["rho_closed_form"]).values
    worst = int(np.nanargmax(rel_all))
    m = mean.values
    rel_mc = np.abs(ds["rho_closed_form"] - ds["rho_monte_carlo"]) / ds["rho_closed_form"]
    failed = ds["run_failed"]
    where = {}
    for i, ph in enumerate(phi):
        rows = np.flatnonzero(failed.values[i].any(axis=-1))
        if rows.size:
            where[f"{ph:.3f}"] = {"n_failed": int(failed.values[i].sum()),
                                  "rho_tilde_failed": [float(ds["rho_tilde"].values[j]) for j in rows]}
    out = {
        "amplitude_m": float(ds["amplitude"]),
        "lone_mean_joint_error_rad": float(ds["lone_mean_joint_error"]),
        "w_over_2A": float(ds.attrs["w_over_2A"]),
        "phi_max_rad": phi,
        "threshold_rho_tilde_mean": m,
        "threshold_rho_tilde_std": std.values,
        "threshold_rho_tilde": [threshold_estimate(thr.values[i], ds["threshold_lo"].values[i],
                                                   ds["threshold_hi"].values[i],
                                                   1.0 / float(ds.attrs["w_over_2A"])).to_dict()
                                for i in range(phi.size)],
        "threshold_n_draws": thr.notnull().sum("draw").values,
        "closed_form_rho_tilde": cf,
        "monte_carlo_rho_tilde": mc_on,
        "closed_form_walls_rho_tilde": walls,
        "threshold_bracket_lo_mean": ds["threshold_lo"].mean("draw", skipna=True).values,
        "threshold_bracket_hi_mean": ds["threshold_hi"].mean("draw", skipna=True).values,
        "threshold_above_grid": [bool(np.all(np.isnan(ds["threshold_hi"].values[i]))) for i in range(phi.size)],
        "spearman_threshold_vs_phi_max": stats.rank_correlation(per_draw_phi, thr.values).to_dict(),
        "largest_rise_of_threshold_between_neighbouring_phi_max": _largest_rise(m, ds),
        "max_rel_diff_closed_form_vs_monte_carlo": float(rel_mc.max()),
        "monte_carlo_rel_stderr_at_max_diff": float(ds["rho_monte_carlo_stderr"].values[worst]
                                                    / ds["rho_monte_carlo"].values[worst]),
        "n_runs": int(ds["evaluated"].sum()) if "evaluated" in ds else int(failed.size),
        "n_failed": int(failed.sum()),
        "n_diverged": int(ds["diverged"].sum()),
        "diverged_or_failed_by_phi_max": where,
        "threshold_rule": f"mean joint error > lone swimmer + {THRESHOLD_RAD} rad; "
                          "linear interpolation in rho~; runs that diverged or failed are left out (none expected)",
    }
    out.update(closed_form_ratios(out, float(np.max(ds["rho_tilde"].values))))
    return out


def closed_form_ratios(s: dict[str, Any], rho_grid_max: float) -> dict[str, Any]:
    """The simulated threshold over the closed form (paper Eq. rho_tilde) at each phi_max, and over the
    closed form with the walls' room, as estimates: the summary's threshold estimate (its interval,
    whatever method made it) divided by the closed form, an exact number.  ``rho_grid_max``: the densest
    grid point (a threshold above the grid lies above it)."""
    thr = [stats.Estimate.from_dict(t) for t in s["threshold_rho_tilde"]]
    return {
        "threshold_over_closed_form": [t.scaled(1.0 / float(c)).to_dict()
                                       for t, c in zip(thr, s["closed_form_rho_tilde"])],
        "threshold_over_closed_form_walls": [t.scaled(1.0 / float(c)).to_dict()
                                             for t, c in zip(thr, s["closed_form_walls_rho_tilde"])],
        "rho_tilde_grid_max": float(rho_grid_max),
    }


def _largest_rise(mean, ds) -> float:
    """Largest increase of the mean threshold from one phi_max to the next (a
    threshold above the density grid counts as larger than any); <= 0 when it
    never rises."""
    t = np.asarray(mean, float)
    above = np.all(np.isnan(ds["threshold_hi"].values), axis=-1) & ~np.isfinite(t)
    t = np.where(above, 1e9, t)
    t = t[~np.isnan(t)]
    return float(np.max(np.diff(t))) if t.size > 1 else float("nan")


E = stats.Estimate.from_dict
MC_TOL = 0.01
"""Largest relative difference allowed between the closed form and its Monte-Carlo estimate."""


def _no_rise(phi, thr: list[stats.Estimate], above_grid) -> list[stats.Check]:
    """"The mean threshold never rises from one phi_max to the next", step by step on the t intervals.

    A step rises beyond its uncertainty (its interval wholly above the previous one's) or into a threshold
    above the density grid (larger than any): fails.  A step whose mean rises inside overlapping intervals
    (or without an interval): undecided.  A step whose mean does not rise: no objection.  Thresholds that
    are neither finite nor above the grid are left out (as in the summary's largest rise)."""
    seq = [(f, None if up and not t.finite else t) for f, t, up in zip(phi, thr, above_grid) if t.finite or up]
    checks = []
    for (fa, a), (fb, b) in zip(seq, seq[1:]):
        what = f"mean threshold from phi_max = {fa:.2f} to {fb:.2f}"
        if a is None:  # from above the grid: b is no larger
            continue
        if b is None:
            checks.append(stats.Check.exact(False, f"{what}: rises above the density grid"))
            continue
        rise = stats.Check.apart(b, a, what)
        if rise.state is True:
            checks.append(stats.Check(False, f"{rise.text}: rises beyond the intervals"))
        elif rise.state is None and b.value > a.value:
            checks.append(stats.Check(None, f"{rise.text}: the mean rises inside the intervals"))
    return checks


def _threshold_falls(s: dict) -> Verdict:
    rho, rise = E(s["spearman_threshold_vs_phi_max"]), s["largest_rise_of_threshold_between_neighbouring_phi_max"]
    thr = [E(t) for t in s["threshold_rho_tilde"]]
    measured = ("simulated threshold rho~ at phi_max = "
                + ", ".join(f"{f:.2f}: {t:.3g}" for f, t in zip(s["phi_max_rad"], thr) if t.finite)
                + ("; above the densest grid point at phi_max = 0" if s["threshold_above_grid"][0] else "")
                + (f"; {s['n_diverged']} of {s['n_runs']} runs diverged" if s["n_diverged"] else "")
                + f"; Spearman rho {rho:+.2f} ({stats.interval_note(rho.level)})")
    value = {"spearman": s["spearman_threshold_vs_phi_max"], "largest_rise": rise}
    if not rho.has_interval or rise is None or not np.isfinite(rise):
        return Verdict.none("fewer than 3 thresholds within the density grid (no rank correlation interval)",
                            measured, value)
    return Verdict.of([rho.below(0.0, "Spearman rho"), *_no_rise(s["phi_max_rad"], thr, s["threshold_above_grid"])],
                      measured, value)


def _closed_form_matches(s: dict) -> Verdict:
    rel, se = s["max_rel_diff_closed_form_vs_monte_carlo"], s["monte_carlo_rel_stderr_at_max_diff"]
    # a deterministic (seeded) numerical check, no interval: exact, never undecided
    return Verdict.of([stats.Check.exact(rel < MC_TOL, f"largest relative difference {rel:.2%} (< {MC_TOL:.0%} "
                                                       "needed)")],
                      f"largest relative difference {rel:.2%} (Monte-Carlo standard error there {se:.2%})",
                      {"max_rel_diff": rel, "mc_rel_stderr": se})


CLOSED_FORM_TOL = 0.2
"""The simulated threshold "agrees" with the closed form when their ratio lies within 1 +- this: the
tolerance by which every study judges agreement of a measured proportion with the compatibility model
(the pairs' slope of dx against lambda dphi / 2 pi, ``_criteria.LINE_SLOPE_TOL``), not one of its own."""


def _threshold_near_closed_form(s: dict) -> Verdict:
    """Each phi_max's simulated threshold over the closed form within 1 +- :data:`CLOSED_FORM_TOL`."""
    lo_b, hi_b = 1 - CLOSED_FORM_TOL, 1 + CLOSED_FORM_TOL
    ratios = [E(r) for r in s["threshold_over_closed_form"]]
    walls = [E(r) for r in s["threshold_over_closed_form_walls"]]
    checks, shown, value = [], [], {}
    for f, r, w, cf, up in zip(s["phi_max_rad"], ratios, walls, s["closed_form_rho_tilde"], s["threshold_above_grid"]):
        what = f"phi_max = {f:.2f}: threshold / closed form"
        if r.finite:
            checks.append(r.within(lo_b, hi_b, what))
            shown.append(f"{f:.2f}: {r:.3g} (with the walls' room {w:.3g})")
            value[f"{f:.3f}"] = r.to_dict()
        elif up:  # no crossing on the grid: the ratio is above the densest point's
            least = s["rho_tilde_grid_max"] / float(cf)
            checks.append(stats.Check.exact(False, f"{what} > {least:.3g}: above the density grid")
                          if least > hi_b else stats.Check(None, f"{what} > {least:.3g} (above the density grid)"))
            shown.append(f"{f:.2f}: > {least:.3g} (above the grid)")
    measured = ("simulated threshold over the closed form at phi_max = " + "; ".join(shown)
                + f" ({stats.interval_note(next((r.level for r in ratios if r.finite), None))})")
    value = {"threshold_over_closed_form": value}
    if not checks:
        return Verdict.none("no phase spread with a simulated threshold", measured, value)
    return Verdict.of(checks, measured, value)


CLAIMS = (
    Claim("the density at which swimmers start to collide falls as the phase spread grows "
          "(more phase spread needs more lateral room)",
          "as the phase variation increases the lateral spacing must increase or swimmers collide",
          "the 95 % interval of Spearman's rho between per-draw threshold and phi_max lies below 0 and the "
          "mean threshold never rises from one phi_max to the next (a threshold above the grid counts as "
          "larger than any); fails if the rho interval lies wholly above 0 or a step rises beyond the t "
          "intervals (or above the grid); undecided if the rho interval straddles 0 or a step's mean rises "
          "inside overlapping intervals", _threshold_falls,
          quote=(r"Overall we find that as the phase variation within a swimming group increases the required "
                 r"lateral density within the group must increase or else swimmers will collide with each other."),
          where="Sec. III.E, Fig. 7b", bands={"spearman": (None, 0.0)}),
    Claim("the closed form for the compatible density matches the Monte-Carlo estimate",
          "the expected value calculation agrees extremely well with the Monte-Carlo simulation",
          f"largest relative difference below {MC_TOL:.0%} (a seeded numerical comparison: holds or fails, "
          "never undecided)", _closed_form_matches,
          quote=(r"We see in Figure~\ref{fig:spatial_packing}b that the expected value calculation agrees "
                 r"extremely well with the Monte-Carlo simulation."),
          where="Sec. III.E, Fig. 7b (the closed form for rho-tilde)", bands={"max_rel_diff": (None, MC_TOL)}),
    Claim("the simulated collision threshold agrees with the compatibility model's closed form",
          "the compatibility model agrees with the simulation results; Sec. III.E and Fig. 7b call the simulated "
          "threshold and the closed form for rho-tilde both the compatibility threshold, on the same axes (the "
          "abstract's sentence that packing is 'in agreement with the compatibility model' is commented out in "
          "paper.tex)",
          f"at every phi_max with a simulated threshold, the interval of its ratio to the closed form (paper Eq. "
          f"rho_tilde, at the free swimmer's A and w) lies within 1 +- {CLOSED_FORM_TOL:g}; a threshold above the "
          "density grid counts by its least possible ratio; fails if an interval (or that least ratio) lies wholly "
          "outside, undecided if one straddles a bound", _threshold_near_closed_form,
          quote=(r"We found considerable agreement between the compatibility model prediction and the experiment "
                 r"and simulation results."),
          where="Sec. IV (Summary and conclusions); for packing: Sec. III.E, Fig. 7b",
          bands={"threshold_over_closed_form": (1 - CLOSED_FORM_TOL, 1 + CLOSED_FORM_TOL)}),
)


def figure(ds):
    from ..plotting.packing import plot_packing

    return plot_packing(ds)


def stages(quick: bool) -> tuple[PackingPlan, ...]:
    """The plan in looks: more phase draws per look (quick 1, 2; full 2, 3, 5 draws, the heatmap's
    first 1, 2, 2), in full mode the phase spreads thinned too (4, 13, 13: every fourth of the cap's 13
    spreads first, as quick's first look of 4 spreads decides both claims; the second look then
    takes every spread)."""
    p = plan(quick)
    if quick:
        return tuple(PackingPlan(p.phi_max_rad, p.rho_tilde, draws=k, duration_s=p.duration_s, heatmap_rho=p.heatmap_rho,
                                 heatmap_draws=1) for k in (1, p.draws))
    looks = ((p.phi_max_rad[::4], 2, 1), (p.phi_max_rad, 3, p.heatmap_draws), (p.phi_max_rad, p.draws, p.heatmap_draws))
    return tuple(PackingPlan(phi, p.rho_tilde, draws=k, duration_s=p.duration_s, heatmap_rho=p.heatmap_rho,
                             heatmap_draws=h) for phi, k, h in looks)


register(Study(
    name="packing", paper_figure="7", plan=plan, stages=stages, dataset=dataset, summary=summary, claims=CLAIMS, figure=figure,
    description="50 swimmers in the short channel: mean joint error over phase spread and "
                "normalised density, the simulated compatibility threshold, and the "
                "closed-form and Monte-Carlo packing densities."))
