"""The EAMOS wire format, version 7: the only place messages become bytes and back.

Every message crossing the network between participants (drones and the ground
station) is one of the frozen :class:`msgspec.Struct` types below.  On the wire it is a two-frame
ZeroMQ multipart message ``[topic, payload]``:

* ``topic`` (UTF-8 bytes) decides who receives it (SUB sockets filter on it):

  ========================  =====================================================
  ``to/<participant>``      addressed to one participant: Trigger, Interrupt,
                            Ready, Progress, Resolved, Report, ReportPart, Ack
                            (``<participant>`` is the message's ``dest``)
  ``tm/<drone>``            telemetry published by ``<drone>`` (the ``sender``)
  ``hb/<participant>``      heartbeats of ``<participant>`` (the ``sender``),
                            for the peers watching it
  ``all``                   broadcasts to everyone: Start, Abort, Complete, Operator
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
  ``v``  int     wire version, always :data:`WIRE_VERSION` (= 7)
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
  ``sta``    Start           deployment              ``dp``    str, the roll-out it starts
                                                               (<= 64 of A-Za-z0-9._-)
                             seq                     ``q``     int >= 0, broadcast sequence
  ``abt``    Abort           reason                  ``r``     str
                             seq                     ``q``     int >= 0, broadcast sequence
  ``cmp``    Complete        seq                     ``q``     int >= 0, broadcast sequence;
                                                               the whole mission is over
  ``opc``    Operator        command                 ``c``     "pause"|"resume"|"hold"|"land"|
                                                               "return-home"|"release"
                             target                  ``tg``    str, the drone ("": every one)
                             origin                  ``o``     str, who asked (for the logs)
                             seq                     ``q``     int >= 0, broadcast sequence
  ``amd``    Amend           dest                    ``d``     str, the drone (its answer: GCS)
                             number                  ``nb``    int >= 0, the staged amendment
                             phase                   ``ph``    "prepare"|"commit"|"cancel" (to
                                                               a drone), "prepared"|"committed"|
                                                               "cancelled"|"refused" (its answer)
                             program                 ``pg``    bin, the drone's new program
                                                               file (UTF-8 JSON; prepare)
                             reason                  ``r``     str, why refused
                             seq                     ``q``     int >= 0
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

  ``seq`` (key ``q``) numbers the reliable messages (per link: Trigger, Interrupt,
  Ready, Amend, Resolved, Report, ReportPart; per sender: the broadcasts) 1, 2, 3 ...,
  0 outside the reliability layer (:mod:`eamos.net.session`).  Progress, telemetry,
  Ack and Heartbeat are never acknowledged.

The rest (plain data, floats, key order, defaults, reports in parts, what :func:`decode`
checks: it raises :class:`WireError` and nothing else) is in ``docs/wire-format.md``,
which holds the same table.  Changing the table means bumping :data:`WIRE_VERSION`.

Version history: 1 (first format); 2 adds ``q``, Ack and Heartbeat (reliable
delivery, liveness); 3 the incarnation (``n``, Ack's ``di``, Heartbeat's ``ki``: a
restarted peer); 4 ReportPart; 5 Start's ``dp``; 6 Operator (``opc``); 7 Amend (``amd``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Annotated, Any, ClassVar, Final, Literal, TypeAlias, get_args

import msgpack
import msgspec

from eamos.program.uniform import GROUND_STATION as _GCS

__all__ = [
    "GROUND_STATION",
    "MAX_DEPTH",
    "MAX_PAYLOAD_BYTES",
    "MAX_REPORT_PARTS",
    "MAX_TOPIC_BYTES",
    "MESSAGE_TYPES",
    "RELIABLE_BROADCAST",
    "RELIABLE_TO",
    "REPORT_PART_BYTES",
    "TOPIC_ALL",
    "WIRE_VERSION",
    "Abort",
    "Ack",
    "Amend",
    "AmendPhase",
    "Complete",
    "Heartbeat",
    "Interrupt",
    "InterruptMode",
    "Message",
    "Operator",
    "OperatorCommand",
    "Progress",
    "Ready",
    "Report",
    "ReportPart",
    "Resolved",
    "Start",
    "TelemetrySample",
    "Trigger",
    "TriggerStatus",
    "WireError",
    "decode",
    "encode",
    "plain_map",
    "topic_heartbeat",
    "topic_telemetry",
    "topic_to",
    "unpack_bounded",
]

WIRE_VERSION: Final = 7
"""Version of this format, carried in every payload under key ``v``."""

GROUND_STATION: Final = _GCS  # the same name the compiler gives the ground station
"""Default participant name of the ground station (``dest`` of status messages)."""

TOPIC_ALL: Final = b"all"
"""Topic of broadcasts (Start, Abort, Complete, Operator)."""

# Limits applied before and during unpacking so a hostile or broken peer cannot
# make a receiver allocate or recurse without bound.  Reports are the largest
# legitimate messages and stay far below them.
MAX_PAYLOAD_BYTES: Final = 1 << 20
MAX_TOPIC_BYTES: Final = 256
MAX_DEPTH: Final = 32
"""Plain data (``detail``, ``report``) nests at most this deep below its map."""
_MAX_CONTAINER_LEN: Final = 1 << 16
REPORT_PART_BYTES: Final = 256 * 1024
"""Bytes of a report's encoding one ReportPart carries (at most); a quarter of a message."""
MAX_REPORT_PARTS: Final = 256
"""At most this many parts make one report (64 MiB): a receiver's bound on what it joins."""


