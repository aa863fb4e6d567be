"""The EAMOS wire format, version 4: the only place messages become bytes and back.

Every message crossing the network between participants (drones and the ground
station) is one of the frozen dataclasses below.  On the wire it is a two-frame
ZeroMQ multipart message ``[topic, payload]``:

* ``topic`` (UTF-8 bytes) decides who receives it (SUB sockets filter on it):

  ========================  =====================================================
  ``to/<participant>``      addressed to one participant: Trigger, Interrupt,
                            Ready, Progress, Resolved, Report, ReportPart, Ack
                            (``<participant>`` is the message's ``dest``)
  ``tm/<drone>``            telemetry published by ``<drone>`` (the ``sender``)
  ``hb/<participant>``      heartbeats of ``<participant>`` (the ``sender``),
                            for the peers watching it
  ``all``                   broadcasts to everyone: Start, Abort, Complete
  ========================  =====================================================

  ZeroMQ subscriptions match topic *prefixes* (``to/D1`` also matches
  ``to/D10``), so receivers must compare topics exactly; :class:`InBridge
  <eamos.net.bridges.InBridge>` does.  Participant names (``sender``,
  ``dest``) are therefore non-empty and contain no ``/``.

* ``payload`` is a msgpack map with short string keys.  Keys present in every
  message:

  =====  ======  ========================================================
  key    type    meaning
  =====  ======  ========================================================
  ``v``  int     wire version, always :data:`WIRE_VERSION` (= 4)
  ``t``  str     message type code (table below)
  ``m``  str     mission id; receivers drop messages of other missions
  ``s``  str     sender: name of the participant that sent the message
  ``n``  int     sender's incarnation: set per process (µs start time and
                 random bits), so a restarted participant is told apart
                 from its predecessor; 0 = none (outside the session)
  =====  ======  ========================================================

  Per-type keys (all required; unknown keys are rejected):

  =========  ==============  ======================  ========  ================================
  code       class           field                   key       type / constraint
  =========  ==============  ======================  ========  ================================
  ``trg``    Trigger         dest                    ``d``     str, receiving participant
                             src_node                ``sn``    str, node on the sender
                             dst_node                ``dn``    str, node on the receiver
                             iteration               ``i``     array of int (loop indices)
                             status                  ``st``    "done" | "skipped" | "failed"
                             seq                     ``q``     int >= 0, link sequence number
  ``int``    Interrupt       dest                    ``d``     str
                             scope                   ``sc``    str, scope being interrupted
                             iteration               ``i``     array of int
                             mode                    ``md``    "all"|"waits"|"suspend"|"resume"
                             seq                     ``q``     int >= 0
  ``tel``    TelemetrySample time_s                  ``ts``    float, sender clock (s)
                             x_m, y_m, z_m           ``x``     float, local frame (m);
                                                     ``y``     keys ``x`` ``y`` ``z``
                                                     ``z``
                             lat_deg, lon_deg        ``lat``   float (deg)
                                                     ``lon``
                             alt_m                   ``alt``   float (m)
                             battery_pct             ``bat``   float (%)
                             armed                   ``arm``   bool
                             landed                  ``lnd``   bool
  ``rdy``    Ready           dest                    ``d``     str (default ``"GCS"``)
                             program_checksum        ``ck``    str
                             seq                     ``q``     int >= 0
  ``sta``    Start           seq                     ``q``     int >= 0, broadcast sequence
  ``abt``    Abort           reason                  ``r``     str
                             seq                     ``q``     int >= 0, broadcast sequence
  ``cmp``    Complete        seq                     ``q``     int >= 0, broadcast sequence;
                                                               the whole mission is over
  ``prg``    Progress        dest                    ``d``     str (default ``"GCS"``)
                             state                   ``st``    str, e.g. "started", "done"
                             node                    ``nd``    str
                             action                  ``a``     str
                             detail                  ``dt``    map str -> plain data
  ``res``    Resolved        dest                    ``d``     str (default ``"GCS"``)
                             seq                     ``q``     int >= 0
  ``rep``    Report          dest                    ``d``     str (default ``"GCS"``)
                             report                  ``rp``    map str -> plain data
                             seq                     ``q``     int >= 0
  ``rpp``    ReportPart      dest                    ``d``     str (default ``"GCS"``)
                             part                    ``pi``    int >= 0, this part's index
                             parts                   ``pn``    int, 1 <= parts <=
                                                               :data:`MAX_REPORT_PARTS`
                             data                    ``pd``    bin, at most
                                                               :data:`REPORT_PART_BYTES`
                             seq                     ``q``     int >= 0
  ``ack``    Ack             dest                    ``d``     str, the sender being acked
                             upto                    ``a``     int >= 0, every seq <= a of the
                                                               link dest -> sender arrived
                             bupto                   ``b``     int >= 0, same for dest's
                                                               broadcasts
                             nack                    ``nk``    bool, a gap is known: resend now
                             dest_incarnation        ``di``    int, dest's incarnation acked
  ``hb``     Heartbeat       sent                    ``hs``    map name -> int, highest seq
                                                               sent on each link with messages
                                                               not yet acknowledged
                             bsent                   ``bs``    int, highest broadcast seq sent
                             leaving                 ``end``   bool, the sender is shutting down
                             acks                    ``ak``    map name -> int, cumulative seq
                                                               delivered from each link whose
                                                               ack changed in the last 3
                                                               heartbeats
                             backs                   ``bk``    map name -> int, same for each
                                                               participant's broadcasts
                             known                   ``ki``    map name -> int, incarnation of
                                                               each name in ``ak``/``bk``
  =========  ==============  ======================  ========  ================================

  ``seq`` (key ``q``) numbers the reliable messages: Trigger, Interrupt, Ready,
  Resolved, Report and ReportPart per link (sender, dest), Start, Abort and Complete per
  sender (broadcast sequence); 1, 2, 3 ... as the reliability layer
  (:mod:`eamos.net.session`) sends them, 0 for a message sent outside it (not
  acknowledged, not deduplicated).  Progress, TelemetrySample, Ack and
  Heartbeat are never acknowledged: progress and telemetry are latest-value
  data, acks and heartbeats are repeated anyway.

  Floats accept msgpack ints on decode (converted to float); bools are never
  accepted where numbers are expected.  "Plain data" is nil, bool, int, float,
  str, bin, array and str-keyed maps, nested at most :data:`MAX_DEPTH` deep
  (arrays come back as lists).

Ready, Progress, Resolved, Report and ReportPart are addressed to the ground
station; their ``dest`` defaults to :data:`GROUND_STATION` so their constructors
stay short.

A report too large for one message travels as ReportParts: the MessagePack
encoding of the report map cut into ``parts`` slices of at most
:data:`REPORT_PART_BYTES`, sent in order on the reliable link (so they arrive
once each, in order); the receiver joins them and decodes the whole as a
Report's ``rp`` (:mod:`eamos.net.reports`).

:func:`decode` raises :class:`WireError`, and nothing else, for any malformed
input: wrong frame count, oversize frames, payload that is not msgpack, wrong or
missing version, unknown type, missing, extra or wrongly typed fields, or a topic
that does not match the message; its ``reason`` is ``"version"`` for a payload of
another wire version (an older or newer program) and ``"malformed"`` otherwise.
Changing anything in this table means bumping :data:`WIRE_VERSION`;
``docs/wire-format.md`` holds the same table.

Version history: 1 (first format); 2 adds ``q`` (sequence numbers), Ack and
Heartbeat for reliable delivery and peer liveness; 3 adds the incarnation
(``n`` in every message, ``di`` in Ack, ``ki`` in Heartbeat) so that peers
resynchronise with a restarted participant; 4 adds ReportPart (reports of any
size, in parts).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from typing import Any, ClassVar, Final, TypeVar

import msgpack

from eamos.net.wire_fields import (
    _MAX_CONTAINER_LEN,
    MAX_DEPTH,
    MAX_PAYLOAD_BYTES,
    MAX_REPORT_PARTS,
    MAX_TOPIC_BYTES,
    REPORT_PART_BYTES,
    WireError,
    _check_bool,
    _check_choice,
    _check_float,
    _check_iteration,
    _check_map,
    _check_name,
    _check_part_data,
    _check_parts,
    _check_seq,
    _check_seq_map,
    _check_str,
    _m,
)
from eamos.program.uniform import GROUND_STATION as _GCS

__all__ = [
    "GROUND_STATION",
    "INTERRUPT_MODES",
    "MAX_DEPTH",
    "MAX_PAYLOAD_BYTES",
    "MAX_REPORT_PARTS",
    "MAX_TOPIC_BYTES",
    "MESSAGE_TYPES",
    "RELIABLE_BROADCAST",
    "RELIABLE_TO",
    "REPORT_PART_BYTES",
    "TOPIC_ALL",
    "TRIGGER_STATUSES",
    "WIRE_VERSION",
    "Abort",
    "Ack",
    "Complete",
    "Heartbeat",
    "Interrupt",
    "Message",
    "Progress",
    "Ready",
    "Report",
    "ReportPart",
    "Resolved",
    "Start",
    "TelemetrySample",
    "Trigger",
    "WireError",
    "decode",
    "encode",
    "restamp",
    "topic_heartbeat",
    "topic_telemetry",
    "topic_to",
    "unpack_bounded",
]

WIRE_VERSION: Final = 4
"""Version of this format, carried in every payload under key ``v``."""

GROUND_STATION: Final = _GCS  # the same name the compiler gives the ground station
"""Default participant name of the ground station (``dest`` of status messages)."""

TOPIC_ALL: Final = b"all"
"""Topic of broadcasts (Start, Abort, Complete)."""

TRIGGER_STATUSES: Final = frozenset({"done", "skipped", "failed"})
INTERRUPT_MODES: Final = frozenset({"all", "waits", "suspend", "resume"})


def topic_to(participant: str) -> bytes:
    """Topic of messages addressed to ``participant`` (``b"to/<participant>"``)."""
    return b"to/" + participant.encode("utf-8")


def topic_heartbeat(participant: str) -> bytes:
    """Topic of the heartbeats of ``participant`` (``b"hb/<participant>"``)."""
    return b"hb/" + participant.encode("utf-8")


def topic_telemetry(drone: str) -> bytes:
    """Topic of the telemetry published by ``drone`` (``b"tm/<drone>"``)."""
    return b"tm/" + drone.encode("utf-8")


# ---------------------------------------------------------------------------
# Messages.


@dataclass(frozen=True)
class _Base:
    """Fields shared by every message; subclasses set ``CODE`` and ``KIND``."""

    CODE: ClassVar[str] = ""
    # How the topic is derived: "to" (from dest), "tm" or "hb" (from sender), or "all".
    KIND: ClassVar[str] = ""

    mission: str = field(metadata=_m("m", _check_str))
    sender: str = field(metadata=_m("s", _check_name))
    # Keyword-only (last in every constructor): the session stamps it on sending.
    incarnation: int = field(default=0, kw_only=True, metadata=_m("n", _check_seq))

    # (field name, validator, "Class.field") per field, set once below the classes:
    # ``dataclasses.fields()`` and the labels cost more than the checks themselves.
    _CHECKS: ClassVar[tuple[tuple[str, Any, str], ...]] = ()

    def __post_init__(self) -> None:
        # Validate and normalise every field (e.g. list -> tuple, int -> float).
        # object.__setattr__ is the documented way to do this in a frozen dataclass.
        for name, check, label in self._CHECKS:
            object.__setattr__(self, name, check(getattr(self, name), label))
        self._check_together()

    def _check_together(self) -> None:
        """Checks across fields, after each field's own (none by default)."""

    @property
    def topic(self) -> bytes:
        """The ZeroMQ topic this message is published on."""
        if self.KIND == "to":
            return topic_to(self.dest)  # type: ignore[attr-defined]
        if self.KIND == "tm":
            return topic_telemetry(self.sender)
        if self.KIND == "hb":
            return topic_heartbeat(self.sender)
        return TOPIC_ALL


