"""Errors raised by undulate.

Every user-facing input is validated; a bad value raises
:class:`ParameterError`, whose message is one line naming the parameter,
what is allowed and what was given.  The CLI turns it into exit code 2.
A simulation that blows up raises :class:`DivergenceError` with a diagnosis.
A file that cannot be written (a full disk, a quota) raises :class:`WriteError`.
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


class WriteError(UndulateError, OSError):
    """A file could not be written (the disk or a quota full, an I/O error); nothing of it was left.

    ``errno`` and ``strerror`` are the system's; ``filename`` is the file the user asked for."""

    def __init__(self, path, cause: OSError):
        import os

        self.folder = os.path.dirname(os.path.abspath(path))
        self.reason = cause.strerror or str(cause)
        super().__init__(cause.errno, f"could not write {path}: {self.reason}; nothing was written", str(path))

    def __reduce__(self):  # across processes (a sweep's worker): rebuilt from its path and cause
        return (type(self), (self.filename, OSError(self.errno, self.reason)))

    @property
    def disk_full(self) -> bool:
        """The disk or a quota is full (ENOSPC, EDQUOT): no further file would fit either."""
        import errno

        return self.errno in (errno.ENOSPC, errno.EDQUOT)

    def __str__(self) -> str:  # the free space when it is read (after the half-written file is removed)
        import shutil

        try:
            b = shutil.disk_usage(self.folder).free
            size = f"{b / 2**30:.3g} GiB" if b >= 2**30 else f"{b / 2**20:.3g} MiB"
            free = f" ({size} free at {self.folder})"
        except OSError:
            free = ""
        return f"could not write {self.filename}: {self.reason}{free}; nothing was written"
