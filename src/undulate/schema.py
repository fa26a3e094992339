"""The trajectory schema: what a simulated, robot or tracked dataset calls its variables.

One public description of the recorded variables (name, dimensions, SI unit,
long name) and of the scene attributes every trajectory carries, shared by
:func:`undulate.simulate`, the robot logger (``undulate robot run``) and the
tracker (``undulate track``), so the three kinds of dataset line up name for
name.  This module imports neither MuJoCo nor OpenCV: a user reading a robot
log or a tracked video needs neither.

Recorded variables (dims; units in each variable's ``units`` attr):

=====================  ==========================  =================================
``x``, ``y``           time, swimmer               centre of mass, m
``heading``            time, swimmer               mean link orientation relative to
                                                   the start (head toward -x), rad
``node_x``, ``node_y`` time, swimmer, node          centre-line nodes head..tail, m
``joint_angle``        time, swimmer, joint        alpha, rad
``joint_command``      time, swimmer, joint        alpha_cmd, rad
``joint_error``        time, swimmer, joint        abs(alpha - alpha_cmd), rad
``contact_force_pair`` time, pair                  net swimmer-swimmer contact force
                                                   between swimmers p and p+1
                                                   (mean magnitude over the sample
                                                   interval), N
``contact_force_wall`` time, wall                  same for all swimmers on each wall, N
``penetration``        time                        deepest interpenetration over the
                                                   sample interval, m
``gait_phase``         time, swimmer               gait phase psi (unwrapped), rad
=====================  ==========================  =================================
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

if TYPE_CHECKING:  # annotations only: importing the schema builds nothing
    import xarray as xr

    from .params import Scene

__all__ = ["Variable", "VARIABLES", "RECORDABLE", "variable", "scene_attrs"]


class Variable(NamedTuple):
    """One recorded variable's dimensions, SI unit and long name."""

    dims: tuple[str, ...]
    units: str
    long_name: str


VARIABLES: dict[str, Variable] = {
    "x": Variable(("time", "swimmer"), "m", "centre of mass x"),
    "y": Variable(("time", "swimmer"), "m", "centre of mass y"),
    "heading": Variable(("time", "swimmer"), "rad", "mean link orientation relative to the start (0: head toward -x)"),
    "node_x": Variable(("time", "swimmer", "node"), "m", "centre-line node x, head to tail"),
    "node_y": Variable(("time", "swimmer", "node"), "m", "centre-line node y, head to tail"),
    "joint_angle": Variable(("time", "swimmer", "joint"), "rad", "joint angle alpha"),
    "joint_command": Variable(("time", "swimmer", "joint"), "rad", "commanded joint angle"),
    "joint_error": Variable(("time", "swimmer", "joint"), "rad", "joint error |alpha - alpha_cmd|"),
    "contact_force_pair": Variable(("time", "pair"), "N",
                                   "net contact force between swimmers pair and pair+1, interval mean"),
    "contact_force_wall": Variable(("time", "wall"), "N",
                                   "net contact force of all swimmers on each wall, interval mean"),
    "penetration": Variable(("time",), "m", "deepest interpenetration over the interval"),
    "gait_phase": Variable(("time", "swimmer"), "rad",
                           "gait phase psi, unwrapped: joint set-points beta sin(2 pi xi i / N - psi); "
                           "open loop psi = 2 pi f t - phi"),
}
"""Every variable a simulation can record, in the dataset's order."""

RECORDABLE: tuple[str, ...] = tuple(VARIABLES)
"""The recordable variable names, in the dataset's order (``SimOptions.record`` picks among them)."""


def variable(name: str, data) -> "xr.Variable":
    """``data`` as the schema's variable ``name``: its dims, ``units`` and ``long_name``."""
    import xarray as xr

    dims, units, long_name = VARIABLES[name]
    return xr.Variable(dims, data, attrs={"units": units, "long_name": long_name})


def scene_attrs(scene: "Scene") -> dict:
    """The scene's lengths and period as dataset attributes (SI, ``*_units`` beside them):
    ``wavelength`` (``inf`` for a standing wave), ``body_length``, ``link_width``,
    ``channel_width``, ``period``; one block for simulated, robot and tracked datasets."""
    g = scene.geometry
    return {
        "wavelength": scene.wavelength_m if math.isfinite(scene.wavelength_m) else math.inf,
        "wavelength_units": "m",
        "body_length": g.length_m,
        "body_length_units": "m",
        "link_width": g.width_m,
        "link_width_units": "m",
        "channel_width": scene.channel.width_m,
        "channel_width_units": "m",
        "period": scene.gait.period_s,
        "period_units": "s",
    }