class WireError(ValueError):
    """A message could not be encoded or decoded (the network layer's one error type).

    ``reason`` is ``"version"`` when the payload is of another wire version,
    ``"oversize"`` for a payload over :data:`MAX_PAYLOAD_BYTES` and ``"malformed"``
    for everything else; receivers log and count drops by it.
    """

    def __init__(self, message: str, reason: str = "malformed") -> None:
        super().__init__(message)
        self.reason = reason


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
# Field types: what decode accepts, said once, in the types.

Name: TypeAlias = Annotated[str, msgspec.Meta(pattern="^[^/]+$")]
"""A participant name: in topics (``to/<name>``), so non-empty and without ``/``."""
Seq: TypeAlias = Annotated[int, msgspec.Meta(ge=0, le=(1 << 63) - 1)]
"""Sequence numbers, acknowledgements and incarnations: ints in [0, 2**63)."""
Iteration: TypeAlias = tuple[int, ...]
"""Loop indices; a tuple, so that a Trigger is hashable and compares equal after a trip."""
SeqMap: TypeAlias = Annotated[dict[Name, Seq], msgspec.Meta(max_length=_MAX_CONTAINER_LEN)]
PlainMap: TypeAlias = Annotated[dict[str, Any], msgspec.Meta(max_length=_MAX_CONTAINER_LEN)]
"""A str-keyed map of plain data; its nesting is bounded by :func:`plain_map` (no type can
say it without recursing)."""
DeploymentId: TypeAlias = Annotated[str, msgspec.Meta(pattern="^[A-Za-z0-9._-]{0,64}$")]
PartCount: TypeAlias = Annotated[int, msgspec.Meta(ge=1, le=MAX_REPORT_PARTS)]
PartData: TypeAlias = Annotated[bytes, msgspec.Meta(max_length=REPORT_PART_BYTES)]
ProgramText: TypeAlias = Annotated[bytes, msgspec.Meta(max_length=MAX_PAYLOAD_BYTES)]
TriggerStatus: TypeAlias = Literal["done", "skipped", "failed"]
InterruptMode: TypeAlias = Literal["all", "waits", "suspend", "resume"]
OperatorCommand: TypeAlias = Literal["pause", "resume", "hold", "land", "return-home", "release"]
AmendPhase: TypeAlias = Literal[
    "prepare", "commit", "cancel", "prepared", "committed", "cancelled", "refused"
]


# ---------------------------------------------------------------------------
# Messages.  Each class's tag (``t``) is its type code; ``name=`` gives each field's
# wire key.  Constructors check nothing: decode does, at the trust boundary.


class _Fields(msgspec.Struct, frozen=True, tag_field="t", forbid_unknown_fields=True):
    """The positional fields every message starts with."""

    mission: str = msgspec.field(name="m")
    sender: Name = msgspec.field(name="s")