@dataclass(frozen=True)
class Trigger(_Base):
    """External arc: ``src_node`` on ``sender`` resolved; trigger ``dst_node`` on ``dest``."""

    CODE: ClassVar[str] = "trg"
    KIND: ClassVar[str] = "to"

    dest: str = field(metadata=_m("d", _check_name))
    src_node: str = field(metadata=_m("sn", _check_str))
    dst_node: str = field(metadata=_m("dn", _check_str))
    iteration: tuple[int, ...] = field(metadata=_m("i", _check_iteration))
    status: str = field(metadata=_m("st", _check_choice(TRIGGER_STATUSES)))
    seq: int = field(metadata=_m("q", _check_seq), default=0)


@dataclass(frozen=True)
class Interrupt(_Base):
    """Interrupt ``scope`` (at ``iteration``) on ``dest``; mode "all" or only its "waits"."""

    CODE: ClassVar[str] = "int"
    KIND: ClassVar[str] = "to"

    dest: str = field(metadata=_m("d", _check_name))
    scope: str = field(metadata=_m("sc", _check_str))
    iteration: tuple[int, ...] = field(metadata=_m("i", _check_iteration))
    mode: str = field(metadata=_m("md", _check_choice(INTERRUPT_MODES)))
    seq: int = field(metadata=_m("q", _check_seq), default=0)


