"""Command-line conventions shared by every zswarm program.

Usage errors print one line (``prog: error: what is wrong (see --help)``) and exit 2; user mistakes
found after parsing raise :class:`UsageError`, which :func:`run_main` turns into the same line.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import sys
from typing import Any, Callable, NoReturn, Sequence

from zswarm.errors import EXIT_FAILURE, EXIT_USAGE, Failure, ParamError, UsageError
from zswarm.ports import LOOPBACK

__all__ = ["EXIT_USAGE", "Parser", "UsageError", "add_param_args", "positive_float", "positive_int", "positive_seconds",
           "run_main", "seconds",
           "seed_arg"]

class Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line on stderr and exit code 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see --help)\n")


def run_main(fn: Callable[[Sequence[str] | None], int], argv: Sequence[str] | None = None,
             prog: str = "zswarm") -> int:
    """Call ``fn(argv)``; turn a :class:`UsageError` or a ValueError from validation into exit 2."""
    try:
        code = fn(argv)
        sys.stdout.flush()  # here, where a reader that went away is caught below, not at exit
        return code
    except (UsageError, ParamError) as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except Failure as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return EXIT_FAILURE
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # its reader stopped reading (| head): no more to say, and no traceback at exit
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


def add_param_args(parser: argparse.ArgumentParser) -> None:
    """``--params FILE.toml`` and ``--set NAME=VALUE`` (repeatable) for any field of
    :mod:`zswarm.paper.params`; ``--set`` wins over the file, whatever their order."""
    parser.add_argument("--set", dest="assignments", action="append", default=[], metavar="NAME=VALUE",
                        help="override a parameter (repeatable), e.g. --set c_o=3 --set l_a=1/2")
    parser.add_argument("--params", dest="assignments", action=ParamsFile, metavar="FILE.toml",
                        help="parameter values from a TOML file (NAME = VALUE, at the top or under [params]), "
                             "e.g. the best.toml of zswarm tune; --set overrides them")


def add_law_arg(parser) -> None:
    """``--law NAME``: the control law, the same as ``--set law=NAME`` (``zswarm laws`` lists them)."""
    parser.add_argument("--law", dest="assignments", action=LawName, metavar="NAME",
                        help="the control law: apf (the paper's, default), olfati-saber, vasarhelyi, boids, "
                             "FILE.py:NAME, package.module:NAME or an installed one (zswarm laws lists them); "
                             "its parameters: --set law.NAME=VALUE")


class LawName(argparse.Action):
    """``--law NAME``: ``law=NAME`` after a params file's law, whatever the order (the law's own
    ``--set law.X`` are kept wherever they stand)."""

    meaning = "a law's name"

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        setattr(namespace, self.dest, list(getattr(namespace, self.dest) or []) + [f"law={values}"])


def law_name(text: str) -> str:
    """``--law NAME`` where a command takes the law's name alone (``zswarm laws`` lists them)."""
    return text


law_name.meaning = LawName.meaning  # type: ignore[attr-defined]


def read_params_file(path: str) -> list[str]:
    """A parameter file as ``NAME=VALUE`` strings (checked as --set values are, where they are used)."""
    from zswarm.files import read_toml

    data = read_toml(path, "parameter file")
    table = dict(data.get("params", data) if isinstance(data.get("params"), dict) else data)
    law = table.pop("law", None) or data.get("law")  # a [law] table beside [params], or a law = NAME
    out = []
    if isinstance(law, dict):  # [law]: name = "boids", and the law's own parameters
        law = dict(law)
        if "name" in law:
            out.append(f"law={law.pop('name')}")
        for name, value in law.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise UsageError(f"parameter file {path}: [law] {name} must be a number (got {value!r})")
            out.append(f"law.{name}={value!r}")
    elif law is not None:
        out.append(f"law={law}")
    for name, value in table.items():
        if isinstance(value, str):  # a name (interaction, body): checked where it is used, as a --set is
            out.append(f"{name}={value}")
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise UsageError(f"parameter file {path}: {name} must be a number or a name (got {value!r})")
        out.append(f"{name}={value!r}")
    return out