class _Base(_Fields, frozen=True, kw_only=True):
    """Fields shared by every message (keyword-only, after each class's own)."""

    # How the topic is derived: "to" (from dest), "tm" or "hb" (from sender), or "all".
    KIND: ClassVar[str] = ""

    # In every payload; decode reads it before anything else (a WireError "version").
    version: Literal[7] = msgspec.field(default=WIRE_VERSION, name="v")
    # The session stamps it on sending.
    incarnation: Seq = msgspec.field(default=0, name="n")

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


class Trigger(_Base, frozen=True, tag="trg"):
    """External arc: ``src_node`` on ``sender`` resolved; trigger ``dst_node`` on ``dest``."""

    KIND: ClassVar[str] = "to"

    dest: Name = msgspec.field(name="d")
    src_node: str = msgspec.field(name="sn")
    dst_node: str = msgspec.field(name="dn")
    iteration: Iteration = msgspec.field(name="i")
    status: TriggerStatus = msgspec.field(name="st")
    seq: Seq = msgspec.field(default=0, name="q")


class Interrupt(_Base, frozen=True, tag="int"):
    """Interrupt ``scope`` (at ``iteration``) on ``dest``; mode "all" or only its "waits"."""

    KIND: ClassVar[str] = "to"

    dest: Name = msgspec.field(name="d")
    scope: str = msgspec.field(name="sc")
    iteration: Iteration = msgspec.field(name="i")
    mode: InterruptMode = msgspec.field(name="md")
    seq: Seq = msgspec.field(default=0, name="q")


class TelemetrySample(_Base, frozen=True, tag="tel"):
    """Latest state of the sender drone, read by other drones' conditions."""

    KIND: ClassVar[str] = "tm"

    time_s: float = msgspec.field(name="ts")
    x_m: float = msgspec.field(name="x")
    y_m: float = msgspec.field(name="y")
    z_m: float = msgspec.field(name="z")
    lat_deg: float = msgspec.field(name="lat")
    lon_deg: float = msgspec.field(name="lon")
    alt_m: float = msgspec.field(name="alt")
    battery_pct: float = msgspec.field(name="bat")
    armed: bool = msgspec.field(name="arm")
    landed: bool = msgspec.field(name="lnd")


class Ready(_Base, frozen=True, tag="rdy"):
    """The sender loaded its program and every participant it sends to has subscribed."""

    KIND: ClassVar[str] = "to"

    program_checksum: str = msgspec.field(name="ck")
    dest: Name = msgspec.field(default=GROUND_STATION, name="d")
    seq: Seq = msgspec.field(default=0, name="q")


class Start(_Base, frozen=True, tag="sta"):
    """Broadcast by the ground station: the drones of ``deployment`` start (only they)."""

    KIND: ClassVar[str] = "all"

    deployment: DeploymentId = msgspec.field(default="", name="dp")
    seq: Seq = msgspec.field(default=0, name="q")


class Abort(_Base, frozen=True, tag="abt"):
    """Broadcast: stop the mission now (drones run their failsafe)."""

    KIND: ClassVar[str] = "all"

    reason: str = msgspec.field(name="r")
    seq: Seq = msgspec.field(default=0, name="q")


class Complete(_Base, frozen=True, tag="cmp"):
    """Broadcast by the ground station: the whole mission is over."""

    KIND: ClassVar[str] = "all"

    seq: Seq = msgspec.field(default=0, name="q")


class Operator(_Base, frozen=True, tag="opc"):
    """Broadcast by the ground station: an operator's ``command`` for ``target`` ("": all)."""

    KIND: ClassVar[str] = "all"

    command: OperatorCommand = msgspec.field(name="c")
    target: str = msgspec.field(default="", name="tg")
    origin: str = msgspec.field(default="", name="o")
    seq: Seq = msgspec.field(default=0, name="q")