@dataclass(frozen=True)
class TelemetrySample(_Base):
    """Latest state of the sender drone, read by other drones' conditions."""

    CODE: ClassVar[str] = "tel"
    KIND: ClassVar[str] = "tm"

    time_s: float = field(metadata=_m("ts", _check_float))
    x_m: float = field(metadata=_m("x", _check_float))
    y_m: float = field(metadata=_m("y", _check_float))
    z_m: float = field(metadata=_m("z", _check_float))
    lat_deg: float = field(metadata=_m("lat", _check_float))
    lon_deg: float = field(metadata=_m("lon", _check_float))
    alt_m: float = field(metadata=_m("alt", _check_float))
    battery_pct: float = field(metadata=_m("bat", _check_float))
    armed: bool = field(metadata=_m("arm", _check_bool))
    landed: bool = field(metadata=_m("lnd", _check_bool))


@dataclass(frozen=True)
class Ready(_Base):
    """The sender loaded its program and every participant it sends to has subscribed."""

    CODE: ClassVar[str] = "rdy"
    KIND: ClassVar[str] = "to"

    program_checksum: str = field(metadata=_m("ck", _check_str))
    dest: str = field(metadata=_m("d", _check_name), default=GROUND_STATION)
    seq: int = field(metadata=_m("q", _check_seq), default=0)


