"""The link-number trend: the free bodies are not the lab-frame travelling sinusoids the model assumes."""

from __future__ import annotations

from ... import stats
from .._sensitivity_design import CaseId, CaseSet, Plan
from ._protocol import CaseExplanation, CaseResults, Shown, all_of, negate, state_word

LINK_SETS = (CaseSet.LINKS, CaseSet.LINKS_X, CaseSet.LINKS_GUIDED, CaseSet.LINKS_GUIDED_X)
"""The four link-number sets, each over the plan's N: equal-A with lambda = L and lambda_x; the same with
the yaw recoil removed."""

CASES = tuple(CaseId.of(s, n_links=n) for s in LINK_SETS for n in Plan.links)

CAUSE = (
    "the compatibility model assumes each body is a lab-frame travelling sinusoid y = A sin(2 pi x / lambda - "
    "omega t). Our free bodies are not, in two ways that do not shrink with N: on isotropic drag a free body turns "
    "back and forth as it bends (yaw recoil: its head-to-tail chord swings by about +-0.1 rad at every N), which "
    "adds a standing wave to its lab-frame shape (an N = 9 body's lateral excursion runs 20-52 mm along it instead "
    "of a uniform 39 mm), and its wavelength along the channel, lambda_x (the head-to-tail extent), is 0.92-0.95 L, "
    "not L. The links study's amplitude rules also change A, and so the confinement, with N. Shown only if, with "
    "A held at the 3-link value (equal-A rule), the yaw recoil removed by a heading guide (only that changed in "
    "the model) and the line drawn with the lambda_x measured in the runs, the error falls with N by the claim's "
    "own criterion, while the equal-A runs with lambda = L or lambda_x, and the recoil-free runs with lambda = L, "
    "do not.")


def _text(entry: dict) -> str:
    E = stats.Estimate.from_dict
    return (f"{entry['label']}: RMS / lambda " + ", ".join(f"{E(r):.4f}" for r in entry["rms_residual_over_lambda"])
            + " at N = " + ", ".join(str(n) for n in entry["n_links"])
            + f" (falls: {state_word(entry['falls'], entry.get('falls_verdict'))})")


def judge(r: CaseResults) -> Shown:
    """Shown: the trend appears when the bodies are what the compatibility model assumes (no recoil,
    lambda the wavelength along the channel), and neither change alone makes it appear; undecided while
    one of the four trends is (overlapping intervals, or one missing)."""
    sets = {s: r.link_set(s) for s in LINK_SETS}
    if any(v is None for v in sets.values()):
        return False, "not every link-number set (equal-A; lambda = L and lambda_x; recoil and none) in this plan", None
    guided, guided_x = sets[CaseSet.LINKS_GUIDED], sets[CaseSet.LINKS_GUIDED_X]
    measured = ("; ".join(_text(v) for v in sets.values()) + " (A = "
                + ", ".join(f"{a * 1000:.1f}" for a in guided["amplitude_m"]) + " mm with the recoil removed; "
                "lambda_x / L " + ", ".join(f"{v:.3f}" for v in guided_x["wavelength_over_L"]) + ")")
    falls = {s.value: v["falls"] for s, v in sets.items()}
    shown = all_of(falls["links-guided-x"], negate(falls["links"]), negate(falls["links-x"]),
                   negate(falls["links-guided"]))
    return shown, measured, falls


EXPLANATIONS = tuple(
    CaseExplanation(study="links", claim=f"error from compatibility falls as links are added ({rule})",
                    cause=CAUSE, cases=CASES, judge=judge)
    for rule in ("joint amplitude 45 deg at every N", "joint amplitude 45 deg x 3/N"))