class ParamsFile(argparse.Action):
    """``--params FILE``: the file's values go before every ``--set``, so a --set always wins."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        try:
            items = read_params_file(str(values))
        except UsageError as exc:
            parser.error(str(exc))
        setattr(namespace, self.dest, items + list(getattr(namespace, self.dest) or []))


#: What ``rerun`` (the viewer) listens on for streamed recordings.
DEFAULT_VIEWER_URL = f"rerun+http://{LOOPBACK}:9876/proxy"


def is_viewer_url(text: str) -> bool:
    return text.startswith(("rerun+http://", "rerun+https://", "rerun://"))


class ZenohEndpoint(argparse.Action):
    """``--connect ENDPOINT`` / ``--listen ENDPOINT``: a Zenoh endpoint (``tcp/...``, ``tls/...``) in every
    command, appended (repeatable) or stored. A Rerun viewer URL is refused with the flag that takes it."""

    meaning = "a Zenoh endpoint"

    def __init__(self, option_strings, dest, append: bool = True, **kw) -> None:
        self.append = append
        super().__init__(option_strings, dest, **kw)

    def __call__(self, parser, namespace, value, option_string=None) -> None:
        if is_viewer_url(value):
            parser.error(f"{option_string} takes a Zenoh endpoint (tcp/HOST:PORT); to stream to a Rerun viewer "
                         f"give --viewer {value}")
        setattr(namespace, self.dest, [*(getattr(namespace, self.dest, None) or []), value] if self.append else value)


def viewer_url(text: str) -> str:
    """``--viewer [URL]``: a Rerun viewer's URL (``rerun+http://HOST:9876/proxy``)."""
    if not is_viewer_url(text):
        raise argparse.ArgumentTypeError(f"expected a Rerun viewer URL like {DEFAULT_VIEWER_URL}, got {text!r}")
    return text


viewer_url.meaning = "a Rerun viewer URL"  # type: ignore[attr-defined]


class Renamed(argparse.Action):
    """An old spelling, refused in one line that names the new one (kept out of ``--help``)."""

    def __init__(self, option_strings, dest, hint: str, **kw) -> None:
        self.hint = hint
        super().__init__(option_strings, argparse.SUPPRESS, nargs="?", help=argparse.SUPPRESS, **kw)

    def __call__(self, parser, namespace, value, option_string=None) -> None:
        parser.error(f"{option_string} is no longer a flag of this command: {self.hint}")


def renamed(parser: argparse.ArgumentParser, old: str, hint: str) -> None:
    """Refuse ``old`` on ``parser`` with ``hint`` (e.g. "give --seeds N")."""
    parser.add_argument(old, action=Renamed, hint=hint)


MAX_SEED = 2**63


def seed_arg(text: str) -> int:
    """A ``--seed``: an integer in [0, 2^63), what numpy's generators accept (every program's)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid int value {text!r}: a seed is an integer in [0, 2^63)") from None
    if not 0 <= value < MAX_SEED:
        raise argparse.ArgumentTypeError(f"a seed is an integer in [0, 2^63) (got {text!r})")
    return value


def non_negative(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text!r}")
    return value


def positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text!r}")
    return value


#: A duration: a number (a sign only to be refused by name), then a unit or none.
_DURATION = re.compile(r"^\s*(-?[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*(ms|s|min|h)?\s*$")
_UNIT = {"ms": 1 / 1000, "s": 1.0, "min": 60.0, "h": 3600.0}


def duration_seconds(text: str, bare: str = "s", units: Sequence[str] = tuple(_UNIT)) -> float | None:
    """``text`` in seconds: a number with one of ``units``, or with none (then it is in ``bare``); None
    when it is no such thing. Every duration zswarm reads goes through here."""
    m = _DURATION.match(str(text))
    if m is None or (m.group(2) is not None and m.group(2) not in units):
        return None
    unit = m.group(2) or bare
    return float(m.group(1)) / 1000.0 if unit == "ms" else float(m.group(1)) * _UNIT[unit]


def counted(n: int, noun: str) -> str:
    """``n`` and ``noun`` as a line says it: "1 node", "3 nodes"."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def seconds(text: str, positive: bool = False) -> float:
    """A duration flag's value in seconds: a bare number is seconds; ``500ms``, ``30s``, ``2min`` and
    ``1h`` say their unit; ``positive``: above zero, which the refusal of any other value says. (Fault
    delays, ``--latency`` and ``--jitter``, take no bare number but 0: they are given in ms or s, and say
    which.)"""
    value = duration_seconds(text)
    if value is None:
        raise argparse.ArgumentTypeError(f"expected a duration like 30, 30s, 500ms or 2min, got {text!r}")
    if not math.isfinite(value) or value < 0 or (positive and value == 0):
        raise argparse.ArgumentTypeError(f"expected a duration {'> 0' if positive else '>= 0'}, got {text!r}")
    return value


