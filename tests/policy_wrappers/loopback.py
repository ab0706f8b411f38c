"""Tiny loopback servers speaking the real wire protocols, run in daemon threads on ephemeral ports."""

from __future__ import annotations

import asyncio
import threading


class WebsocketServer:
    """An asyncio websockets server in a thread; ``handler(ws)`` is an async function of the connection."""

    def __init__(self, handler, process_request=None):
        self.handler, self.process_request = handler, process_request
        self.port = None
        self._ready = threading.Event()

    async def _main(self):
        from websockets.asyncio.server import serve

        self._stop = asyncio.Event()
        self._loop = asyncio.get_running_loop()
        async with serve(
            self.handler,
            "127.0.0.1",
            0,
            compression=None,
            max_size=None,
            process_request=self.process_request,
        ) as server:
            self.port = server.sockets[0].getsockname()[1]
            self._ready.set()
            await self._stop.wait()

    def __enter__(self):
        self._thread = threading.Thread(target=lambda: asyncio.run(self._main()), daemon=True)
        self._thread.start()
        assert self._ready.wait(10)
        return self

    def __exit__(self, *exc):
        self._loop.call_soon_threadsafe(self._stop.set)
        self._thread.join(5)
