"""``indgen view DIR``: browse every run under a folder on http://127.0.0.1 (the index, each run's report.html, a live
page for a running run); loopback only, since run directories hold policy specs, paths and videos."""

from __future__ import annotations

import argparse
import functools
import socket
from dataclasses import dataclass
from http import HTTPStatus
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import unquote, urlsplit

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.reporting.html_index import REFRESH_S, find_rows, index_page
from indgen_vla.core.reporting.html_page import Section, esc, render_page

LOOPBACK = ("127.0.0.1", "localhost", "::1")
DEFAULT_PORT = 8765


@dataclass(frozen=True)
class ViewConfig:
    """What ``indgen view`` serves and where; checked on construction."""

    root: Path
    port: int = DEFAULT_PORT
    host: str = "127.0.0.1"

    def __post_init__(self) -> None:
        if self.host not in LOOPBACK:
            raise ConfigError(f"indgen view serves on 127.0.0.1 only (runs hold policy specs, paths and videos), "
                              f"not --host {self.host}; to browse from elsewhere forward the port: ssh -L "
                              f"{self.port}:127.0.0.1:{self.port} THIS_HOST")  # fmt: skip
        if not 0 <= self.port <= 65535:
            raise ConfigError(f"--port {self.port} must lie in 0..65535 (0: any free port)")
        if not Path(self.root).is_dir():
            raise ConfigError(
                f"{self.root} is not a directory; give the folder that holds your runs, e.g. demo_out"
            )


class _Handler(SimpleHTTPRequestHandler):
    """Static files under the served folder, plus ``/`` (the index) and ``/live/RUN`` (a live run page)."""

    def do_GET(self) -> None:  # noqa: N802 (http.server's name)
        path = unquote(urlsplit(self.path).path)
        root = Path(self.directory).resolve()
        if path in ("/", "/index.html") and not (root / "index.html").is_file():
            return self._send(index_page(root, find_rows(root)))
        if path.startswith("/live/"):
            run = (root / path[len("/live/") :].strip("/")).resolve()
            inside, raw = root == run or root in run.parents, urlsplit(self.path).path  # raw: still quoted
            # a file the live page links relatively (videos/, protocol.md) is the run's own: /RUN/...
            if inside and run.is_file():
                self.path = raw[len("/live") :]
                return super().do_GET()
            if not inside or not (run / "manifest.json").is_file():
                return self.send_error(HTTPStatus.NOT_FOUND, "no run directory there")
            # the page lives at /live/RUN/, so that its relative links (videos/x.mp4) stay inside the run
            if not raw.endswith("/"):
                self.send_response(HTTPStatus.MOVED_PERMANENTLY)
                self.send_header("Location", raw + "/")
                self.send_header("Content-Length", "0")
                self.end_headers()
                return None
            try:
                from indgen_vla.core.reporting.live_page import live_page  # lazy: start-up (numpy)

                return self._send(live_page(run))
            except Exception as e:  # a half-written run: say so on the page, keep serving
                return self._send(render_page("Live run", [Section("error", "Not readable yet", f"<p>{esc(e)}</p>")],
                                              str(run), REFRESH_S))  # fmt: skip
        return super().do_GET()

    def _send(self, page: str) -> None:
        data = page.encode()
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", "text/html; charset=utf-8")
        self.send_header("Content-Length", str(len(data)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(data)

    def log_message(self, format, *args) -> None:  # noqa: A002 (http.server's signature)
        pass  # quiet: the terminal shows the URL, not every request


class _Server6(ThreadingHTTPServer):
    address_family = socket.AF_INET6


def make_server(cfg: ViewConfig) -> ThreadingHTTPServer:
    """The bound (not yet serving) server of ``cfg``; one clear line when the port is taken."""
    handler = functools.partial(_Handler, directory=str(Path(cfg.root).resolve()))
    host = "127.0.0.1" if cfg.host == "localhost" else cfg.host
    try:
        return (_Server6 if host == "::1" else ThreadingHTTPServer)((host, cfg.port), handler)
    except OSError as e:
        raise ConfigError(f"cannot serve on {host}:{cfg.port}: {e.strerror}; pick another --port (0: any free "
                          "port)") from None  # fmt: skip


def add_parser(sp: argparse._SubParsersAction) -> None:
    """``indgen view``'s parser."""
    p = sp.add_parser(
        "view", help="browse every run under a folder in a web browser (index, reports, live runs)"
    )
    p.add_argument(
        "root", metavar="DIR", help="folder holding run directories (searched recursively), e.g. demo_out"
    )
    p.add_argument(
        "--port", type=int, default=DEFAULT_PORT, help=f"port (default {DEFAULT_PORT}; 0: any free one)"
    )
    p.add_argument("--host", default="127.0.0.1", help="127.0.0.1 only (any other host is refused)")


def main(args: argparse.Namespace) -> int:
    """Serve until Ctrl-C."""
    server = make_server(ViewConfig(Path(args.root), args.port, args.host))
    host, port = server.server_address[:2]
    print(
        f"serving {len(find_rows(Path(args.root)))} runs of {args.root} on http://{host}:{port}/ (Ctrl-C stops)"
    )
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.server_close()
    return 0
