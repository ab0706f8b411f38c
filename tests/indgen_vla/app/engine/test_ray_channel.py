"""The policy actor's channel: a Unix socket on its node that carries a simulator's calls as plain pickles."""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import time

import numpy as np
import pytest

from indgen_vla.app.engine.ray_channel import Address, ChannelLost, ChannelServer, available, connect
from indgen_vla.core.errors import PolicyConnectionError
from indgen_vla.core.protocol.interface import Observation

pytestmark = pytest.mark.skipif(not available(), reason="abstract Unix sockets are Linux's")


def _reply(op: str, client: int, args: tuple):
    """What the policy actor's ``_on_call`` does: a value, or an exception as a value."""
    if op == "act":
        (obs,) = args
        return np.full((2, 7), float(obs.state.sum()) + client, np.float32)
    if op == "down":
        return PolicyConnectionError("openpi server at ws://h:8000 unreachable")
    if op == "lambda":
        return lambda: None  # does not pickle
    return ValueError(f"unknown policy call {op!r}")


def test_a_client_on_the_node_gets_replies_and_errors_as_values():
    server = ChannelServer("node-a", _reply)
    try:
        client = connect(server.address, "node-a")
        assert client is not None
        obs = Observation(
            {"agentview": np.zeros((8, 8, 3), np.uint8)}, np.arange(8, dtype=np.float32), "pick"
        )
        np.testing.assert_array_equal(client.call("act", 3, obs), np.full((2, 7), 28 + 3, np.float32))
        err = client.call("down", 0)
        assert isinstance(err, PolicyConnectionError) and "unreachable" in str(
            err
        )  # its type survives the trip
        err = client.call("lambda", 0)
        assert isinstance(err, RuntimeError) and "does not pickle" in str(err)
        np.testing.assert_array_equal(
            client.call("act", 0, obs), np.full((2, 7), 28, np.float32)
        )  # still serving
        client.close()
    finally:
        server.close()


def test_no_channel_off_the_node_without_the_key_or_without_an_address():
    server = ChannelServer("node-a", _reply)
    try:
        assert connect(server.address, "node-b") is None  # another node: calls go through Ray
        assert connect(None, "node-a") is None
        stranger = Address("node-a", server.address.name, b"0" * 16)
        assert connect(stranger, "node-a") is None  # a wrong key is refused
        assert connect(Address("node-a", "\0indgen-policy-nobody", b"k"), "node-a") is None  # nothing listens
        client = connect(server.address, "node-a")  # the server still accepts after a refused stranger
        assert client is not None and client.call(
            "act", 0, Observation({}, np.ones(8, np.float32), "x")
        ).shape == (2, 7)
        client.close()
    finally:
        server.close()


def _serve_in_child(conn) -> None:
    server = ChannelServer("node-a", _reply)
    conn.send(server.address)
    time.sleep(600)


def test_a_dead_policy_process_is_seen_at_once():
    """The actor's process killed: the simulator's next call raises ChannelLost instead of waiting."""
    ctx = mp.get_context("spawn")
    parent, child = ctx.Pipe()
    proc = ctx.Process(target=_serve_in_child, args=(child,), daemon=True)
    proc.start()
    try:
        address = parent.recv()
        client = connect(address, "node-a")
        obs = Observation({}, np.ones(8, np.float32), "x")
        assert client.call("act", 1, obs)[0, 0] == 9
        os.kill(proc.pid, signal.SIGKILL)
        proc.join(10)
        t0 = time.monotonic()
        with pytest.raises(ChannelLost):
            client.call("act", 1, obs)
        assert time.monotonic() - t0 < 5
    finally:
        if proc.is_alive():
            proc.kill()
