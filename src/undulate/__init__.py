"""undulate: simulate and analyse active undulatory collectives.

Planar multi-link swimmers bend with a travelling wave, sit side by side in a
walled channel and interact only through contact (MuJoCo).  The public API
is listed here; everything else may change.

>>> import math
>>> from undulate import Scene, SimOptions, simulate, neighbour_offsets
>>> ds = simulate(Scene(phases_rad=(0.0, math.pi / 2)), SimOptions(duration_s=10))
>>> dx_over_lambda = neighbour_offsets(ds)["dx"] / ds.attrs["wavelength"]
"""

from __future__ import annotations

from . import _source
from .errors import DivergenceError, ParameterError, UndulateError
from .execution import Execution
from .params import Channel, ContactModel, Gait, Ground, Scene, Servo, SimOptions, SwimmerGeometry

_source.snapshot()  # the code this process runs: a result is never labelled with files edited later

__all__ = [
    # parameters
    "Gait",
    "SwimmerGeometry",
    "Servo",
    "Ground",
    "Channel",
    "ContactModel",
    "Scene",
    "SimOptions",
    "Execution",
    # errors
    "UndulateError",
    "ParameterError",
    "DivergenceError",
    # simulation (lazy: imports MuJoCo/xarray on first use)
    "simulate",
    "simulate_batch",
    "Checkpoint",
    "build",
    # studies and theory
    "theory",
    "studies",
    "run_study",
    "animate",
    # observables
    "neighbour_offsets",
    "dx_over_wavelength",
    "period_average",
    "steady_state",
    "gait_amplitude",
    "contact_impulse",
    "mean_contact_force",
]

_LAZY = {
    "theory": ("theory", None),
    "studies": ("studies", None),
    "run_study": ("studies", "run_study"),
    "animate": ("animation", "animate"),
    "simulate": ("simulation", "simulate"),
    "simulate_batch": ("simulation", "simulate_batch"),
    "Checkpoint": ("simulation", "Checkpoint"),
    "build": ("scene", "build"),
    "neighbour_offsets": ("observables", "neighbour_offsets"),
    "dx_over_wavelength": ("observables", "dx_over_wavelength"),
    "period_average": ("observables", "period_average"),
    "steady_state": ("observables", "steady_state"),
    "gait_amplitude": ("observables", "gait_amplitude"),
    "contact_impulse": ("observables", "contact_impulse"),
    "mean_contact_force": ("observables", "mean_contact_force"),
}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        mod, attr = _LAZY[name]
        module = importlib.import_module(f".{mod}", __name__)
        value = module if attr is None else getattr(module, attr)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'undulate' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
