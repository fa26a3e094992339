"""equal_amplitude_beta: the joint amplitude at which a free swimmer's body amplitude meets a target,
with the amplitude measured by any plain function of beta (the study passes its cached free swimmer)."""

from __future__ import annotations

import math

import pytest

from undulate.studies._gaits import A_TOL_M, curvature_beta, equal_amplitude_beta


def test_starts_from_the_curvature_rule_and_stops_there_when_it_meets_the_target():
    calls = []

    def amp(beta):
        calls.append(beta)
        return 0.05

    assert equal_amplitude_beta(amp, 9, 0.05 + A_TOL_M / 2) == (curvature_beta(9), 0.05)
    assert calls == [math.radians(45.0) * 3 / 9]


def test_secant_iteration_meets_a_nonlinear_amplitude_within_the_tolerance():
    def amp(beta):  # saturating, like a body whose amplitude grows sub-linearly with its joints
        return 0.09 * math.tanh(2.0 * beta)

    beta, a = equal_amplitude_beta(amp, 7, 0.0523)
    assert abs(a - 0.0523) <= A_TOL_M and a == pytest.approx(amp(beta))
    assert beta == round(beta, 9)  # rounded, so that cached runs are found again
