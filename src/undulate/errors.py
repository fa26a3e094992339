"""Errors raised by undulate.

Every user-facing input is validated; a bad value raises
:class:`ParameterError`, whose message is one line naming the parameter,
what is allowed and what was given.  The CLI turns it into exit code 2.
A simulation that blows up raises :class:`DivergenceError` with a diagnosis.
"""

from __future__ import annotations


class UndulateError(Exception):
    """Base class of every error undulate raises on purpose."""


class ParameterError(UndulateError, ValueError):
    """An input parameter is outside what is allowed.

    Parameters
    ----------
    name:
        The parameter as the user knows it (a field or a CLI option).
    allowed:
        What is allowed, in words, with units (``"> 0 m"``).
    got:
        The offending value.
    """

    def __init__(self, name: str, allowed: str, got: object = None):
        self.name = name
        self.allowed = allowed
        self.got = got
        msg = f"invalid {name}: must be {allowed}"
        if got is not None:
            msg += f" (got {got!r})"
        super().__init__(msg)


class DivergenceError(UndulateError, RuntimeError):
    """The simulation produced non-finite values or deep interpenetration."""
