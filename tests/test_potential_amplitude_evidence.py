"""The potential study's claim "the contact impulse grows with the gait amplitude" and its evidence figures.

The criterion (:func:`undulate.studies.potential.impulse_by_amplitude` and its judge) is fed impulses built by
hand over one design of starts: one that holds, one that fails and one that is undecided, so each outcome is
reachable and a judge that ignored its data would fail here; the starts at dphi = 0 must not count.  Each
evidence figure of the study's own (``Claim.evidence``) is drawn from a constructed value and must be the
generic figure's width (560 px).  No simulation.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from undulate import stats
from undulate.errors import ParameterError
from undulate.studies import potential as P

DPHI = np.linspace(-np.pi, np.pi, 9)  # the quick impulse grid: 8 detuned, one at dphi = 0
N_PHI0 = 4


E = stats.Estimate.from_dict


def _claim(text):
    (c,) = [c for c in P.CLAIMS if c.claim == text]
    return c


def _impulse(per_beta_scale, noise=0.0, seed=0):
    """Impulse (beta, dphi, phi0), N s: ``scale |dphi|`` per beta, plus a start's own share common to
    every beta (so the paired difference cancels it) and independent noise."""
    rng = np.random.default_rng(seed)
    start = 0.01 * rng.random((DPHI.size, N_PHI0))  # the start's own share, the same at every beta
    return np.stack([s * np.abs(DPHI)[:, None] + start + noise * rng.standard_normal((DPHI.size, N_PHI0))
                     for s in per_beta_scale])


def _judge(imp, betas=(30.0, 45.0, 60.0)):
    s = {"impulse_by_amplitude": P.impulse_by_amplitude(betas, DPHI, imp)}
    return _claim(P.IMPULSE_AMPLITUDE_CLAIM).judge(s), s["impulse_by_amplitude"]


def test_impulse_by_amplitude_averages_the_detuned_starts_and_pairs_the_steps():
    imp = _impulse([0.01, 0.02, 0.03])
    imp[:, DPHI.size // 2, :] = 10.0  # dphi = 0: not a detuned start, never averaged
    d = P.impulse_by_amplitude([60.0, 30.0, 45.0], DPHI, imp[[2, 0, 1]])  # betas in any order
    assert d["n_starts"] == 8 * N_PHI0 and list(d["betas_deg"]) == [30.0, 45.0, 60.0]
    detuned = np.abs(DPHI) > 0
    for b, i in (("30", 0), ("45", 1), ("60", 2)):
        assert d["mean_impulse_Ns"][b]["value"] == pytest.approx(imp[i][detuned].mean(), rel=1e-12)
    # paired: each start's own share cancels, the step is exactly 0.01 |dphi| averaged, with no spread
    step = d["steps"]["30-45"]["increase_Ns"]
    assert step["value"] == pytest.approx(0.01 * np.abs(DPHI[detuned]).mean(), rel=1e-12)
    assert step["n"] == 8 * N_PHI0 and step["ci95"][0] > 0
    with pytest.raises(ParameterError, match="impulse"):
        P.impulse_by_amplitude([30.0, 45.0], DPHI, imp)


def test_impulse_amplitude_claim_holds_fails_and_is_undecided():
    ok, _ = _judge(_impulse([0.01, 0.02, 0.03], noise=1e-3))
    assert ok.verdict == "holds", ok
    # the largest amplitude pushes less than the middle one: that step's interval lies below 0
    down, d = _judge(_impulse([0.01, 0.02, 0.012], noise=1e-3))
    assert down.verdict == "fails" and E(d["steps"]["45-60"]["increase_Ns"]).high < 0
    # a step within the noise: its interval straddles 0, the other step holds
    flat, d = _judge(_impulse([0.01, 0.02, 0.02], noise=5e-3, seed=3))
    assert flat.verdict == "undecided" and "45-60" in flat.reason, flat
    assert E(d["steps"]["30-45"]["increase_Ns"]).low > 0
    # one amplitude only, or every start failed at one: nothing to compare
    one, _ = _judge(_impulse([0.01])[:1], betas=(45.0,))
    assert one.verdict == "no result"
    failed = _impulse([0.01, 0.02, 0.03])
    failed[1] = np.nan
    assert _judge(failed)[0].verdict == "no result"


def _row(claim, value, verdict="holds"):
    return {"study": "potential", "claim": claim.claim, "paper": claim.paper, "verdict": verdict, "value": value}


def _stiffness_summary():
    """Per beta k falling with d/2A (one width without a fit), their widths W and the amplitude pairs."""
    R = np.array([0.5, 0.6, 0.7, 0.8])
    amps = np.array([0.037, 0.052, 0.066])
    per_beta, K, W = {}, [], []
    for i, b in enumerate(("30", "45", "60")):
        k = np.exp(3.0 - 6.0 * R + 0.8 * i)
        k[-1] = math.nan
        w = P.channel_width_m(R, amps[i], 2)
        per_beta[b] = {"channel_width_m": w, "spearman_k_vs_d": stats.rank_correlation(R[:3], k[:3]).to_dict(),
                       "stiffness_N_per_m": [stats.Estimate(v, 0.1 * v, 0.7 * v, 1.3 * v, 5).to_dict() for v in k]}
        K.append(k)
        W.append(w)
    K, W = np.array(K), np.array(W)
    return {"d_over_2A": R, "per_beta": per_beta,
            "k_by_amplitude_at_width": P.stiffness_by_amplitude([30, 45, 60], amps, W, K, 0.1 * K, np.full(K.shape, 5))}


@pytest.mark.parametrize("text", ["the cohesion stiffness k falls as the channel widens", P.AMPLITUDE_CLAIM,
                                  P.IMPULSE_AMPLITUDE_CLAIM])
def test_each_evidence_function_draws_its_claims_value(text):
    from matplotlib.figure import Figure

    from undulate._evidence import DPI, WIDTH_IN

    c = _claim(text)
    assert c.evidence is not None
    v = (_judge(_impulse([0.01, 0.02, 0.03], noise=1e-3))[0] if text == P.IMPULSE_AMPLITUDE_CLAIM
         else c.judge(_stiffness_summary()))
    fig = c.evidence(_row(c, v.value, v.verdict))
    assert isinstance(fig, Figure) and len(fig.axes) == 2  # the data, and the judged number with its region
    assert fig.get_size_inches()[0] == pytest.approx(WIDTH_IN) and fig.dpi == DPI
    texts = " ".join(t.get_text() for t in fig.texts)
    assert c.paper[:30] in texts.replace("\n", " ")  # the paper's statement drawn above the panels
    main = fig.axes[0]
    if text != P.IMPULSE_AMPLITUDE_CLAIM:  # k over 1.3 decades: log y, one curve per beta
        assert main.get_yscale() == "log" and len(main.containers) == 3
        legend = " ".join(t.get_text() for lg in fig.legends for t in lg.get_texts())
        assert "β = 30°" in legend and ("ρ = " in legend) == (text != P.AMPLITUDE_CLAIM)
    # and from the claim's row as claims.json holds it (NaN written as None)
    import json

    from undulate.studies._staging import _jsonable

    row = json.loads(json.dumps(_jsonable(_row(c, v.value, v.verdict)), allow_nan=False))
    assert isinstance(c.evidence(row), Figure)