def positive_seconds(text: str) -> float:
    """:func:`seconds`, above zero."""
    return seconds(text, positive=True)


def sim_seconds(text: str) -> float:
    """``--duration``: simulated time, in seconds (:func:`positive_seconds`); the wall clock's flags are
    named otherwise (``--stop-after``)."""
    return positive_seconds(text)


def wall_seconds(text: str) -> float:
    """``--stop-after``: wall-clock time, in seconds (:func:`positive_seconds`)."""
    return positive_seconds(text)


#: The safety filter's modes (``zswarm.control.safety`` takes them from here: a flag's values are known
#: below the layer that acts on them).
SAFETY_MODES: tuple[str, ...] = ("off", "barrier")


def safety_modes(text: str) -> tuple[str, ...]:
    """``--safety``: the safety filter's modes, ``off`` and ``barrier``, as a comma-separated list (one
    where a command runs one, :func:`safety_mode_arg`)."""
    modes = tuple(dict.fromkeys(m.strip() for m in str(text).split(",") if m.strip()))
    if not modes or any(m not in SAFETY_MODES for m in modes):
        raise argparse.ArgumentTypeError(f"expected {' or '.join(SAFETY_MODES)}, or a comma-separated list of them, "
                                         f"got {text!r}")
    return modes


def safety_mode_arg(text: str) -> str:
    """``--safety`` where a command runs one mode: the same form, one item (a sweep compares several)."""
    modes = safety_modes(text)
    if len(modes) > 1:
        raise argparse.ArgumentTypeError(f"this command runs one filter mode, got {text!r}; zswarm sweep --safety "
                                         f"{','.join(modes)} runs each")
    return modes[0]


safety_modes.meaning = safety_mode_arg.meaning = "safety filter modes"  # type: ignore[attr-defined]


def agent_count(text: str) -> int:
    """``--agents N``: a number of agents, >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of agents, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a number of agents >= 1, got {text!r}")
    return value


def loss_probability(text: str) -> float:
    """``--dropout P``: the probability that a message is lost, in [0, 1)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a loss probability in [0, 1), got {text!r}") from None
    if not 0.0 <= value < 1.0:
        raise argparse.ArgumentTypeError(f"expected a loss probability in [0, 1), got {text!r}")
    return value


def router_count(text: str) -> int:
    """``--routers K``: a number of routers, 1 to :data:`MAX_ROUTERS`."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if not 1 <= value <= MAX_ROUTERS:
        raise argparse.ArgumentTypeError(f"expected a number of routers from 1 to {MAX_ROUTERS}, got {text!r}")
    return value


#: The most routers one run meshes.
MAX_ROUTERS = 64
router_count.meaning = "a number of routers"  # type: ignore[attr-defined]
agent_count.meaning = "numbers of agents"  # type: ignore[attr-defined]
loss_probability.meaning = "loss probabilities"  # type: ignore[attr-defined]


def list_of(one: Callable[[str], Any]) -> Callable[[str], list]:
    """The flag that takes a comma-separated list of what ``one`` takes (at least one item), where a
    command runs several settings: the same meaning, so the flag keeps one name everywhere."""
    def many(text: str) -> list:
        return [one(x) for x in str(text).split(",") if x.strip()] or [one(text)]

    many.__name__ = f"{one.__name__}_list"
    many.meaning = one.meaning  # type: ignore[attr-defined]
    return many


agent_counts = list_of(agent_count)  # --agents N1,N2,... where a command measures several swarm sizes
loss_probabilities = list_of(loss_probability)  # --dropout P1,P2,... where a command sweeps several
sim_seconds.meaning = "simulated seconds"  # type: ignore[attr-defined]
wall_seconds.meaning = "wall-clock seconds"  # type: ignore[attr-defined]


def positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}")
    return value


def id_ranges(ids: Sequence[int]) -> str:
    """0-5, 8, 10-12."""
    parts, start = [], None
    for k, i in enumerate(ids):
        if start is None:
            start = i
        if k + 1 == len(ids) or ids[k + 1] != i + 1:
            parts.append(str(start) if start == i else f"{start}-{i}")
            start = None
    return ", ".join(parts)
