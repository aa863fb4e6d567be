"""Option builders shared by every ``eamos`` command: one spelling, one meaning, one unit.

Each builder adds one option to an :mod:`argparse` parser, so ``--run-dir``,
``--speedup``, ``--svg/--no-svg``, ``-v/--verbose`` and the timeouts read and
behave the same in ``compile``, ``run``, ``rollout``, ``start``, ... .  Durations
are in seconds, always said by the metavar ``SECONDS``.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path


def positive_number(text: str) -> float:
    """argparse type for a finite number greater than zero (seconds, speed-ups)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):  # nan would never time out, inf never either
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    if not value > 0:
        raise argparse.ArgumentTypeError("must be greater than 0")
    return value


#: The longest duration an option takes: a week (a config's ``mission_timeout_s`` at most).
MAX_SECONDS = 7 * 86_400.0


def seconds_number(text: str) -> float:
    """argparse type for a duration option: a finite number of seconds, 0 < s <= a week."""
    value = positive_number(text)
    if value > MAX_SECONDS:
        raise argparse.ArgumentTypeError(
            f"must be at most {MAX_SECONDS:g} s (a week), got {text!r}"
        )
    return value


def speedup_number(text: str) -> float:
    """argparse type for ``--speedup``: as ``hal.speedup`` in a config, 0 < K <= 1000."""
    from eamos.config import MAX_SPEEDUP

    value = positive_number(text)
    if value > MAX_SPEEDUP:
        raise argparse.ArgumentTypeError(f"must be at most {MAX_SPEEDUP:g}, got {text!r}")
    return value


def add_mission(parser: argparse.ArgumentParser, *, path: bool = True) -> None:
    """The positional ``MISSION.go``."""
    parser.add_argument(
        "mission", metavar="MISSION.go", type=Path if path else str, help="the mission file"
    )


def add_verbose(
    parser: argparse.ArgumentParser, what: str = "tracebacks of internal errors"
) -> None:
    """``-v/--verbose``: an internal error's traceback is printed only with it."""
    parser.add_argument("-v", "--verbose", action="store_true", help=what)


def add_svg(parser: argparse.ArgumentParser, *, default: bool) -> None:
    """``--svg/--no-svg``: draw the graphs as SVG pictures (slow for big missions).

    Both spellings work on every command (``run --no-svg`` and ``rollout --svg``
    were the only ones before); only the default differs.
    """
    parser.add_argument(
        "--svg",
        action=argparse.BooleanOptionalAction,
        default=default,
        help=f"draw the graphs as SVG pictures (default: {'yes' if default else 'no'})",
    )


def add_check(parser: argparse.ArgumentParser) -> None:
    """``--check/--no-check``: fly the mission in virtual time first (``eamos check``).

    With an error finding the mission is refused (exit 1) unless ``--no-check``.
    """
    parser.add_argument(
        "--check",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="check the mission in virtual time first and refuse it on an error finding "
        "(default: yes; --no-check flies it anyway)",
    )


def add_run_dir(parser: argparse.ArgumentParser) -> None:
    """``--run-dir DIR``: where a run (or roll-out) writes its folder."""
    parser.add_argument(
        "--run-dir",
        type=Path,
        metavar="DIR",
        help="the run folder (default: runs/<mission>-<date-time>/)",
    )


def add_speedup(parser: argparse.ArgumentParser, *, default: float | None = None) -> None:
    """``--speedup K``: simulated time runs K times faster than real time."""
    shown = f"{default:g}" if default is not None else "1"
    parser.add_argument(
        "--speedup",
        type=speedup_number,
        default=default,
        metavar="K",
        help=f"simulated drones run K times faster than real time (default {shown})",
    )


def add_seconds(
    parser: argparse.ArgumentParser,
    flag: str,
    help_text: str,
    *,
    default: float | None = None,
    default_text: str | None = None,
) -> None:
    """A duration option (``--timeout``, ``--ready-timeout``, ``--listen``) in seconds.

    Finite, greater than 0 and at most :data:`MAX_SECONDS` (a week).
    """
    shown = default_text if default_text is not None else f"{default:g}" if default else None
    parser.add_argument(
        flag,
        type=seconds_number,
        default=default,
        metavar="SECONDS",
        help=f"{help_text} (seconds{f', default {shown}' if shown else ''})",
    )


def add_plain(parser: argparse.ArgumentParser) -> None:
    """``--plain``: plain progress lines instead of a live table."""
    parser.add_argument(
        "--plain", action="store_true", help="plain progress lines instead of a live table"
    )


def add_fleet_file(parser: argparse.ArgumentParser, *, required: bool) -> None:
    """The fleet file: positional ``FLEET.toml`` (rollout) or ``--fleet FLEET.toml`` (run)."""
    help_text = "the drones: hardware settings, and for a roll-out SSH hosts and folders"
    if required:
        parser.add_argument("fleet", metavar="FLEET.toml", type=Path, help=help_text)
    else:
        parser.add_argument(
            "--fleet",
            type=Path,
            metavar="FLEET.toml",
            help=f"{help_text} (default: every drone simulated)",
        )


__all__ = [
    "add_check",
    "add_fleet_file",
    "add_mission",
    "add_plain",
    "add_run_dir",
    "add_seconds",
    "add_speedup",
    "add_svg",
    "add_verbose",
    "positive_number",
    "seconds_number",
    "speedup_number",
]
