"""The ZAP authenticator of a ZeroMQ context: pyzmq's own, admitting an allow-list of keys.

libzmq asks the ZAP handler bound at ``inproc://zeromq.zap.01`` of a context
whether each CURVE handshake of that context's server sockets may proceed (ZeroMQ
RFC 27).  :func:`start_authenticator` starts pyzmq's
:class:`zmq.auth.thread.ThreadAuthenticator` there, configured for CURVE in one
domain with a credentials provider (``configure_curve_callback``): pyzmq answers
each request as RFC 27 says (a key the provider admits gets 200 with its z85 key as
user id, any other 400 "Unknown key"; another domain "Unknown domain"; NULL is let
through), and the provider decides from the fleet's public keys, read from the key
files (:class:`eamos.net.keys.FleetKeys`), logging the refusals
(:class:`eamos.net.keys.FleetAuthenticator`).

A ZAP handler binds a fixed address, so there is one per context: a second
raises ``zmq.ZMQError`` (and leaves nothing open).  Participants that share a
context (several drones in one process: one context and one authenticator
thread for all of them, not one each) share its handler through a
:class:`ZapHandler`, each answered in a ZAP domain of its own
(:func:`participant_domain`, set on its server socket), so each keeps its own
allow-list and its own count of refusals.
"""

from __future__ import annotations

import threading
from typing import Any, Protocol

import zmq
from zmq.auth.thread import ThreadAuthenticator

__all__ = [
    "ZAP_DOMAIN_PREFIX",
    "CredentialsProvider",
    "ZapHandler",
    "participant_domain",
    "start_authenticator",
]

#: Every participant's ZAP domain starts with it (:func:`participant_domain`).
ZAP_DOMAIN_PREFIX = "eamos/"


def participant_domain(participant: str) -> str:
    """The ZAP domain ``participant``'s server socket names, and its provider answers for."""
    return ZAP_DOMAIN_PREFIX + participant


class CredentialsProvider(Protocol):
    """pyzmq's credentials provider: may a client with this key (z85) join ``domain``?"""

    def callback(self, domain: str, key: bytes) -> bool: ...


class _Refusing:
    """A provider whose exception refuses the connection (and is counted).

    pyzmq lets a provider's exception end its authenticator thread, after which
    no handshake of the context gets an answer: a checker's bug must refuse one
    client, never stop the node from admitting its fleet.
    """

    def __init__(self, provider: CredentialsProvider) -> None:
        self.provider = provider
        self.errors = 0

    def callback(self, domain: str, key: bytes) -> bool:
        try:
            return bool(self.provider.callback(domain, key))
        except Exception:
            self.errors += 1
            return False


def start_authenticator(
    context: zmq.Context[Any], domain: str, provider: CredentialsProvider
) -> ThreadAuthenticator:
    """pyzmq's :class:`~zmq.auth.thread.ThreadAuthenticator` on ``context``, started.

    CURVE clients of ``context``'s server sockets in ``domain`` are admitted when
    ``provider.callback(domain, z85_key)`` says so (an exception refuses).  Stop it
    with ``stop()`` before the context terminates.  Raises ``zmq.ZMQError`` when
    the context has a ZAP handler already.
    """
    auth = ThreadAuthenticator(context)
    auth.configure_curve_callback(domain, _Refusing(provider))
    try:
        auth.start()
    except zmq.ZMQError:
        auth.stop()  # closes the ZAP socket made before its address was found taken
        raise
    return auth


class ZapHandler:
    """The ZAP handler of one ZeroMQ context, shared by the participants it hosts.

    Started with the first :meth:`admit`; each participant adds its domain with its
    own provider (pyzmq's ``configure_curve_callback``, which its authenticator
    reads per request, as pyzmq's examples configure a started one).  Raises
    ``zmq.ZMQError`` at the first :meth:`admit` when the context has a ZAP handler
    that is not this one.  Thread-safe.
    """

    def __init__(self, context: zmq.Context[Any]) -> None:
        self.context = context
        self._lock = threading.Lock()
        self._auth: ThreadAuthenticator | None = None
        self._domains: set[str] = set()
        self._stopped = False

    def admit(self, domain: str, provider: CredentialsProvider) -> None:
        """Answer CURVE handshakes in ``domain`` with ``provider`` (its exception refuses)."""
        with self._lock:
            if self._stopped:
                raise zmq.ZMQError(zmq.ETERM, "the ZAP handler was stopped")
            if domain in self._domains:
                raise zmq.ZMQError(zmq.EADDRINUSE, f"ZAP domain {domain!r} is taken")
            if self._auth is None:
                self._auth = start_authenticator(self.context, domain, provider)
            else:
                self._auth.configure_curve_callback(domain, _Refusing(provider))
            self._domains.add(domain)

    def stop(self) -> None:
        """Stop the authenticator and close its socket (before ``Context.term``); idempotent."""
        with self._lock:
            self._stopped = True
            auth, self._auth = self._auth, None
        if auth is not None:
            auth.stop()
