"""Gait physics shared by studies and explorations: the joint amplitude that gives a body amplitude.

Not a study (the registry loads only public modules).  :func:`equal_amplitude_beta`
takes the amplitude measurement as a plain function of the joint amplitude, so
that a study can pass its cached free swimmer (``ctx.lone_swimmer``) and a
script the runner itself (:func:`undulate.studies._runners.lone_swimmer`).
"""

from __future__ import annotations

import math
from collections.abc import Callable

__all__ = ["A_TOL_M", "BETA_DEG", "curvature_beta", "equal_amplitude_beta"]

BETA_DEG = 45.0
"""The 3-link body's joint amplitude, deg (the default gait)."""
A_TOL_M = 1e-4
"""The equal-A rule's tolerance on the free swimmer's amplitude, m."""


def curvature_beta(n_links: int) -> float:
    """The links study's curvature rule, 45 deg x 3/N (rad): the start of :func:`equal_amplitude_beta`."""
    return math.radians(BETA_DEG) * 3.0 / n_links


def equal_amplitude_beta(amplitude_m: Callable[[float], float], n_links: int,
                         target_m: float) -> tuple[float, float]:
    """beta(N) (rad) at which the free N-link swimmer's amplitude A equals ``target_m``; and that A.

    ``amplitude_m(beta)``: the free swimmer's body amplitude A (m) at joint amplitude ``beta`` (rad),
    for the N-link body and gait in question (e.g. with its yaw recoil removed).  Secant iteration
    from the curvature rule's 45 deg x 3/N (:func:`curvature_beta`) and its proportional correction,
    to :data:`A_TOL_M` (at most six measurements; betas rounded to 1e-9 rad, so that cached runs
    are found again).
    """
    b0 = curvature_beta(n_links)  # exactly the links study's curvature rule (shared free swimmer)
    a0 = amplitude_m(b0)
    if abs(a0 - target_m) <= A_TOL_M:
        return b0, a0
    b1 = round(b0 * target_m / a0, 9)
    a1 = amplitude_m(b1)
    for _ in range(4):
        if abs(a1 - target_m) <= A_TOL_M or a1 == a0:
            break
        b0, a0, b1 = b1, a1, round(b1 + (target_m - a1) * (b1 - b0) / (a1 - a0), 9)
        a1 = amplitude_m(b1)
    return b1, a1
