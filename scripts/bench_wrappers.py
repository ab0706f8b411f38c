"""Per-call overhead of each policy wrapper and batched vs one-by-one inference; prints one JSON line.

Every remote family runs against a loopback server speaking its real wire format with a zero-compute
policy behind it, so the round trip is the wrapper's own cost (conversion + encoding + transport). The
in-process tiny ACT (random init, 2x32x32 cameras) gives a policy-compute reference.

    .venv/bin/python scripts/bench_wrappers.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import numpy as np

os.environ.setdefault("HF_HUB_OFFLINE", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from indgen_vla.core.protocol.interface import Observation  # noqa: E402
from policy_wrappers import msgpack_numpy  # noqa: E402


def obs(seed: int, size: int = 256) -> Observation:
    rng = np.random.default_rng(seed)
    images = {c: rng.integers(0, 256, (size, size, 3), dtype=np.uint8) for c in ("agentview", "wrist")}
    return Observation(images, rng.normal(size=8).astype(np.float32), "put the bowl on the plate")


def timed(fn, n: int, warmup: int = 5) -> float:
    """Median wall time of ``fn()`` in milliseconds."""
    for _ in range(warmup):
        fn()
    samples = []
    for _ in range(n):
        t = time.perf_counter()
        fn()
        samples.append((time.perf_counter() - t) * 1000)
    return round(statistics.median(samples), 3)


def bench_openpi(n: int) -> dict:
    from policy_wrappers.openpi import make_request
    from policy_wrappers.serve import PolicyServer
    from policy_wrappers.specs import load_policy

    server = PolicyServer(load_policy("standin:noop?chunk=10"), port=0)
    port = server.start_background()
    client = load_policy(f"openpi:ws://127.0.0.1:{port}")
    o = obs(0)
    packed_reply = msgpack_numpy.packb(
        {"actions": np.zeros((10, 7), np.float32), "server_timing": {"infer_ms": 0.1}}
    )
    out = {
        "encode_ms": timed(lambda: msgpack_numpy.packb(make_request(o, client.config.conventions.images)), n),
        "decode_ms": timed(lambda: msgpack_numpy.unpackb(packed_reply), n),
        "roundtrip_ms": timed(lambda: client.act([o]), n),
    }
    client.close()
    server.stop()
    return out


def bench_openvla(n: int) -> dict:
    from policy_wrappers.openvla import dumps, loads
    from policy_wrappers.specs import load_policy

    reply = dumps([np.zeros(7, np.float32)] * 8).encode()

    class Handler(BaseHTTPRequestHandler):
        protocol_version = "HTTP/1.1"

        def do_POST(self):  # noqa: N802
            loads(self.rfile.read(int(self.headers["Content-Length"])))
            self.send_response(200)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(reply)))
            self.end_headers()
            self.wfile.write(reply)

        def log_message(self, *args):
            pass

    httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    client = load_policy(f"openvla-oft:http://127.0.0.1:{httpd.server_address[1]}")
    o = obs(0)
    out = {
        "encode_ms": timed(lambda: dumps(client.make_payload(o)), n),
        "decode_ms": timed(lambda: loads(reply), n),
        "roundtrip_ms": timed(lambda: client.act([o]), n),
    }
    httpd.shutdown()
    return out


def bench_groot(n: int) -> dict:
    import zmq

    from policy_wrappers.specs import load_policy

    reply_n16 = msgpack_numpy.groot_packb(
        [
            {
                f"action.{k}": np.zeros((1, 16, 1), np.float32)
                for k in ("x", "y", "z", "roll", "pitch", "yaw", "gripper")
            },
            {},
        ]
    )
    ctx = zmq.Context()
    sock = ctx.socket(zmq.REP)
    port = sock.bind_to_random_port("tcp://127.0.0.1")
    running = True

    def loop():
        while running:
            if sock.poll(20):
                req = msgpack_numpy.groot_unpackb(sock.recv())
                ep = req.get("endpoint")
                sock.send(
                    reply_n16
                    if ep == "get_action"
                    else msgpack_numpy.groot_packb({"status": "ok"} if ep == "ping" else {})
                )

    thread = threading.Thread(target=loop, daemon=True)
    thread.start()
    client = load_policy(f"groot:tcp://127.0.0.1:{port}?gripper=raw")
    o = obs(0)
    out = {
        "encode_ms": timed(
            lambda: msgpack_numpy.groot_packb(
                {
                    "endpoint": "get_action",
                    "data": {"observation": client.make_observation([o]), "options": None},
                }
            ),
            n,
        ),
        "decode_ms": timed(lambda: msgpack_numpy.groot_unpackb(reply_n16), n),
        "roundtrip_ms": timed(lambda: client.act([o]), n),
    }
    client.close()
    running = False
    thread.join(1)
    sock.close(linger=0)
    ctx.term()
    return out


def bench_lerobot(n: int, batch: int, ckpt: str, threads: int) -> dict:
    import torch

    from policy_wrappers.serve import PolicyServer
    from policy_wrappers.specs import load_policy

    torch.set_num_threads(threads)
    policy = load_policy(f"lerobot:{ckpt}")
    o = obs(0)
    with torch.inference_mode():
        pre = policy.pre(policy.to_batch([o]))
        actions = policy.policy.predict_action_chunk(pre)
        out = {
            "convert_ms": timed(lambda: policy.pre(policy.to_batch([o])), n),
            "model_ms": timed(lambda: policy.policy.predict_action_chunk(pre), n),
            "post_ms": timed(lambda: policy.post(actions), n),
        }
    out["act_ms"] = timed(lambda: policy.act([o]), n)
    server = PolicyServer(policy, port=0)
    port = server.start_background()
    client = load_policy(f"openpi:ws://127.0.0.1:{port}?chunk=10&replan=10")
    out["served_over_openpi_ms"] = timed(lambda: client.act([o]), n)
    client.close()
    server.stop()
    many = [obs(i) for i in range(batch)]
    out[f"batched_b{batch}_ms"] = timed(lambda: policy.act(many), max(3, n // 4))
    out[f"one_by_one_b{batch}_ms"] = timed(lambda: [policy.act([m]) for m in many], max(3, n // 4))
    out["batched_speedup"] = round(out[f"one_by_one_b{batch}_ms"] / out[f"batched_b{batch}_ms"], 2)
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="few iterations (smoke run, ~25 s)")
    parser.add_argument("--batch", type=int, default=8)
    parser.add_argument("--threads", type=int, default=1, help="torch threads for the in-process policy")
    args = parser.parse_args(argv)
    n = 10 if args.quick else 50
    result = {
        "bench": "policy_wrappers",
        "iters": n,
        "image": "2 cameras 256x256 uint8",
        "torch_threads": args.threads,
    }
    result["openpi"] = bench_openpi(n)
    result["openvla_oft"] = bench_openvla(n)
    result["groot_n16"] = bench_groot(n)
    try:
        from tests.fixtures.tiny_policies import build_tiny_checkpoint

        with tempfile.TemporaryDirectory() as tmp:
            result["lerobot_tiny_act"] = bench_lerobot(
                n, args.batch, build_tiny_checkpoint("act", tmp), args.threads
            )
    except ImportError as e:
        result["lerobot_tiny_act"] = {"skipped": str(e)}
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
