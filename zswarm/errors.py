"""The two kinds of mistake a user can make and fix (one line on stderr, exit code 2, no traceback), and
a failure at run time that is nobody's typing mistake (one line, exit code 1)."""

from __future__ import annotations

EXIT_USAGE = 2
EXIT_FAILURE = 1


class UsageError(Exception):
    """A mistake the user can fix (bad value, missing file, unknown scenario): one line, exit 2."""


class ParamError(ValueError):
    """A parameter is unknown or out of its allowed range (message is one line, user-facing)."""


class Failure(Exception):
    """Something outside the program failed while it ran (a robot went silent): one line, exit 1."""
