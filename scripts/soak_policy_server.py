"""Soak test of the engine against flaky policy servers (issue 18): loopback servers speaking the openpi
websocket, OpenVLA-OFT REST and GR00T ZMQ protocols that, on a schedule of request numbers, are killed and
restarted, stall past the client timeout, close the socket mid-reply or answer HTTP 503, and (as episode
faults, a deterministic function of the observation) return NaN actions or wrong shapes.

For each protocol: an undisturbed reference run, a disturbed run (2 workers), then a second invocation with
the episode faults switched off. Checks: every planned episode present exactly once, ``ok`` episodes equal
the reference, episode faults are ``error`` with their cause, exit 0 only without errors, the second
invocation completes the run. Loopback (127.0.0.1) only; every loop is bounded.

    python scripts/soak_policy_server.py --protocols openpi,openvla,groot --out /tmp/soak
"""

from __future__ import annotations

import argparse
import asyncio
import hashlib
import json
import socket
import sys
import threading
import time
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

PROTOCOLS = ("openpi", "openvla", "groot")
HORIZON = 16
STALL_S = 3.0  # longer than the client timeout below
CLIENT = "timeout=1.5&connect_timeout=1.5&render=64"
# request number -> transport fault; HTTP 503 only where there is HTTP, no mid-reply close on ZMQ (atomic)
SCHEDULES = {
    "openpi": {3: "kill", 8: "stall", 13: "close", 18: "kill", 24: "close"},
    "openvla": {2: "kill", 6: "stall", 10: "close", 14: "http503", 18: "kill"},
    "groot": {2: "kill", 6: "stall", 10: "kill", 15: "stall"},
}
POISON_MOD = 23  # an observation whose hash is 0 (1) mod this gets NaN (wrong-shaped) actions


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def obs_hash(*arrays) -> int:
    h = hashlib.blake2b(digest_size=8)
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return int.from_bytes(h.digest(), "little")


def actions_for(key: int, horizon: int = HORIZON) -> np.ndarray:
    """A deterministic function of the observation, so outcomes cannot depend on scheduling or retries."""
    rng = np.random.default_rng(key)
    out = rng.uniform(-0.5, 0.5, size=(horizon, 7)).astype(np.float32)
    out[:, -1] = np.where(rng.random(horizon) < 0.5, 0.0, 1.0)
    return out


@dataclass
class Faults:
    """What a server injects: transport faults by request number, episode faults by observation."""

    schedule: dict[int, str] = field(default_factory=dict)
    poison: bool = False
    down_s: float = 2.0
    n: int = 0
    injected: dict[str, int] = field(default_factory=dict)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def next(self) -> str:
        with self.lock:
            self.n += 1
            kind = self.schedule.get(self.n, "")
        if kind:
            self.injected[kind] = self.injected.get(kind, 0) + 1
        return kind

    def episode_fault(self, key: int) -> str:
        kind = {0: "nan", 1: "shape"}.get(key % POISON_MOD, "") if self.poison else ""
        if kind:
            with self.lock:
                self.injected[kind] = self.injected.get(kind, 0) + 1
        return kind

    def actions(self, key: int) -> np.ndarray:
        kind, out = self.episode_fault(key), actions_for(key)
        if kind == "nan":
            out[2:4] = np.nan
        elif kind == "shape":
            out = out[:, :5]
        return out


class _Server:
    """Start/kill/restart on a fixed port; ``kill`` drops every connection and comes back after ``down_s``."""

    def __init__(self, faults: Faults, port: int | None = None):
        self.faults, self.port = faults, port or free_port()
        self.restarts = 0

    def kill_and_restart(self) -> None:
        def cycle():
            self.stop()
            time.sleep(self.faults.down_s)
            self.start()
            self.restarts += 1

        threading.Thread(target=cycle, daemon=True).start()


class OpenpiServer(_Server):
    """openpi's websocket policy server protocol: metadata frame on connect, msgpack-numpy request/reply."""

    def start(self) -> None:
        ready = threading.Event()

        async def handler(ws):
            from policy_wrappers import msgpack_numpy

            await ws.send(msgpack_numpy.packb({"server": "soak"}))
            async for frame in ws:
                req = msgpack_numpy.unpackb(frame)
                kind = self.faults.next()
                if kind == "kill":
                    self.kill_and_restart()
                    return
                if kind == "stall":
                    await asyncio.sleep(STALL_S)
                    return
                if kind == "close":  # a binary frame header announcing 4096 bytes, 10 of them, then gone
                    ws.transport.write(b"\x82\x7e\x10\x00" + b"\x00" * 10)
                    ws.transport.abort()
                    return
                key = obs_hash(req["observation/state"], req["observation/image"])
                await ws.send(msgpack_numpy.packb({"actions": self.faults.actions(key)}))

        async def main():
            from websockets.asyncio.server import serve

            self._loop, self._stop = asyncio.get_running_loop(), asyncio.Event()
            async with serve(handler, "127.0.0.1", self.port, compression=None, max_size=None) as server:
                self._server = server
                ready.set()
                await self._stop.wait()
                for conn in list(server.connections):
                    conn.transport.abort()  # killed, not a polite close

        self._thread = threading.Thread(target=lambda: asyncio.run(main()), daemon=True)
        self._thread.start()
        assert ready.wait(10), "openpi soak server did not start"

    def stop(self) -> None:
        self._loop.call_soon_threadsafe(self._stop.set)
        self._thread.join(10)

    def spec(self) -> str:
        return f"openpi:ws://127.0.0.1:{self.port}?{CLIENT}&size=64&chunk=10&replan=5"