@dataclass(frozen=True)
class Start(_Base):
    """Broadcast by the ground station: every drone starts its program."""

    CODE: ClassVar[str] = "sta"
    KIND: ClassVar[str] = "all"

    seq: int = field(metadata=_m("q", _check_seq), default=0)


@dataclass(frozen=True)
class Abort(_Base):
    """Broadcast: stop the mission now (drones run their failsafe)."""

    CODE: ClassVar[str] = "abt"
    KIND: ClassVar[str] = "all"

    reason: str = field(metadata=_m("r", _check_str))
    seq: int = field(metadata=_m("q", _check_seq), default=0)


@dataclass(frozen=True)
class Complete(_Base):
    """Broadcast by the ground station: the whole mission is over."""

    CODE: ClassVar[str] = "cmp"
    KIND: ClassVar[str] = "all"

    seq: int = field(metadata=_m("q", _check_seq), default=0)


@dataclass(frozen=True)
class Progress(_Base):
    """A node/action event on the sender, for live display at the ground station."""

    CODE: ClassVar[str] = "prg"
    KIND: ClassVar[str] = "to"

    state: str = field(metadata=_m("st", _check_str))
    node: str = field(metadata=_m("nd", _check_str))  # not "n": the incarnation's key
    action: str = field(metadata=_m("a", _check_str))
    detail: dict[str, Any] = field(metadata=_m("dt", _check_map), default_factory=dict)
    dest: str = field(metadata=_m("d", _check_name), default=GROUND_STATION)


@dataclass(frozen=True)
class Resolved(_Base):
    """The sender's top-level nodes are all resolved."""

    CODE: ClassVar[str] = "res"
    KIND: ClassVar[str] = "to"

    dest: str = field(metadata=_m("d", _check_name), default=GROUND_STATION)
    seq: int = field(metadata=_m("q", _check_seq), default=0)