class Amend(_Base, frozen=True, tag="amd"):
    """An amendment applied in two phases (:mod:`eamos.actors.reprogram`): the ground
    station's ``prepare`` (with the drone's new ``program``), ``commit`` or ``cancel``,
    and the drone's answer to each (``reason`` when ``refused``)."""

    KIND: ClassVar[str] = "to"

    dest: Name = msgspec.field(name="d")
    number: Seq = msgspec.field(name="nb")
    phase: AmendPhase = msgspec.field(name="ph")
    program: ProgramText = msgspec.field(default=b"", name="pg")
    reason: str = msgspec.field(default="", name="r")
    seq: Seq = msgspec.field(default=0, name="q")


class Progress(_Base, frozen=True, tag="prg"):
    """A node/action event on the sender, for live display at the ground station."""

    KIND: ClassVar[str] = "to"

    state: str = msgspec.field(name="st")
    node: str = msgspec.field(name="nd")  # not "n": the incarnation's key
    action: str = msgspec.field(name="a")
    detail: PlainMap = msgspec.field(default_factory=dict, name="dt")
    dest: Name = msgspec.field(default=GROUND_STATION, name="d")


class Resolved(_Base, frozen=True, tag="res"):
    """The sender's top-level nodes are all resolved."""

    KIND: ClassVar[str] = "to"

    dest: Name = msgspec.field(default=GROUND_STATION, name="d")
    seq: Seq = msgspec.field(default=0, name="q")


class Report(_Base, frozen=True, tag="rep"):
    """Final per-drone summary, sent to the ground station."""

    KIND: ClassVar[str] = "to"

    report: PlainMap = msgspec.field(name="rp")
    dest: Name = msgspec.field(default=GROUND_STATION, name="d")
    seq: Seq = msgspec.field(default=0, name="q")


class ReportPart(_Base, frozen=True, tag="rpp"):
    """Part ``part`` of ``parts`` of a report too large for one message: ``data`` is a
    slice of the report map's MessagePack encoding; parts follow in order, 0 first."""

    KIND: ClassVar[str] = "to"

    part: Seq = msgspec.field(name="pi")
    parts: PartCount = msgspec.field(name="pn")
    data: PartData = msgspec.field(name="pd")
    dest: Name = msgspec.field(default=GROUND_STATION, name="d")
    seq: Seq = msgspec.field(default=0, name="q")

    def __post_init__(self) -> None:
        # The one check across fields; msgspec runs it when decoding too.
        if self.part >= self.parts:
            raise WireError(f"ReportPart.part: {self.part} of {self.parts} parts")


class Ack(_Base, frozen=True, tag="ack"):
    """Cumulative acknowledgement from ``sender`` to ``dest`` (the reliability layer).

    Every message of the link ``dest -> sender`` with ``seq <= upto`` and every broadcast
    of ``dest`` with ``seq <= bupto`` arrived; ``nack``: a gap is known, resend at once;
    ``dest_incarnation``: the incarnation of ``dest`` acknowledged (0: unknown)."""

    KIND: ClassVar[str] = "to"

    dest: Name = msgspec.field(name="d")
    upto: Seq = msgspec.field(name="a")
    bupto: Seq = msgspec.field(name="b")
    nack: bool = msgspec.field(default=False, name="nk")
    dest_incarnation: Seq = msgspec.field(default=0, name="di")


class Heartbeat(_Base, frozen=True, tag="hb"):
    """Periodic sign of life on ``hb/<sender>``, carrying the sender's acknowledgements.

    ``sent``/``bsent``: highest seq sent per link / broadcast (a receiver with less
    nacks); ``acks``/``backs``: cumulative seq delivered from each P's link / broadcasts
    (steady traffic's acks ride here); ``leaving``: the sender shuts down (gone, not
    lost); ``known``: the incarnation each ack refers to (a restarted peer ignores its
    predecessor's)."""

    KIND: ClassVar[str] = "hb"

    sent: SeqMap = msgspec.field(default_factory=dict, name="hs")
    bsent: Seq = msgspec.field(default=0, name="bs")
    leaving: bool = msgspec.field(default=False, name="end")
    acks: SeqMap = msgspec.field(default_factory=dict, name="ak")
    backs: SeqMap = msgspec.field(default_factory=dict, name="bk")
    known: SeqMap = msgspec.field(default_factory=dict, name="ki")