class OpenVLAServer(_Server):
    """OpenVLA-OFT's deploy.py protocol: POST /act with a json-numpy body, a json-numpy list of actions."""

    def start(self) -> None:
        from policy_wrappers.openvla import dumps, loads

        outer = self

        class Handler(BaseHTTPRequestHandler):
            protocol_version = "HTTP/1.1"

            def do_POST(self):  # noqa: N802
                req = loads(self.rfile.read(int(self.headers["Content-Length"])))
                kind = outer.faults.next()
                if kind == "kill":
                    outer.kill_and_restart()
                    self.close_connection = True
                    return
                if kind == "stall":
                    time.sleep(STALL_S)
                    self.close_connection = True
                    return
                if kind == "http503":
                    self.send_response(503)
                    self.send_header("Content-Length", "0")
                    self.end_headers()
                    return
                key = obs_hash(req["state"], req["full_image"])
                data = dumps(list(outer.faults.actions(key)[:8])).encode()
                self.send_response(200)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                if kind == "close":  # half the body, then the socket goes away
                    self.wfile.write(data[: len(data) // 2])
                    self.wfile.flush()
                    self.close_connection = True
                    return
                self.wfile.write(data)

            def log_message(self, *args):
                pass

        ThreadingHTTPServer.allow_reuse_address = True
        self.httpd = ThreadingHTTPServer(("127.0.0.1", self.port), Handler)
        self.httpd.daemon_threads = True
        self._thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()

    def spec(self) -> str:
        return f"openvla-oft:http://127.0.0.1:{self.port}?{CLIENT}&size=64"


class GrootServer(_Server):
    """Isaac-GR00T N1.5's ZMQ REP inference service (ping, get_modality_config, get_action)."""

    def start(self) -> None:
        import zmq

        self._ctx = zmq.Context()
        self._sock = self._ctx.socket(zmq.REP)
        self._sock.setsockopt(zmq.LINGER, 0)
        self._sock.bind(f"tcp://127.0.0.1:{self.port}")
        self._running = True
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._thread.start()

    def _loop(self) -> None:
        from policy_wrappers.msgpack_numpy import groot_packb, groot_unpackb

        sock = self._sock
        while self._running:
            if not sock.poll(50):
                continue
            req = groot_unpackb(sock.recv())
            endpoint = req.get("endpoint")
            if endpoint != "get_action":
                sock.send(groot_packb({"status": "ok"} if endpoint == "ping" else {}))
                continue
            kind = self.faults.next()
            if kind == "kill":
                self._running = False
                sock.close(linger=0)
                self._ctx.term()
                threading.Thread(target=self._restart, daemon=True).start()
                return
            if kind == "stall":
                time.sleep(STALL_S)
            data = req["data"]
            state = np.concatenate([np.ravel(data[k]) for k in sorted(data) if k.startswith("state.")])
            acts = self.faults.actions(obs_hash(state.astype(np.float32), data["video.image"]))
            names = ("x", "y", "z", "roll", "pitch", "yaw", "gripper")
            reply = {f"action.{n}": acts[:, j : j + 1] for j, n in enumerate(names[: acts.shape[1]])}
            if acts.shape[1] != 7:  # the wrong-shape fault: a 3-wide "x" and every key present
                reply = {f"action.{n}": acts[:, :1] for n in names} | {"action.x": acts[:, :3]}
            sock.send(groot_packb(reply))

    def _restart(self) -> None:
        time.sleep(self.faults.down_s)
        self.start()
        self.restarts += 1

    def stop(self) -> None:
        if self._running:
            self._running = False
            self._thread.join(5)
            self._sock.close(linger=0)
            self._ctx.term()

    def spec(self) -> str:
        return f"groot:tcp://127.0.0.1:{self.port}?{CLIENT}&api=n1.5&replan=8&chunk=16"


SERVERS = {"openpi": OpenpiServer, "openvla": OpenVLAServer, "groot": GrootServer}


def evaluate_cli(spec: str, out: Path, episodes: int, max_steps: int, workers: int) -> int:
    """One ``indgen evaluate`` invocation in this process (the real CLI entry point and exit code)."""
    from indgen_vla.app.cli import main

    return main(["evaluate", "--policy", spec, "--scene", "pick_place", "--axis", "pick_y", "--levels", "0:1",
                 "--episodes", str(episodes), "--max-steps", str(max_steps), "--workers", str(workers),
                 "--server-patience", "60", "--out", str(out)])  # fmt: skip


def outcomes(out: Path) -> dict:
    import pandas as pd

    df = pd.read_parquet(out / "episodes.parquet")
    return {(r.task, r.axis, int(r.level), int(r.episode)): (int(r.seed), bool(r.success), int(r.steps),
            r.status, r.failure, r.error) for r in df.itertuples()}  # fmt: skip


def soak(protocol: str, root: Path, episodes: int = 3, max_steps: int = 30, workers: int = 2) -> dict:
    """Reference, disturbed and completing runs for one protocol; returns the measured facts (raises on a
    violated check)."""
    import pandas as pd

    faults = Faults()
    server = SERVERS[protocol](faults)
    server.start()
    try:
        ref = root / f"{protocol}_ref"
        rc_ref = evaluate_cli(server.spec(), ref, episodes, max_steps, workers)
        faults.schedule, faults.poison, faults.n = SCHEDULES[protocol], True, 0
        run = root / f"{protocol}_soak"
        t0 = time.time()
        rc1 = evaluate_cli(server.spec(), run, episodes, max_steps, workers)
        wall1 = time.time() - t0
        first = outcomes(run)
        df = pd.read_parquet(run / "episodes.parquet")
        injected = dict(faults.injected)
        faults.schedule, faults.poison = {}, False
        rc2 = evaluate_cli(server.spec(), run, episodes, max_steps, workers)
        final = outcomes(run)
        final_df = pd.read_parquet(run / "episodes.parquet")
    finally:
        server.stop()
    reference = outcomes(ref)
    planned = 2 * episodes
    keys = list(zip(df["task"], df["axis"], df["level"], df["episode"], strict=True))
    errors = {k: v for k, v in first.items() if v[3] == "error"}
    same = {k for k, v in first.items() if v[3] == "ok" and v[:5] == reference[k][:5]}
    final_latest = final_df.drop_duplicates(["task", "axis", "level", "episode"], keep="last")
    facts = {
        "protocol": protocol,
        "planned": planned,
        "rc_reference": rc_ref,
        "rc_first": rc1,
        "rc_second": rc2,
        "wall_first_s": round(wall1, 1),
        "injected": injected,
        "restarts": server.restarts,
        "episodes_first": len(first),
        "duplicated": len(keys) - len(set(keys)),
        "lost": planned - len(first),
        "errors_first": len(errors),
        "error_causes": sorted({v[5][:140] for v in errors.values()}),
        "ok_equal_reference": len(same),
        "ok_first": sum(v[3] == "ok" for v in first.values()),
        "final_all_ok": bool(len(final_latest) == planned and (final_latest["status"] == "ok").all()),
        "final_equal_reference": {k: v[:5] for k, v in final.items()}
        == {k: v[:5] for k, v in reference.items()},
    }
    problems = []
    if rc_ref != 0 or len(reference) != planned:
        problems.append("the undisturbed reference run failed")
    if facts["lost"] or facts["duplicated"]:
        problems.append("episodes lost or duplicated")
    if facts["ok_equal_reference"] != facts["ok_first"]:
        problems.append("an ok episode differs from the undisturbed run")
    if any("non-finite" not in v[5] and "shape" not in v[5] for v in errors.values()):
        problems.append("an error episode does not name an episode fault as its cause")
    if rc1 != (3 if errors else 0):
        problems.append(f"first invocation exited {rc1} with {len(errors)} error episode(s)")
    if rc2 != 0 or not facts["final_all_ok"] or not facts["final_equal_reference"]:
        problems.append("the second invocation did not complete the run to the reference outcomes")
    facts["problems"] = problems
    return facts


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--protocols", default=",".join(PROTOCOLS))
    parser.add_argument("--out", default="/tmp/indgen_soak")
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--max-steps", type=int, default=30)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args(argv)
    root = Path(args.out)
    root.mkdir(parents=True, exist_ok=True)
    bad = 0
    for protocol in [p.strip() for p in args.protocols.split(",") if p.strip()]:
        if protocol not in SERVERS:
            print(
                f"error: unknown protocol {protocol!r}; choose from {', '.join(PROTOCOLS)}", file=sys.stderr
            )
            return 2
        facts = soak(protocol, root / protocol, args.episodes, args.max_steps, args.workers)
        print(json.dumps(facts), flush=True)
        bad += bool(facts["problems"])
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