@dataclass(frozen=True)
class Report(_Base):
    """Final per-drone summary, sent to the ground station."""

    CODE: ClassVar[str] = "rep"
    KIND: ClassVar[str] = "to"

    report: dict[str, Any] = field(metadata=_m("rp", _check_map))
    dest: str = field(metadata=_m("d", _check_name), default=GROUND_STATION)
    seq: int = field(metadata=_m("q", _check_seq), default=0)


@dataclass(frozen=True)
class ReportPart(_Base):
    """Part ``part`` of ``parts`` of a final report too large for one message.

    ``data`` is a slice of the report map's MessagePack encoding; the parts of
    one report follow each other on the link, ``part`` 0 first.
    """

    CODE: ClassVar[str] = "rpp"
    KIND: ClassVar[str] = "to"

    part: int = field(metadata=_m("pi", _check_seq))
    parts: int = field(metadata=_m("pn", _check_parts))
    data: bytes = field(metadata=_m("pd", _check_part_data))
    dest: str = field(metadata=_m("d", _check_name), default=GROUND_STATION)
    seq: int = field(metadata=_m("q", _check_seq), default=0)

    def _check_together(self) -> None:
        if self.part >= self.parts:
            raise WireError(f"ReportPart.part: {self.part} of {self.parts} parts")


@dataclass(frozen=True)
class Ack(_Base):
    """Cumulative acknowledgement from ``sender`` to ``dest`` (the reliability layer).

    Every message of the link ``dest -> sender`` with ``seq <= upto`` and every
    broadcast of ``dest`` with ``seq <= bupto`` arrived.  ``nack`` says the
    sender of the Ack knows of a gap (it received a later message, or a
    heartbeat announcing one): ``dest`` should resend what follows at once.
    ``dest_incarnation`` is the incarnation of ``dest`` acknowledged (0: unknown).
    """

    CODE: ClassVar[str] = "ack"
    KIND: ClassVar[str] = "to"

    dest: str = field(metadata=_m("d", _check_name))
    upto: int = field(metadata=_m("a", _check_seq))
    bupto: int = field(metadata=_m("b", _check_seq))
    nack: bool = field(metadata=_m("nk", _check_bool), default=False)
    dest_incarnation: int = field(metadata=_m("di", _check_seq), default=0)


@dataclass(frozen=True)
class Heartbeat(_Base):
    """Periodic sign of life on ``hb/<sender>``, carrying the sender's acknowledgements.

    ``sent`` maps each participant to the highest seq sent to it, ``bsent`` is
    the highest broadcast seq; a receiver that has less asks for the rest with
    a nack.  ``acks`` maps each participant P to the cumulative seq of the link
    P -> sender delivered so far, ``backs`` the same for P's broadcasts: the
    acknowledgements of steady traffic ride here, once per period, instead of
    costing a message per trigger.  ``leaving`` is set once, when the sender
    shuts down: peers then record it as gone rather than lost.  ``known`` maps
    each participant in ``acks`` or ``backs`` to its incarnation those refer to:
    a restarted participant ignores acknowledgements meant for its predecessor.
    """

    CODE: ClassVar[str] = "hb"
    KIND: ClassVar[str] = "hb"

    sent: dict[str, int] = field(metadata=_m("hs", _check_seq_map), default_factory=dict)
    bsent: int = field(metadata=_m("bs", _check_seq), default=0)
    leaving: bool = field(metadata=_m("end", _check_bool), default=False)
    acks: dict[str, int] = field(metadata=_m("ak", _check_seq_map), default_factory=dict)
    backs: dict[str, int] = field(metadata=_m("bk", _check_seq_map), default_factory=dict)
    known: dict[str, int] = field(metadata=_m("ki", _check_seq_map), default_factory=dict)


Message = (
    Trigger
    | Interrupt
    | TelemetrySample
    | Ready
    | Start
    | Abort
    | Complete
    | Progress
    | Resolved
    | Report
    | ReportPart
    | Ack
    | Heartbeat
)
"""Any message of the wire format."""

