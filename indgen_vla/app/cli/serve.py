"""``indgen serve``: its parser; the handler serves the policy (``policy_wrappers.serve.serve``) and prints where."""

from __future__ import annotations

import argparse


def add_parser(sp: argparse._SubParsersAction) -> None:
    """The serve subcommand: the policy spec, address, port, API key."""
    p = sp.add_parser("serve", help="serve any policy over openpi's websocket protocol")
    p.add_argument(
        "--policy", required=True, help="policy spec to serve, e.g. lerobot:HUB_ID or standin:oracle"
    )
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default loopback only)")
    p.add_argument("--port", type=int, default=8000, help="port (default 8000)")
    p.add_argument("--api-key", default=None, help="require 'Authorization: Api-Key KEY' from clients")
    p.add_argument(
        "--trust-remote-code", action="store_true", help="allow checkpoints that ship their own code"
    )


def main(args: argparse.Namespace) -> int:
    """Log to the terminal and serve until Ctrl-C."""
    import logging

    from policy_wrappers.serve import serve  # lazy: start-up (numpy)

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(message)s")

    def listening(name: str, port: int) -> None:
        print(
            f"serving {name} on ws://{args.host}:{port} (health: http://{args.host}:{port}/healthz)",
            flush=True,
        )

    serve(args.policy, host=args.host, port=args.port, api_key=args.api_key,
          trust_remote_code=args.trust_remote_code, on_listening=listening)  # fmt: skip
    return 0
