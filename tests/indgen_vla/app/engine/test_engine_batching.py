import multiprocessing as mp
import threading
import time

from indgen_vla.app.engine.batching import Ready


class _Pipe:
    """The worker side the coordinator sees: a connection it selects on and polls."""

    def __init__(self):
        self.conn, self.child = mp.Pipe()

    def poll(self) -> bool:
        return self.conn.poll()


def test_ready_reports_only_busy_workers_with_a_reply_and_never_spins_on_idle_ones():
    pool = [_Pipe() for _ in range(3)]
    ready = Ready(pool)
    try:
        assert ready.now([0, 1, 2]) == []
        pool[2].child.send_bytes(b"x")
        pool[0].child.send_bytes(b"x")
        assert ready.now([0, 1, 2]) == [0, 2]  # sorted: rows of a batch keep the worker order
        assert ready.now([1]) == []  # a reply of a worker that is not busy is not this round's
        pool[1].child.close()  # an idle worker's pipe at EOF stays readable: waiting must not return for it
        t0 = time.monotonic()
        assert ready.wait([0], 0.2) == [0]
        pool[0].conn.recv_bytes()
        assert ready.wait([0], 0.2) == [] and time.monotonic() - t0 >= 0.2
        late = threading.Timer(0.1, pool[0].child.send_bytes, args=(b"x",))
        late.start()
        assert ready.gather([0, 2], [2], window_s=2.0) == [0, 2]  # waits for the late one, not the window
        assert time.monotonic() - t0 < 2.0
        assert ready.gather([0, 2], [2], window_s=0.0) == [2]
    finally:
        ready.close()