MESSAGE_TYPES: Final[tuple[type[_Base], ...]] = (
    Trigger,
    Interrupt,
    TelemetrySample,
    Ready,
    Start,
    Abort,
    Complete,
    Progress,
    Resolved,
    Report,
    ReportPart,
    Ack,
    Heartbeat,
)

RELIABLE_TO: Final[frozenset[type[_Base]]] = frozenset(
    {Trigger, Interrupt, Ready, Resolved, Report, ReportPart}
)
"""Addressed messages the reliability layer numbers per link (sender, dest) and acknowledges."""

RELIABLE_BROADCAST: Final[frozenset[type[_Base]]] = frozenset({Start, Abort, Complete})
"""Broadcasts the reliability layer numbers per sender and has every peer acknowledge."""

for _cls in MESSAGE_TYPES:
    _cls._CHECKS = tuple(
        (f.name, f.metadata["check"], f"{_cls.__name__}.{f.name}") for f in fields(_cls)
    )

_BY_CODE: Final[dict[str, type[_Base]]] = {cls.CODE: cls for cls in MESSAGE_TYPES}
# Wire key -> field name, per type; computed once (immutable afterwards).
_KEYS: Final[dict[type[_Base], dict[str, str]]] = {
    cls: {f.metadata["key"]: f.name for f in fields(cls)} for cls in MESSAGE_TYPES
}
_ENVELOPE_KEYS: Final = frozenset({"v", "t"})
# Per type: every key of a payload (envelope included), and (key, field, validator,
# label) per field: what decode checks, once, without the constructor's overhead.
_PAYLOAD_KEYS: Final[dict[type[_Base], frozenset[str]]] = {
    cls: frozenset(keys) | _ENVELOPE_KEYS for cls, keys in _KEYS.items()
}
_DECODERS: Final[dict[type[_Base], tuple[tuple[str, str, Any, str], ...]]] = {
    cls: tuple(
        (f.metadata["key"], f.name, f.metadata["check"], f"{cls.__name__}.{f.name}")
        for f in fields(cls)
    )
    for cls in MESSAGE_TYPES
}
_CHECK_OF: Final[dict[type[_Base], dict[str, tuple[Any, str]]]] = {
    cls: {name: (check, label) for _key, name, check, label in checks}
    for cls, checks in _DECODERS.items()
}
# Per type: (wire key, field name) in field order, for encode.
_ENCODERS: Final[dict[type[_Base], tuple[tuple[str, str], ...]]] = {
    cls: tuple(keys.items()) for cls, keys in _KEYS.items()
}


# ---------------------------------------------------------------------------
# Encode / decode.  Sequence numbers and acks are ordinary fields (above);
# authentication and encryption happen below, in ZeroMQ's CURVE mechanism.


def encode(msg: Message) -> list[bytes]:
    """Encode ``msg`` as the multipart frames ``[topic, payload]``.

    Raises :class:`WireError` if ``msg`` is not a wire message or its payload
    does not fit in :data:`MAX_PAYLOAD_BYTES`.
    """
    cls = type(msg)
    keys = _ENCODERS.get(cls)
    if keys is None:
        raise WireError(f"not a wire message: {cls.__name__}")
    values = msg.__dict__
    body: dict[str, Any] = {"v": WIRE_VERSION, "t": cls.CODE}
    for key, name in keys:
        body[key] = values[name]  # a tuple packs as an array, as a list does
    try:
        payload = msgpack.packb(body, use_bin_type=True)
    except (TypeError, ValueError, OverflowError) as exc:
        raise WireError(f"cannot encode {cls.__name__}: {exc}") from exc
    if len(payload) > MAX_PAYLOAD_BYTES:
        raise WireError(f"{cls.__name__} payload of {len(payload)} bytes exceeds the limit")
    return [msg.topic, payload]


