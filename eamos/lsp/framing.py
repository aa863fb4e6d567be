"""The language server's framing: ``Content-Length`` headers and bodies, and what to do
when a frame lies about its length.

Pure (no thread, no I/O): :class:`FrameReader` is fed the bytes read from the editor and
gives back :class:`Frame` (a body to decode) and :class:`BadFrame` (something that is not
a frame; the server answers it with an error when it can and goes on).  pygls' own reader
trusts every header: after one frame whose ``Content-Length`` is wrong or missing, it
reads the next messages as the body (or as headers) and the server answers nothing more.
This reader finds its way back to the next ``Content-Length`` header instead:

* a header block without a valid ``Content-Length`` is refused, and reading goes on
  after it;
* a ``Content-Length`` over :data:`MAX_BODY_BYTES` is refused at once, and the bytes
  up to the next header skipped;
* a length longer than the body (the body's JSON ends, and a ``Content-Length`` header
  follows, before the length is reached) ends the frame there: refused, and the next
  header read;
* a length shorter than the body cuts it: the cut body is refused (not JSON), and the
  rest, up to the next header, skipped;
* bytes between frames that are no header are skipped (said once per run of them).
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass

__all__ = ["MAX_BODY_BYTES", "BadFrame", "Frame", "FrameReader"]

#: The largest body taken: a mission file is at most 2 MB, and JSON may escape every
#: character of it (``\u0000`` is six).
MAX_BODY_BYTES = 16 << 20
#: The largest header block (a few short lines in practice).
MAX_HEADER_BYTES = 8 << 10

_HEADER = re.compile(rb"Content-Length:", re.IGNORECASE)
_LENGTH = re.compile(rb"(?im)^Content-Length:[ \t]*([0-9]{1,12})[ \t]*\r?$")
_END_OF_HEADERS = re.compile(rb"\r?\n\r?\n")
#: What a step returns when it read something but has nothing to give back yet.
_READ = object()


@dataclass(frozen=True)
class Frame:
    """A frame's body, as its header announced it."""

    body: bytes


@dataclass(frozen=True)
class BadFrame:
    """Bytes that are no frame: why, and the body if there was one (to find its id)."""

    reason: str
    body: bytes = b""


class FrameReader:
    """``feed(bytes)`` -> the frames (and bad frames) complete so far, in order."""

    def __init__(self) -> None:
        self._buffer = bytearray()
        self._length: int | None = None  # the body length of the header just read
        self._skipping = False  # dropping bytes until the next header
        self._orphan = False  # what is dropped is the body of a header refused

    def feed(self, data: bytes) -> list[Frame | BadFrame]:
        """Take ``data`` (any chunk of the stream); return what it completed."""
        self._buffer += data
        out: list[Frame | BadFrame] = []
        while True:
            event = self._header() if self._length is None else self._body(self._length)
            if event is None:
                return out  # more bytes needed
            if event is not _READ:
                out.append(event)  # type: ignore[arg-type]

    def _header(self) -> BadFrame | object | None:
        buffer = self._buffer
        start = _HEADER.search(buffer)
        if start is None:
            if self._orphan and len(buffer) <= MAX_BODY_BYTES:
                return None  # a refused header's body: kept until the next header
            self._orphan = False
            # No header yet: keep only what may be the start of one, drop the rest.
            junk = bytes(buffer[: max(0, len(buffer) - 16)])
            del buffer[: len(junk)]
            return self._skipped(junk)
        if start.start() > 0:
            junk = bytes(buffer[: start.start()])
            del buffer[: start.start()]
            return self._skipped(junk) or _READ
        end = _END_OF_HEADERS.search(buffer)
        if end is None:
            if len(buffer) > MAX_HEADER_BYTES:
                del buffer[: len(b"Content-Length:")]
                self._skipping = True
                return BadFrame("a header block that never ends")
            return None  # the rest of the headers is still to come
        headers = bytes(buffer[: end.start()])
        del buffer[: end.end()]
        self._skipping = False
        match = _LENGTH.search(headers)
        if match is None:
            self._skipping = self._orphan = True
            return BadFrame("a header without a valid Content-Length")
        length = int(match.group(1))
        if length > MAX_BODY_BYTES:
            self._skipping = True
            return BadFrame(f"a Content-Length of {length} bytes, over {MAX_BODY_BYTES}")
        self._length = length
        return _READ

    def _skipped(self, junk: bytes) -> BadFrame | None:
        """Bytes dropped between frames: said once per run of them (None: nothing new).

        After a header refused for its length, what comes before the next header is its
        body: given back (a request's id is in it, for the error the editor waits for).
        """
        orphan, self._orphan = self._orphan, False
        if orphan and junk.strip() and _json_end(junk) is not None:
            return BadFrame("the body after a header without a valid Content-Length", junk)
        if not junk.strip() or self._skipping:
            return None
        self._skipping = True
        return BadFrame(f"{len(junk)} bytes that are no frame")

    def _body(self, length: int) -> Frame | BadFrame | None:
        buffer = self._buffer
        if len(buffer) >= length:
            body = bytes(buffer[:length])
            del buffer[:length]
            self._length = None
            return Frame(body)
        # Not all there yet.  If a header follows a whole JSON value already, the
        # length lied (a client's bug): the body ends there, and so does the wait.
        after = _HEADER.search(buffer)
        if after is None:
            return None
        end = _json_end(bytes(buffer[: after.start()]))
        if end is None:
            return None
        body = bytes(buffer[:end])
        del buffer[:end]
        self._length = None
        return BadFrame(f"a Content-Length of {length} bytes for a body of {len(body)} bytes", body)


def _json_end(data: bytes) -> int | None:
    """Where the JSON value ``data`` starts with ends, if only blanks follow it."""
    try:
        text = data.decode("utf-8")
        _, end = json.JSONDecoder().raw_decode(text.lstrip())
    except (UnicodeDecodeError, ValueError, RecursionError):
        return None
    consumed = len(text) - len(text.lstrip()) + end
    if text[consumed:].strip():
        return None
    return len(data)