Message = (
    Trigger
    | Interrupt
    | TelemetrySample
    | Ready
    | Start
    | Abort
    | Complete
    | Operator
    | Amend
    | Progress
    | Resolved
    | Report
    | ReportPart
    | Ack
    | Heartbeat
)
"""Any message of the wire format (a tagged union on ``t``)."""

MESSAGE_TYPES: Final[tuple[type[_Base], ...]] = get_args(Message)

RELIABLE_TO: Final[frozenset[type[_Base]]] = frozenset(
    {Trigger, Interrupt, Ready, Amend, Resolved, Report, ReportPart}
)
"""Addressed messages the reliability layer numbers per link (sender, dest) and acknowledges."""

RELIABLE_BROADCAST: Final[frozenset[type[_Base]]] = frozenset({Start, Abort, Complete, Operator})
"""Broadcasts the reliability layer numbers per sender and has every peer acknowledge."""

_BY_CODE: Final[dict[str, type[_Base]]] = {
    str(cls.__struct_config__.tag): cls for cls in MESSAGE_TYPES
}
# Per type, computed once: (wire key, field name, field type) per field; every key of
# a payload (the tag included); the keys holding plain data, whose nesting decode bounds.
_FIELDS: Final[dict[type[_Base], tuple[tuple[str, str, Any], ...]]] = {
    cls: tuple((f.encode_name, f.name, f.type) for f in msgspec.structs.fields(cls))
    for cls in MESSAGE_TYPES
}
_PAYLOAD_KEYS: Final[dict[type[_Base], frozenset[str]]] = {
    cls: frozenset(key for key, _name, _type in fields) | {"t"} for cls, fields in _FIELDS.items()
}
_PLAIN_KEYS: Final[dict[type[_Base], tuple[tuple[str, str], ...]]] = {
    cls: tuple((key, f"{cls.__name__}.{name}") for key, name, kind in fields if kind == PlainMap)
    for cls, fields in _FIELDS.items()
}
# msgpack carries bin natively: a str is not decoded as base64 into a bytes field.
_NATIVE: Final = (bytes,)
_BYTES: Final = (bytes, bytearray, memoryview)


# ---------------------------------------------------------------------------
# Encode / decode (authentication and encryption happen below, in ZeroMQ's CURVE).

# One encoder for all: it keeps its working state per call (thread-safe).
_ENCODER: Final = msgspec.msgpack.Encoder()


def encode(msg: Message) -> list[bytes]:
    """Encode ``msg`` as the multipart frames ``[topic, payload]``.

    Raises :class:`WireError` if ``msg`` is not a wire message, holds a value
    MessagePack cannot carry, or its payload does not fit in :data:`MAX_PAYLOAD_BYTES`.
    """
    cls = type(msg)
    if cls not in _FIELDS:
        raise WireError(f"not a wire message: {cls.__name__}")
    try:
        payload = _ENCODER.encode(msg)
    except (TypeError, ValueError, OverflowError, msgspec.EncodeError) as exc:
        raise WireError(f"cannot encode {cls.__name__}: {_cut(str(exc))}") from exc
    if len(payload) > MAX_PAYLOAD_BYTES:
        raise WireError(f"{cls.__name__} payload of {len(payload)} bytes exceeds the limit")
    return [msg.topic, payload]


