"""Robots in the loop: the gaits of :mod:`undulate.control` on Dynamixel servos, logged like a simulation.

Optional extra: ``pip install 'undulate[robot]'`` (ROBOTIS's ``dynamixel-sdk``).
Protocol 1.0 (AX-12A, AX-18A: the paper's robots) and 2.0 (XL430-W250), every
joint of every robot on one bus.  See ``docs/robots.md`` for wiring,
calibration, safety and how it is tested (an emulated bus on a pseudo-terminal).

Public API (names load on first use, so ``undulate --help`` stays fast; the
SDK is imported only when a port is opened)::

    from undulate.robot import RobotConfig, run_robot, dry_run, load_calibration
"""

from __future__ import annotations

import importlib

_WHERE = {
    "RobotConfig": "runner", "run_robot": "runner", "dry_run": "runner", "ping": "runner",
    "schedule_text": "runner", "Interrupted": "runner", "BAUDRATES": "runner",
    "Calibration": "calibration", "JointCalibration": "calibration", "load_calibration": "calibration",
    "ServoModel": "servos", "SERVO_MODELS": "servos", "DEFAULT_SERVO": "servos", "servo_model": "servos",
    "BusError": "bus", "BusLost": "bus", "ServoSilent": "bus", "ServoFault": "bus", "ServoSetupError": "bus",
}

__all__ = list(_WHERE)


def __getattr__(name: str):
    if name in _WHERE:
        return getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(list(globals()) + __all__)
