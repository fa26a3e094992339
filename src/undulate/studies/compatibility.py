"""Study ``compatibility`` (paper Fig. 4): the gait-compatibility region, theory only.

The region of paper Eq. (fullcompatibility) on a grid of (dphi, dx/lambda,
dy/2A), with its sections at dy/2A = 0.2, 0.5, 0.9 (Fig. 4c).  The region is
written in normalised variables, so it holds for every amplitude A and
wavelength lambda (it is evaluated with A = 1/2, lambda = 1).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .. import theory
from ._context import StudyContext
from ._protocol import Study
from ._registry import register

if TYPE_CHECKING:
    import xarray as xr

SECTIONS_DY_OVER_2A = (0.2, 0.5, 0.9)


def _grid(quick: bool):
    n_phi, n_dx, n_dy = (121, 121, 13) if quick else (361, 401, 49)
    dphi = np.linspace(-np.pi, np.pi, n_phi)
    dxl = np.linspace(-1.0, 1.0, n_dx)
    dy = np.unique(np.round(np.concatenate([np.linspace(0.0, 1.2, n_dy), SECTIONS_DY_OVER_2A]), 12))
    return dphi, dxl, dy


def _trapezoid_weights(n: int) -> np.ndarray:
    """Weights of the trapezoid rule on n closed, equally spaced points (sum 1)."""
    w = np.ones(n)
    w[[0, -1]] = 0.5
    return w / w.sum()


def compatibility_dataset(dphi_rad, dx_over_lambda, dy_over_2A):
    """The region of paper Eq. (fullcompatibility) on the given axes, as an xarray Dataset.

    ``compatible(dphi, dx_over_lambda, dy_over_2A)``: bool;
    ``min_dy_over_2A(dphi, dx_over_lambda)``: the boundary surface
    ``|sin(psi/2)|`` (Eq. (sep)); ``compatible_fraction(dy_over_2A)``: area
    fraction of the (dphi, dx) plane that is compatible (trapezoid rule; the
    axes should span whole periods), and its closed form
    ``compatible_fraction_theory = 2 arcsin(min(dy/2A, 1)) / pi``.
    """
    import xarray as xr

    P, X, Y = np.meshgrid(dphi_rad, dx_over_lambda, dy_over_2A, indexing="ij")
    ok = theory.is_compatible(P, X, Y, amplitude_m=0.5, wavelength_m=1.0)
    min_dy = theory.min_lateral_separation(P[..., 0], X[..., 0], amplitude_m=0.5, wavelength_m=1.0)
    w = np.multiply.outer(_trapezoid_weights(len(dphi_rad)), _trapezoid_weights(len(dx_over_lambda)))
    frac = np.einsum("ij,ijk->k", w, ok.astype(float))
    frac_theory = 2.0 * np.arcsin(np.minimum(np.asarray(dy_over_2A), 1.0)) / np.pi

    one = {"units": "1"}
    return xr.Dataset(
        {
            "compatible": (("dphi", "dx_over_lambda", "dy_over_2A"), ok, {
                "long_name": "sinusoids never cross (paper Eq. fullcompatibility)",
                "description": "|wrap(dphi - 2 pi dx/lambda)| <= 2 arcsin(min(dy/2A, 1))"}),
            "min_dy_over_2A": (("dphi", "dx_over_lambda"), min_dy, {
                **one, "long_name": "required lateral separation / 2A, |sin(psi/2)| (Eq. sep)"}),
            "compatible_fraction": (("dy_over_2A",), frac, {
                **one, "long_name": "compatible fraction of the (dphi, dx) plane, numerical"}),
            "compatible_fraction_theory": (("dy_over_2A",), frac_theory, {
                **one, "long_name": "compatible fraction, closed form 2 arcsin(dy/2A) / pi"}),
        },
        coords={
            "dphi": ("dphi", np.asarray(dphi_rad, float), {
                "units": "rad", "long_name": "phase difference phi_b - phi_a"}),
            "dx_over_lambda": ("dx_over_lambda", np.asarray(dx_over_lambda, float), {
                **one, "long_name": "longitudinal offset (x_b - x_a) / wavelength"}),
            "dy_over_2A": ("dy_over_2A", np.asarray(dy_over_2A, float), {
                **one, "long_name": "lateral offset (y_b - y_a) / peak-to-peak amplitude 2A"}),
        },
        attrs={
            "title": "gait compatibility region of sinusoidal swimmers (paper Fig. 4)",
            "conventions": "y = A sin(2 pi x/lambda - omega t + phi); dx = x_b - x_a, "
                           "dphi = phi_b - phi_a, b the upper neighbour",
            "sections_dy_over_2A": np.asarray(SECTIONS_DY_OVER_2A),
        },
    )


def plan(quick: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The (dphi, dx/lambda, dy/2A) axes: quick 121 x 121 x 16, full 361 x 401 x 49+."""
    return _grid(quick)


def dataset(ctx: StudyContext, p) -> "xr.Dataset":
    return compatibility_dataset(*p)


def summary(ds) -> dict:
    """Pure: the section fractions against their closed form (a quadrature, no fit: no uncertainty)."""
    err = np.abs(ds["compatible_fraction"] - ds["compatible_fraction_theory"])
    sections = {
        f"{s:g}": {
            "compatible_fraction": float(ds["compatible_fraction"].sel(dy_over_2A=s)),
            "compatible_fraction_theory": float(ds["compatible_fraction_theory"].sel(dy_over_2A=s)),
            "max_phase_mismatch_rad": float(theory.max_phase_mismatch(s, 0.5)),
        }
        for s in SECTIONS_DY_OVER_2A
    }
    fully = ds["dy_over_2A"].where(ds["compatible"].all(("dphi", "dx_over_lambda")), drop=True)
    return {
        "sections": sections,
        "max_abs_fraction_error": float(err.max()),
        "smallest_dy_over_2A_all_compatible": float(fully.min()) if fully.size else None,
        "grid_shape": [int(n) for n in ds["compatible"].shape],
    }


def figure(ds):
    from ..plotting.compatibility import plot_compatibility

    return plot_compatibility(ds)


register(Study(
    name="compatibility", needs_simulation=False, paper_figure="4", plan=plan, dataset=dataset,
    summary=summary, figure=figure,
    description="Gait-compatibility region of two sinusoids in (dphi, dx/lambda, dy/2A) "
                "and its sections at dy/2A = 0.2, 0.5, 0.9."))
