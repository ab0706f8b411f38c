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


class _Overlapping:
    """Per-episode instances (``batched=False``, as a policy server's clients) whose ``act`` takes 200 ms, as a
    server's forward would; ``overlapped`` holds the calls that ran beside another."""

    lock, running, overlapped, calls = threading.Lock(), set(), set(), 0

    def __init__(self):
        import dataclasses

        from tests.fixtures.feedback import feedback_policy_class

        self.inner = feedback_policy_class()()
        self.spec = dataclasses.replace(self.inner.spec, batched=False, replan_steps=1)

    def reset(self, instruction, seed=None):
        pass

    def act(self, observations):
        cls = type(self)
        with cls.lock:
            me = cls.calls = cls.calls + 1
            if cls.running:  # this call and every one still running overlap
                cls.overlapped |= cls.running | {me}
            cls.running.add(me)
        time.sleep(0.2)
        with cls.lock:
            cls.running.discard(me)
        return self.inner.act(observations)

    def close(self):
        pass


def test_per_episode_policies_of_two_workers_are_called_together():
    """The local coordinator waits a moment (``Gather``) for the other worker's reply before it calls per-episode
    instances, so their calls overlap; acting on the first reply alone serialised them (a policy server at 50 ms a
    forward ran 2 workers at half speed: docs/results/benchmarks/speed.md)."""
    from indgen_vla.app.engine.config import EvalConfig, plan_episodes
    from indgen_vla.app.engine.local import LocalOptions, run_local
    from indgen_vla.app.engine.rollout import RunMeta, RunnerConfig
    from scenes.family import get_scene
    from scenes.planning import scene_levels

    task = list(get_scene("pick_place").tasks)[:1]
    c = EvalConfig.from_flat(
        policy="test:feedback", scene="pick_place", axes=("pick_y",), out="-", episodes=2
    )
    jobs = plan_episodes(c, task, {"pick_y": [0]}, {(task[0], "pick_y", 0): 0.0})
    rc = RunnerConfig(levels=scene_levels(get_scene("pick_place"), ["pick_y"]), cameras=(), image_size=(64, 64),
                      max_steps=8, privileged=False)  # fmt: skip
    got = []
    run_local(jobs, rc, _Overlapping, RunMeta("r", "test:feedback", "", "pick_place"), got.append,
              LocalOptions(workers=2, replan_steps=1))  # fmt: skip
    assert len(got) == 2 and all(r.status == "ok" for r in got)
    assert _Overlapping.calls == 2 * 8
    overlapped = len(_Overlapping.overlapped)
    assert overlapped >= 0.75 * _Overlapping.calls, overlapped  # serialised (one call at a time): 0


def test_a_round_waits_half_a_forward_and_per_episode_instances_only_for_slow_ones():
    from indgen_vla.app.engine.batching import Gather

    batched, per_episode = Gather(), Gather(per_episode=True)
    for g in (batched, per_episode):
        assert g.window() == 0.0  # nothing measured yet
        g.observe(0.001)
    assert batched.window() == 0.0005 and per_episode.window() == 0.0  # the oracle: called alone, at once
    for g in (batched, per_episode):
        g.observe(0.051)  # running cost 0.8 * 1 ms + 0.2 * 51 ms = 11 ms
    assert abs(batched.window() - 0.0055) < 1e-9 and abs(per_episode.window() - 0.0055) < 1e-9
    for _ in range(50):
        batched.observe(5.0)
    assert batched.window() == Gather.CAP_S
