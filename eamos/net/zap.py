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
raises ``zmq.ZMQError`` (and leaves nothing open).
"""

from __future__ import annotations

from typing import Any, Protocol

import zmq
from zmq.auth.thread import ThreadAuthenticator

__all__ = ["CredentialsProvider", "start_authenticator"]


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
