"""``eamos keys``: make the fleet's network keys (one CURVE key pair per participant)."""

from __future__ import annotations

import argparse
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from .errors import BadInput, command
from .exits import EXIT_OK
from .options import add_verbose

_KEYS_HELP = """\
Make one CURVE key pair per participant of a mission (each drone and the ground
station), in ZeroMQ's certificate format.  Either name the participants with
--fleet (keys go to OUT, by default your own folder for them:
$XDG_DATA_HOME/eamos/keys, that is ~/.local/share/eamos/keys, never the checkout),
or give a compiled mission or run folder (`eamos compile -o OUT`): the participants
are read from OUT/programs/*.program.json and the keys go to OUT/keys.

Layout: public/<name>.key (every public key), <name>/<name>.key_secret (the key
pair, mode 0600) and <name>/public/ (a copy of the public keys).  Ship <name>/
with participant <name>'s program and point its config at it: [net] keys = "...".
Only the fleet's keys can connect; traffic is encrypted.

Also OUT/mavlink_signing.key: the fleet's MAVLink 2 signing key (32 random bytes
as 64 hex digits, mode 0600).  Copy it to each MAVLink drone and give
[hal] signing_key = "<where it lands>" (docs/flying-real-drones.md, "Signing").
Exit code 2 on bad input."""


def add_keys_parser(sub: Any) -> None:
    """Add ``eamos keys`` to the ``eamos`` command's subparsers."""
    parser = sub.add_parser(
        "keys",
        help="make the fleet's network keys (CURVE key pairs)",
        description=_KEYS_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  eamos keys --fleet GCS Drone1 Drone2      "
        "# into ~/.local/share/eamos/keys\n"
        "  eamos compile missions/experiment_c.go && eamos keys out/experiment_c",
    )
    parser.add_argument(
        "out",
        metavar="OUT",
        type=Path,
        nargs="?",
        default=None,
        help="output (or compiled mission) folder; default with --fleet: "
        "$XDG_DATA_HOME/eamos/keys (~/.local/share/eamos/keys)",
    )
    parser.add_argument(
        "--fleet", nargs="+", metavar="NAME", help="participant names (the ground station is GCS)"
    )
    parser.add_argument("--force", action="store_true", help="replace existing keys")
    add_verbose(parser)
    command(parser, cmd_keys)


def default_keys_folder(env: Mapping[str, str] = os.environ) -> Path:
    """Where ``eamos keys --fleet ...`` puts a fleet's keys: a per-user folder.

    ``$XDG_DATA_HOME/eamos/keys`` (``~/.local/share/eamos/keys`` without it, as the
    XDG base directory specification says): secret keys never land in a checkout
    by default, where ``git add .`` would take them.
    """
    data = env.get("XDG_DATA_HOME", "")
    base = Path(data) if data and Path(data).is_absolute() else Path.home() / ".local" / "share"
    return base / "eamos" / "keys"


def cmd_keys(args: argparse.Namespace) -> int:
    """``eamos keys``; a :class:`~eamos.net.keys.KeysError` is bad input (exit 2)."""
    from eamos.hal.mavlink.signing import create_signing_key
    from eamos.net.keys import create_fleet_keys, participants_of_compiled
    from eamos.program.uniform import GROUND_STATION

    if args.fleet:
        names = list(dict.fromkeys(args.fleet))
        if GROUND_STATION not in names:
            names.insert(0, GROUND_STATION)  # the ground station is always a participant
        out = Path(args.out) if args.out is not None else default_keys_folder()
    elif args.out is None:
        raise BadInput(
            "name the participants (--fleet GCS Drone1 ...) or give a compiled "
            "mission folder (eamos keys out/MISSION)"
        )
    else:
        names = participants_of_compiled(args.out)
        out = Path(args.out) / "keys"
    create_fleet_keys(out, names, force=args.force)
    # A new key set (fresh, or --force): the signing key goes with it.
    signing = create_signing_key(out, force=True)
    print(f"keys for {', '.join(names)} in {out}/")
    for name in names:
        print(f'  {name}: ship {out / name}/  ([net] keys = "<where it lands>")')
    print(f'  MAVLink drones: ship {signing}  ([hal] signing_key = "<where it lands>")')
    print(f'  eamos rollout: [ground] keys = "{out}" in the fleet file')
    return EXIT_OK


__all__ = ["add_keys_parser", "cmd_keys", "default_keys_folder"]
