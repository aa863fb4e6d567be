"""Final reports of any size: one Report message, or ReportParts joined again (pure).

A drone's report grows with its mission (every action it ran) and its fleet
(link statistics per peer); one wire message holds at most
:data:`~eamos.net.wire.MAX_PAYLOAD_BYTES`.  :func:`report_messages` gives the
messages that carry a report: a plain :class:`~eamos.net.wire.Report` when it
fits, else the report map's MessagePack encoding cut into
:class:`~eamos.net.wire.ReportPart` slices.  The reliable link delivers those
once each and in order; the receiver's :class:`ReportJoiner` puts them back
together and hands on one ordinary ``Report``, so nothing above the link (the
ground station, the monitor) knows parts exist.  Over a slow link a part is
retransmitted on its own: no single message is large.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Final

import msgpack

import eamos.net.wire as wire

__all__ = ["MAX_REPORT_BYTES", "SINGLE_REPORT_BYTES", "ReportJoiner", "report_messages"]

SINGLE_REPORT_BYTES: Final = wire.MAX_PAYLOAD_BYTES - 4096
"""A report map encoded in at most this many bytes goes as one Report (the rest of the
message, envelope and topic, is far below 4 KiB)."""

MAX_REPORT_BYTES: Final = wire.REPORT_PART_BYTES * wire.MAX_REPORT_PARTS
"""The largest report that can be sent (and that a receiver joins): 64 MiB."""


def report_messages(
    mission: str, sender: str, report: Mapping[str, Any], dest: str = wire.GROUND_STATION
) -> list[wire.Report | wire.ReportPart]:
    """The messages carrying ``report`` (plain data) from ``sender`` to ``dest``, in order.

    Raises :class:`~eamos.net.wire.WireError` if it is not plain data or larger
    than :data:`MAX_REPORT_BYTES` encoded.
    """
    data = dict(report)
    try:
        packed = msgpack.packb(data, use_bin_type=True)
    except (TypeError, ValueError, OverflowError) as exc:
        raise wire.WireError(f"cannot encode the report: {exc}") from exc
    if len(packed) <= SINGLE_REPORT_BYTES:
        return [wire.Report(mission=mission, sender=sender, report=data, dest=dest)]
    if len(packed) > MAX_REPORT_BYTES:
        raise wire.WireError(f"report of {len(packed)} bytes exceeds {MAX_REPORT_BYTES}")
    size = wire.REPORT_PART_BYTES
    parts = -(-len(packed) // size)
    return [
        wire.ReportPart(
            mission=mission,
            sender=sender,
            part=i,
            parts=parts,
            data=packed[i * size : (i + 1) * size],
            dest=dest,
        )
        for i in range(parts)
    ]


@dataclass
class _Partial:
    """One sender's report so far: how many parts it has, and those received."""

    parts: int
    incarnation: int
    chunks: list[bytes] = field(default_factory=list)


class ReportJoiner:
    """Joins each sender's ReportParts into one Report (the receiving side; not thread-safe).

    :meth:`add` returns the whole :class:`~eamos.net.wire.Report` with the last
    part, None before.  Parts out of step (a part 0 starts a report afresh; a
    restarted sender's parts replace its predecessor's) or a joined report that
    is not a valid report map raise :class:`~eamos.net.wire.WireError`; what was
    gathered for that sender is dropped.
    """

    def __init__(self) -> None:
        self._partial: dict[str, _Partial] = {}

    def add(self, msg: wire.ReportPart) -> wire.Report | None:
        """Take one part (in link order); the joined report once it is complete."""
        partial = self._partial.get(msg.sender)
        if msg.part == 0 or partial is None or partial.incarnation != msg.incarnation:
            partial = _Partial(msg.parts, msg.incarnation)
            self._partial[msg.sender] = partial
        if msg.part != len(partial.chunks) or msg.parts != partial.parts:
            del self._partial[msg.sender]
            raise wire.WireError(
                f"ReportPart from {msg.sender}: part {msg.part} of {msg.parts} "
                f"after {len(partial.chunks)} of {partial.parts}"
            )
        partial.chunks.append(msg.data)
        if len(partial.chunks) < partial.parts:
            return None
        del self._partial[msg.sender]
        return _joined(msg, b"".join(partial.chunks))

    def pending(self) -> dict[str, tuple[int, int]]:
        """Senders with a report under way: (parts received, parts expected)."""
        return {s: (len(p.chunks), p.parts) for s, p in self._partial.items()}


def _joined(last: wire.ReportPart, packed: bytes) -> wire.Report:
    body = wire.unpack_bounded(
        packed,
        MAX_REPORT_BYTES,
        MAX_REPORT_BYTES,
        f"joined report from {last.sender} is not msgpack",
    )
    # What a Report's decode checks: a map of plain data, nested at most MAX_DEPTH deep.
    return wire.Report(
        mission=last.mission,
        sender=last.sender,
        report=wire.plain_map(body, f"joined report from {last.sender}"),
        dest=last.dest,
        seq=last.seq,
        incarnation=last.incarnation,
    )
