"""Exceptions and warnings raised by hrtls.

Every problem with user input is an :class:`InputError` that names *what* is wrong, *where*
(file, line, column, stream, index or field) and *what was expected*. The CLI prints its message as
one line and exits non-zero. Repairs that change data (sorting, merging duplicates, dropping
invalid rows) are announced with a :class:`RepairWarning` and never done silently.
"""

from __future__ import annotations


class HrtlsError(Exception):
    """Base class of all errors raised on purpose by hrtls."""


class InputError(HrtlsError, ValueError):
    """Bad input: a malformed file, an invalid array or an inconsistent parameter.

    Parameters
    ----------
    problem:
        What is wrong, e.g. ``"time goes backwards by 0.02 s"``.
    where:
        Where it is, e.g. ``"imu.csv line 17"`` or ``"stream 'gyroscope' index 12"``.
    expected:
        What would have been accepted, e.g. ``"strictly increasing time"``.
    hint:
        Optional advice on how to fix it.
    """

    def __init__(self, problem: str, *, where: str = "", expected: str = "", hint: str = ""):
        self.problem = problem
        self.where = where
        self.expected = expected
        self.hint = hint
        super().__init__(self._compose())

    def _compose(self) -> str:
        text = f"{self.where}: {self.problem}" if self.where else self.problem
        if self.expected:
            text += f"; expected {self.expected}"
        if self.hint:
            text += f" ({self.hint})"
        return text


class UnitError(InputError):
    """A signal looks like it is in the wrong unit (g instead of m/s^2, deg/s instead of rad/s)."""


class FormatError(InputError):
    """A file is not in the format the reader expects, or its format cannot be detected."""


class RepairWarning(UserWarning):
    """Input was repaired (sorted, merged, dropped rows); the message says exactly what changed."""


class DegradedInputWarning(UserWarning):
    """A method runs with fewer sensors or observations than it was designed for."""