def unpack_bounded(
    data: bytes | bytearray | memoryview, max_bytes: int, max_items: int, refusal: str
) -> Any:
    """``data`` decoded from msgpack with every length bounded; :class:`WireError` if bad.

    Strings and binaries are at most ``max_bytes`` long, arrays and maps hold at
    most ``max_items``; extension types are refused.  ``refusal`` begins the
    error's message ("payload is not valid msgpack").
    """
    try:
        return msgpack.unpackb(
            data,
            raw=False,
            strict_map_key=True,
            max_str_len=max_bytes,
            max_bin_len=max_bytes,
            max_array_len=max_items,
            max_map_len=max_items,
            max_ext_len=0,
        )
    # msgpack signals bad input with ValueError subclasses (incl. UnicodeDecodeError),
    # its own UnpackException family, TypeError (e.g. unhashable keys) and
    # OverflowError; all mean "not valid msgpack".
    except (ValueError, TypeError, OverflowError, msgpack.UnpackException) as exc:
        raise WireError(f"{refusal}: {exc}") from exc


def decode(frames: Sequence[bytes]) -> Message:
    """Decode multipart ``frames`` (``[topic, payload]``) into a message.

    Raises :class:`WireError`, and only that, for any malformed input.
    """
    if not isinstance(frames, list | tuple) or len(frames) != 2:
        count = len(frames) if isinstance(frames, list | tuple) else type(frames).__name__
        raise WireError(f"expected 2 frames [topic, payload], got {count}")
    topic, payload = frames
    if not isinstance(topic, bytes | bytearray | memoryview) or not isinstance(
        payload, bytes | bytearray | memoryview
    ):
        raise WireError("frames must be bytes")
    if len(topic) > MAX_TOPIC_BYTES:
        raise WireError(f"topic of {len(topic)} bytes exceeds {MAX_TOPIC_BYTES}")
    if len(payload) > MAX_PAYLOAD_BYTES:
        raise WireError(
            f"payload of {len(payload)} bytes exceeds {MAX_PAYLOAD_BYTES}", reason="oversize"
        )
    body = unpack_bounded(
        payload, MAX_PAYLOAD_BYTES, _MAX_CONTAINER_LEN, "payload is not valid msgpack"
    )
    if not isinstance(body, dict):
        raise WireError(f"payload must be a map, got {type(body).__name__}")
    version = body.get("v")
    # type() rather than isinstance: True and 1.0 both compare equal to 1.
    if type(version) is not int or version != WIRE_VERSION:
        raise WireError(
            f"unsupported wire version {version!r} (expected {WIRE_VERSION})", reason="version"
        )
    code = body.get("t")
    cls = _BY_CODE.get(code) if isinstance(code, str) else None
    if cls is None:
        raise WireError(f"unknown message type {code!r}")
    if body.keys() != _PAYLOAD_KEYS[cls]:
        keys = set(_KEYS[cls])
        present = set(body) - _ENVELOPE_KEYS
        missing = sorted(keys - present)
        extra = sorted(map(repr, present - keys))
        raise WireError(f"{cls.__name__}: missing keys {missing}, unexpected keys {extra}")
    # Validated here, once, at the trust boundary: each field's check, then the
    # instance filled in directly (the constructor would look every field up again).
    msg: Message = cls.__new__(cls)  # type: ignore[assignment]
    values = msg.__dict__
    for key, name, check, label in _DECODERS[cls]:
        values[name] = check(body[key], label)
    msg._check_together()
    if type(topic) is not bytes:
        topic = bytes(topic)
    if topic != msg.topic:
        raise WireError(f"{cls.__name__} on topic {topic!r}, expected {msg.topic!r}")
    return msg


MessageT = TypeVar("MessageT", bound=_Base)


def restamp(msg: MessageT, **changes: Any) -> MessageT:
    """``msg`` with the fields in ``changes`` replaced and checked; the others are kept.

    What :func:`dataclasses.replace` does, without checking again the fields
    that were checked when ``msg`` was made (the session stamps every message
    it sends with its sequence number and incarnation).
    """
    cls = type(msg)
    checks = _CHECK_OF[cls]
    new = cls.__new__(cls)
    values = new.__dict__
    values.update(msg.__dict__)
    for name, value in changes.items():
        if name not in checks:
            raise TypeError(f"{cls.__name__} has no field {name!r}")
        check, label = checks[name]
        values[name] = check(value, label)
    new._check_together()
    return new
