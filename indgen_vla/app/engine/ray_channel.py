"""The fast lane from a simulator actor to the policy actor on its own node: a Unix socket carrying plain pickles,
as the local backend's pipes do, instead of one Ray actor call per policy call.

A Ray actor call costs ≈ 1.5 ms of round trip, and CPU on both sides, on a 2-core VM (the policy actor's task
queue, the core workers, futures); the oracle asks its policy every control step, so that was most of the Ray
backend's extra wall time on a small box (docs/results/benchmarks/speed.md). Simulators on another node, and any
that cannot connect, call through Ray as before. The socket lives in Linux's abstract namespace (it vanishes with
its process: a killed actor leaves no file behind) and a connection must know the channel's random key. A dead
policy actor closes its sockets, so its clients see the end of the stream at once.
"""

from __future__ import annotations

import os
import pickle
import secrets
import sys
import threading
from collections.abc import Callable
from dataclasses import dataclass
from multiprocessing import AuthenticationError
from multiprocessing.connection import Client, Connection, Listener

SOCKET_ENV = "INDGEN_RAY_SOCKET"  # 0: every policy call goes through Ray (a knob of ray_backend.ENV_KNOBS)


@dataclass(frozen=True)
class Address:
    """Where a policy actor's channel listens: its Ray node, its socket's name, and the key a client must show."""

    node: str
    name: str
    key: bytes


def available() -> bool:
    """Abstract Unix sockets are Linux's; elsewhere every call goes through Ray."""
    return sys.platform.startswith("linux")


class ChannelServer:
    """Serves ``handler(op, client, args)`` for each connection on its own thread: a simulator has at most one call
    in flight, as it had through the actor's ``max_concurrency`` threads. Replies are values (the actor's methods
    return exceptions as values); one that does not pickle goes back as a ``RuntimeError`` with its line."""

    def __init__(self, node: str, handler: Callable[[str, int, tuple], object]):
        self.handler = handler
        self.address = Address(
            node, f"\0indgen-policy-{os.getpid()}-{secrets.token_hex(8)}", secrets.token_bytes(16)
        )
        self._listener = Listener(self.address.name, family="AF_UNIX", authkey=self.address.key)
        self._closed = threading.Event()
        threading.Thread(target=self._accept, name="indgen-channel", daemon=True).start()

    def _accept(self) -> None:
        while not self._closed.is_set():
            try:
                conn = self._listener.accept()
            except (OSError, EOFError, AuthenticationError):  # a stranger, or the listener closed
                continue
            threading.Thread(
                target=self._serve, args=(conn,), name="indgen-channel-client", daemon=True
            ).start()

    def _serve(self, conn: Connection) -> None:
        with conn:
            while not self._closed.is_set():
                try:
                    op, client, args = pickle.loads(conn.recv_bytes())
                except (EOFError, OSError):  # the simulator closed or died
                    return
                reply = self.handler(op, client, args)
                try:
                    data = pickle.dumps(reply, protocol=pickle.HIGHEST_PROTOCOL)
                except Exception as e:  # noqa: BLE001 - any pickling failure: the reply's line still goes back
                    data = pickle.dumps(RuntimeError(f"{type(reply).__name__} reply does not pickle: {e}"))
                try:
                    conn.send_bytes(data)
                except OSError:
                    return

    def close(self) -> None:
        self._closed.set()
        self._listener.close()


class ChannelLost(Exception):  # noqa: N818 - the caller turns it into its own signal
    """The policy actor's end of the socket is gone (the actor died or closed)."""


class ChannelClient:
    """A simulator's end: ``call(op, client, *args)`` returns the policy actor's reply value."""

    def __init__(self, address: Address):
        self._conn = Client(address.name, family="AF_UNIX", authkey=address.key)

    def call(self, op: str, client: int, *args):
        try:
            self._conn.send_bytes(pickle.dumps((op, client, args), protocol=pickle.HIGHEST_PROTOCOL))
            return pickle.loads(self._conn.recv_bytes())
        except (EOFError, OSError) as e:
            raise ChannelLost(type(e).__name__) from None

    def close(self) -> None:
        self._conn.close()


def connect(address: Address | None, node: str) -> ChannelClient | None:
    """A client of the channel at ``address`` when it is on this ``node`` and takes the connection; None otherwise
    (the caller then calls through Ray)."""
    if address is None or address.node != node or not available():
        return None
    try:
        return ChannelClient(address)
    except (OSError, EOFError, AuthenticationError):
        return None
