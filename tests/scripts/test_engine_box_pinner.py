"""The bench's ``--pin`` spreads workers over the cores the coordinator does not keep (a bug put them all on core 0)."""

import multiprocessing as mp
import os
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
from _engine_box import Pinner  # noqa: E402


def _report_affinity(q, ready) -> None:
    ready.wait(5)
    q.put(sorted(os.sched_getaffinity(0)))


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="needs two cores to tell core 0 from the rest")
def test_pinned_workers_run_on_the_cores_the_coordinator_left():
    cores = sorted(os.sched_getaffinity(0))
    ctx = mp.get_context("forkserver")
    q, ready = ctx.Queue(), ctx.Event()
    with Pinner(True, period_s=0.005) as pinner:
        assert sorted(os.sched_getaffinity(0)) == cores[:1]
        procs = [ctx.Process(target=_report_affinity, args=(q, ready)) for _ in range(2)]
        for p in procs:
            p.start()
        deadline = time.monotonic() + 10
        while len(pinner._done) < len(procs) and time.monotonic() < deadline:  # the poller pins each it sees
            time.sleep(0.005)
        ready.set()
        seen = sorted(q.get(timeout=10) for _ in procs)
        for p in procs:
            p.join(5)
    assert sorted(os.sched_getaffinity(0)) == cores
    assert all(len(a) == 1 and a[0] != cores[0] for a in seen), seen
    assert seen == sorted([[c] for c in (cores[1:] * 2)[:2]])
