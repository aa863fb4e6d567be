#!/usr/bin/env python3
"""Benchmark of the wire messages alone: construct, encode, decode per kind; prints JSON.

``messages``: for one realistic message of every kind of :mod:`eamos.net.wire`, the
microseconds to build it with its constructor, to :func:`~eamos.net.wire.encode` it
and to :func:`~eamos.net.wire.decode` its frames, its payload's size, and the bare
``msgpack.unpackb`` of that payload (the floor under any decode).

``dataclass_reference``: the same for a Trigger and a Heartbeat written the other
way issue 26 allowed, standard ``@dataclass(frozen=True, slots=True)`` classes:
a plain constructor, encode by ``msgpack.packb`` of the keyed map, decode by
:func:`~eamos.net.wire.unpack_bounded`, the same envelope and key checks, one
check per field and the constructor.  It is the reference the choice of
``msgspec.Struct`` was measured against.

The script runs against any checkout whose ``eamos.net.wire`` has these message
classes (``PYTHONPATH`` picks it), so one version can be compared with another on
the same machine, alternately.  Each figure is the best of 5 repeats.

Usage: ``python scripts/bench_wire.py [--number N]`` (N calls per repeat, default 20000).
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import timeit
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import msgpack

if __package__ in (None, ""):  # run as a script: the checkout it lives in, unless PYTHONPATH says
    sys.path.append(str(Path(__file__).resolve().parents[1]))

from eamos.net import wire

M = "m-0123456789abcdef"
INC = 1_700_000_000_000_000 << 8


def samples() -> dict[str, Callable[[], Any]]:
    """One constructor call per kind, with values of the size a mission sends."""
    peers = {f"Drone{i}": 100 + i for i in range(1, 5)}
    report = {
        "drone": "Drone2",
        "aborted": False,
        "actions": [
            {
                "node": f"n{i}",
                "action": "FlyTo(1, 2, 3)",
                "status": "ok",
                "start_s": i,
                "end_s": i + 0.5,
            }
            for i in range(50)
        ],
        "final": {"x": 1.0, "y": 2.0, "z": 0.0, "armed": False},
    }
    detail = {
        "iteration": [2],
        "at": 1712345678.25,
        "earlier": [["running", "n3", "Arm()", {"at": 1.5}]],
    }
    return {
        "Trigger": lambda: wire.Trigger(
            M, "Drone1", "Drone2", "n12", "n13", (3,), "done", 17, incarnation=INC
        ),
        "Interrupt": lambda: wire.Interrupt(
            M, "Drone1", "Drone2", "7", (1, 0), "all", 18, incarnation=INC
        ),
        "TelemetrySample": lambda: wire.TelemetrySample(
            M,
            "Drone1",
            12.5,
            1.0,
            -2.0,
            10.25,
            47.39,
            8.54,
            510.0,
            87.5,
            True,
            False,
            incarnation=INC,
        ),
        "Ready": lambda: wire.Ready(M, "Drone1", "sha256:" + "ab" * 32, seq=1, incarnation=INC),
        "Start": lambda: wire.Start(M, "GCS", "d1", 1, incarnation=INC),
        "Abort": lambda: wire.Abort(M, "GCS", "operator pressed abort", 2, incarnation=INC),
        "Complete": lambda: wire.Complete(M, "GCS", 3, incarnation=INC),
        "Progress": lambda: wire.Progress(
            M, "Drone1", "ok", "n12", "FlyTo(1, 2, 3)", detail, incarnation=INC
        ),
        "Resolved": lambda: wire.Resolved(M, "Drone1", seq=4, incarnation=INC),
        "Report": lambda: wire.Report(M, "Drone2", report, seq=5, incarnation=INC),
        "ReportPart": lambda: wire.ReportPart(
            M, "Drone2", 1, 3, b"\x81" * 4096, seq=6, incarnation=INC
        ),
        "Ack": lambda: wire.Ack(M, "Drone2", "Drone1", 17, 2, True, INC + 1, incarnation=INC),
        "Heartbeat": lambda: wire.Heartbeat(
            M, "Drone1", peers, 3, False, peers, peers, peers, incarnation=INC
        ),
    }


def per_call(fn: Callable[[], Any], number: int) -> float:
    return round(min(timeit.repeat(fn, number=number, repeat=5)) / number * 1e6, 3)


def bench_messages(number: int) -> dict[str, dict[str, float]]:
    out = {}
    for kind, make in samples().items():
        msg = make()
        frames = wire.encode(msg)
        assert wire.decode(frames) == msg, kind
        out[kind] = {
            "construct_us": per_call(make, number),
            "encode_us": per_call(partial(wire.encode, msg), number),
            "decode_us": per_call(partial(wire.decode, frames), number),
            "msgpack_unpackb_us": per_call(partial(msgpack.unpackb, frames[1]), number),
            "payload_bytes": len(frames[1]),
        }
    return out


# -- the reference: standard slotted frozen dataclasses, msgpack, checks per field ------


def _name(value: Any) -> str:
    if type(value) is not str or not value or "/" in value:
        raise wire.WireError("expected a name")
    return value


def _seq(value: Any) -> int:
    if type(value) is not int or not 0 <= value < 1 << 63:
        raise wire.WireError("expected a seq")
    return value


def _str(value: Any) -> str:
    if type(value) is not str:
        raise wire.WireError("expected a str")
    return value


def _bool(value: Any) -> bool:
    if type(value) is not bool:
        raise wire.WireError("expected a bool")
    return value


def _iteration(value: Any) -> tuple[int, ...]:
    if type(value) is not list or any(type(i) is not int for i in value):
        raise wire.WireError("expected ints")
    return tuple(value)


def _status(value: Any) -> str:
    if value not in ("done", "skipped", "failed"):
        raise wire.WireError("expected a status")
    return str(value)


def _seq_map(value: Any) -> dict[str, int]:
    if type(value) is not dict:
        raise wire.WireError("expected a map")
    for key, item in value.items():
        _name(key)
        _seq(item)
    return value


@dataclass(frozen=True, slots=True)
class RefTrigger:
    mission: str
    sender: str
    dest: str
    src_node: str
    dst_node: str
    iteration: tuple[int, ...]
    status: str
    seq: int = 0
    incarnation: int = field(default=0, kw_only=True)


@dataclass(frozen=True, slots=True)
class RefHeartbeat:
    mission: str
    sender: str
    sent: dict[str, int] = field(default_factory=dict)
    bsent: int = 0
    leaving: bool = False
    acks: dict[str, int] = field(default_factory=dict)
    backs: dict[str, int] = field(default_factory=dict)
    known: dict[str, int] = field(default_factory=dict)
    incarnation: int = field(default=0, kw_only=True)


# Per class: its code, its topic, and (wire key, field name, check) per field.
REF: dict[type, tuple[str, Callable[[Any], bytes], tuple[tuple[str, str, Any], ...]]] = {
    RefTrigger: (
        "trg",
        lambda m: wire.topic_to(m.dest),
        (
            ("m", "mission", _str),
            ("s", "sender", _name),
            ("n", "incarnation", _seq),
            ("d", "dest", _name),
            ("sn", "src_node", _str),
            ("dn", "dst_node", _str),
            ("i", "iteration", _iteration),
            ("st", "status", _status),
            ("q", "seq", _seq),
        ),
    ),
    RefHeartbeat: (
        "hb",
        lambda m: wire.topic_heartbeat(m.sender),
        (
            ("m", "mission", _str),
            ("s", "sender", _name),
            ("n", "incarnation", _seq),
            ("hs", "sent", _seq_map),
            ("bs", "bsent", _seq),
            ("end", "leaving", _bool),
            ("ak", "acks", _seq_map),
            ("bk", "backs", _seq_map),
            ("ki", "known", _seq_map),
        ),
    ),
}
REF_BY_CODE = {code: cls for cls, (code, _topic, _fields) in REF.items()}
REF_KEYS = {
    cls: frozenset(k for k, _n, _c in fields) | {"v", "t"} for cls, (_c, _t, fields) in REF.items()
}


def ref_encode(msg: Any) -> list[bytes]:
    code, topic, fields = REF[type(msg)]
    body = {"v": wire.WIRE_VERSION, "t": code}
    for key, name, _check in fields:
        body[key] = getattr(msg, name)
    return [topic(msg), msgpack.packb(body, use_bin_type=True)]


def ref_decode(frames: list[bytes]) -> Any:
    topic, payload = frames
    body = wire.unpack_bounded(payload, wire.MAX_PAYLOAD_BYTES, 1 << 16, "not msgpack")
    if type(body) is not dict or body.get("v") != wire.WIRE_VERSION:
        raise wire.WireError("version")
    cls = REF_BY_CODE.get(body.get("t"))  # type: ignore[arg-type]
    if cls is None or body.keys() != REF_KEYS[cls]:
        raise wire.WireError("keys")
    _code, make_topic, fields = REF[cls]
    msg = cls(**{name: check(body[key]) for key, name, check in fields})
    if make_topic(msg) != topic:
        raise wire.WireError("topic")
    return msg


def bench_reference(number: int) -> dict[str, dict[str, float]]:
    peers = {f"Drone{i}": 100 + i for i in range(1, 5)}
    makers: dict[str, Callable[[], Any]] = {
        "Trigger": lambda: RefTrigger(
            M, "Drone1", "Drone2", "n12", "n13", (3,), "done", 17, incarnation=INC
        ),
        "Heartbeat": lambda: RefHeartbeat(
            M, "Drone1", peers, 3, False, peers, peers, peers, incarnation=INC
        ),
    }
    out = {}
    for kind, make in makers.items():
        msg = make()
        frames = ref_encode(msg)
        assert ref_decode(frames) == msg, kind
        out[kind] = {
            "construct_us": per_call(make, number),
            "encode_us": per_call(partial(ref_encode, msg), number),
            "decode_us": per_call(partial(ref_decode, frames), number),
            "payload_bytes": len(frames[1]),
        }
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--number", type=int, default=20000, help="calls per repeat")
    args = parser.parse_args()
    try:
        from importlib.metadata import version

        msgspec_version = version("msgspec")
    except Exception:  # a checkout before msgspec: the figures still stand
        msgspec_version = None
    out = {
        "python": platform.python_version(),
        "msgspec": msgspec_version,
        "wire_module": wire.__file__,
        "messages": bench_messages(args.number),
        "dataclass_reference": bench_reference(args.number),
    }
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
