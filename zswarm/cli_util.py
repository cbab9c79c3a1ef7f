"""Command-line conventions shared by every zswarm program.

Usage errors print one line (``prog: error: what is wrong (see --help)``) and exit 2; user mistakes
found after parsing raise :class:`UsageError`, which :func:`run_main` turns into the same line.
"""

from __future__ import annotations

import argparse
import sys
from typing import Callable, NoReturn, Sequence

EXIT_USAGE = 2


class UsageError(Exception):
    """A mistake the user can fix (bad value, missing file, unknown scenario): one line, exit 2."""


class Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line on stderr and exit code 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see --help)\n")


def run_main(fn: Callable[[Sequence[str] | None], int], argv: Sequence[str] | None = None,
             prog: str = "zswarm") -> int:
    """Call ``fn(argv)``; turn a :class:`UsageError` or a ValueError from validation into exit 2."""
    from zswarm.params import ParamError

    try:
        return fn(argv)
    except (UsageError, ParamError) as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130


def add_param_args(parser: argparse.ArgumentParser) -> None:
    """``--set NAME=VALUE`` (repeatable) for any field of :mod:`zswarm.params`."""
    parser.add_argument("--set", dest="assignments", action="append", default=[], metavar="NAME=VALUE",
                        help="override a parameter (repeatable), e.g. --set c_o=3 --set l_a=1/2")