def unpack_bounded(
    data: bytes | bytearray | memoryview, max_bytes: int, max_items: int, refusal: str
) -> Any:
    """``data`` decoded from msgpack with every length bounded; :class:`WireError` if bad.

    Strings and binaries are at most ``max_bytes`` long, arrays and maps hold at
    most ``max_items``; extension types are refused.  msgpack's unpacker keeps
    its own stack (it never recurses) and refuses more than about a thousand
    levels of nesting.  ``refusal`` begins the error's message ("payload is not
    valid msgpack").
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
    # ValueError (incl. UnicodeDecodeError, StackError), UnpackException, TypeError
    # (unhashable keys), OverflowError: all mean "not valid msgpack".
    except (ValueError, TypeError, OverflowError, msgpack.UnpackException) as exc:
        raise WireError(f"{refusal}: {_cut(str(exc)) or type(exc).__name__}") from exc


def plain_map(value: Any, label: str) -> dict[str, Any]:
    """``value`` if it is a str-keyed map of plain data nested at most :data:`MAX_DEPTH` deep.

    Meant for what msgpack unpacked (whose containers are dicts and lists); raises
    :class:`WireError` naming ``label`` otherwise.  It walks the map with a stack of
    its own: it never recurses, however deep ``value`` is.
    """
    if type(value) is not dict:
        raise WireError(f"{label}: expected a map, got {type(value).__name__}")
    # The map itself is depth 0: an item at depth MAX_DEPTH + 1 is one too deep.
    todo: list[tuple[Any, int]] = [(value, 0)]
    while todo:
        container, depth = todo.pop()
        if depth == MAX_DEPTH and container:
            raise WireError(f"{label}: nested deeper than {MAX_DEPTH}")
        if type(container) is dict:
            for key, item in container.items():
                if type(key) is not str:
                    raise WireError(f"{label}: map keys must be str")
                if type(item) is dict or type(item) is list:
                    todo.append((item, depth + 1))
        else:
            for item in container:
                if type(item) is dict or type(item) is list:
                    todo.append((item, depth + 1))
    return value


def decode(frames: Sequence[bytes]) -> Message:
    """Decode multipart ``frames`` (``[topic, payload]``) into a message, validated.

    The trust boundary: every field is checked against its type here, once.
    Raises :class:`WireError`, and only that, for any malformed input.
    """
    if not isinstance(frames, (list, tuple)) or len(frames) != 2:
        count = len(frames) if isinstance(frames, (list, tuple)) else type(frames).__name__
        raise WireError(f"expected 2 frames [topic, payload], got {count}")
    topic, payload = frames
    if not isinstance(topic, _BYTES) or not isinstance(payload, _BYTES):
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
    if type(body) is not dict:
        raise WireError(f"payload must be a map, got {type(body).__name__}")
    version = body.get("v")
    # type() rather than isinstance: True and 1.0 both compare equal to 1.
    if type(version) is not int or version != WIRE_VERSION:
        raise WireError(
            f"unsupported wire version {_shown(version)} (expected {WIRE_VERSION})",
            reason="version",
        )
    code = body.get("t")
    cls = _BY_CODE.get(code) if type(code) is str else None
    if cls is None:
        raise WireError(f"unknown message type {_shown(code)}")
    # Every key is required on the wire (the defaults serve constructors only).
    if body.keys() != _PAYLOAD_KEYS[cls]:
        keys = _PAYLOAD_KEYS[cls]
        missing = sorted(keys - body.keys())
        extra = sorted(_shown(key) for key in body.keys() - keys)
        raise WireError(
            f"{cls.__name__}: missing keys {missing}, unexpected keys {_cut(', '.join(extra))}"
        )
    for key, label in _PLAIN_KEYS[cls]:
        plain_map(body[key], label)
    try:
        msg: Message = msgspec.convert(body, cls, builtin_types=_NATIVE)  # type: ignore[assignment]
    except msgspec.ValidationError as exc:
        raise _field_error(cls, body, exc) from exc
    if type(topic) is not bytes:
        topic = bytes(topic)
    if topic != msg.topic:
        raise WireError(f"{cls.__name__} on topic {topic!r}, expected {msg.topic!r}")
    return msg


def _field_error(cls: type[_Base], body: dict[str, Any], exc: Exception) -> WireError:
    """The error naming the field at fault (msgspec's own text names its wire key)."""
    for key, name, kind in _FIELDS[cls]:
        try:
            msgspec.convert(body[key], kind, builtin_types=_NATIVE)
        except msgspec.ValidationError as field_exc:
            return WireError(f"{cls.__name__}.{name}: {_cut(str(field_exc))}")
    return WireError(_cut(str(exc)))  # a check across fields (ReportPart's)


def _shown(value: Any) -> str:
    """``value`` for an error text: a short repr of a scalar, else only its type."""
    if type(value) is str or type(value) is bytes:
        shown = repr(value[:40])
        return shown if len(value) <= 40 else shown + "..."
    if value is None or type(value) in (int, float, bool):
        return repr(value)
    return f"of type {type(value).__name__}"


def _cut(text: str, limit: int = 300) -> str:
    return text if len(text) <= limit else text[:limit] + "..."
