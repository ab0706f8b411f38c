"""The Ray backend on a real multi-node Ray cluster on one machine (``ray.cluster_utils.Cluster``: a head and worker
nodes, each its own raylet; a fake GPU where a test needs one), joined through ``RAY_ADDRESS`` as a user joins theirs.
Nodes leave and join mid-run, actors are SIGKILLed, the driver is SIGKILLed and resumed: every planned episode ends
up recorded exactly once, with the outcome its seed gives it wherever it ran."""

from __future__ import annotations

import json
import os
import signal
import threading
import time
from collections.abc import Callable
from pathlib import Path

import pandas as pd
import pytest

from indgen_vla.app.engine.config import EvalConfig
from scenes.family import get_scene
from tests.fixtures.kill import episodes_on_disk, kill_midway, processes
from tests.fixtures.resolved import evaluate

ray = pytest.importorskip("ray")
pytestmark = [pytest.mark.filterwarnings("ignore"), pytest.mark.timeout(900)]

FAST_DEATH = {
    "health_check_period_ms": 500,
    "health_check_failure_threshold": 3,
    "health_check_timeout_ms": 500,
}
ROW = ["task", "axis", "level", "episode", "seed", "success", "steps", "status", "failure"]


@pytest.fixture(scope="module")
def cluster():
    """Head (1 CPU) and two worker nodes of 2 CPUs: the issue's 5 logical CPUs, where one policy actor per node
    left no room for two of --workers 4 simulators and the run hung."""
    from ray.cluster_utils import Cluster

    c = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False,
                                                      "_system_config": FAST_DEATH})  # fmt: skip
    for _ in range(2):
        c.add_node(num_cpus=2)
    c.wait_for_nodes()
    yield c
    c.shutdown()


@pytest.fixture
def joined(cluster, monkeypatch):
    """``RAY_ADDRESS`` names the cluster, as the docs tell a user to set it; the run joins and leaves it."""
    monkeypatch.setenv("RAY_ADDRESS", cluster.address)
    yield cluster
    if ray.is_initialized():
        ray.shutdown()


def config(out: Path, **kw) -> EvalConfig:
    base = dict(policy="standin:oracle", scene="pick_place", axes=("pick_y",), levels="0:1", episodes=4,
                max_steps=10, workers=4, backend="ray", out=str(out), server_patience=120.0)  # fmt: skip
    return EvalConfig.from_flat(**{**base, **kw})


def rows(out: Path) -> pd.DataFrame:
    return pd.read_parquet(out / "episodes.parquet")


def ray_entry(out: Path) -> dict:
    return json.loads((out / "manifest.json").read_text())["ray"]


def when(ready: Callable[[], bool], then: Callable[[], None], timeout_s: float = 600) -> threading.Thread:
    """Run ``then`` in a thread as soon as ``ready()`` (e.g. some episodes on disk)."""

    def wait() -> None:
        deadline = time.monotonic() + timeout_s
        while not ready() and time.monotonic() < deadline:
            time.sleep(0.2)
        then()

    t = threading.Thread(target=wait, daemon=True)
    t.start()
    return t


def actor_pids(name: str) -> list[int]:
    """PIDs of this test's Ray actors of class ``name`` (Ray titles them ``ray::NAME``, ``ray::NAME.method`` while a
    method runs; ``name`` may name the method too):
    descendants of this process, so another session's Ray on the machine is never touched."""
    parent = {}
    for pid, _, _, _ in processes():
        try:
            stat = Path(f"/proc/{pid}/stat").read_text()
            parent[pid] = int(stat[stat.rfind(")") + 2 :].split()[1])
        except (OSError, ValueError, IndexError):
            continue

    def ours(pid: int) -> bool:
        while pid > 1:
            pid = parent.get(pid, 1)
            if pid == os.getpid():
                return True
        return False

    def named(cmd: str) -> bool:
        title = cmd.split(" ")[0]
        return title == f"ray::{name}" or title.startswith(f"ray::{name}.")

    return [pid for pid, state, _, cmd in processes() if named(cmd) and state != "Z" and ours(pid)]


def check_once(out: Path, planned: int) -> pd.DataFrame:
    """Every planned episode recorded exactly once, each ok, each video its row names present."""
    df = rows(out)
    assert len(df) == planned and not df.duplicated(["task", "axis", "level", "episode"]).any()
    assert (df["status"] == "ok").all(), df[df["status"] != "ok"]["error"].tolist()
    for video in df["video"]:
        assert not video or (out / video).is_file(), video
    return df


@pytest.mark.slow  # ~50 s: a node added, then SIGKILLed mid-run; make test-cluster runs it
def test_a_node_removed_mid_run_loses_no_episode_and_videos_reach_the_run_directory(joined, tmp_path):
    """The issue's 5-CPU cluster with --workers 4 runs (3 simulators fit; one line says so) instead of hanging; a
    worker node SIGKILLed after the first episodes takes its simulator and policy actor with it: the episodes they
    held run again elsewhere, and each video travels back with its record (nodes share no directory here)."""
    node = joined.add_node(num_cpus=2)  # the one that leaves: the fixture's nodes stay for the other tests
    joined.wait_for_nodes()
    out = tmp_path / "run"
    killer = when(lambda: episodes_on_disk(out) >= 2, lambda: joined.remove_node(node, allow_graceful=False))
    evaluate(config(out, episodes=4, video=True, video_per_level=1), quiet=True)
    killer.join(10)
    df = check_once(out, 8)
    entry = ray_entry(out)
    assert entry["files"] == "shipped" and df["video"].str.len().gt(0).sum() == 2  # one per level
    assert entry["faults"]["nodes_lost"] == 1
    assert len(entry["episodes_per_node"]) >= 2 and sum(entry["episodes_per_node"].values()) == 8  # spread


@pytest.mark.slow  # ~70 s with the cluster's start: the default suite's budget; 'make test-cluster' runs this file
def test_driver_sigkilled_then_the_same_command_resumes_to_the_uninterrupted_runs_episodes(cluster, tmp_path):
    """``indgen evaluate --backend ray`` with ``RAY_ADDRESS`` set (the documented path, which died in ``ray.init``
    before the first episode), SIGKILLed mid-run and run again: the episodes equal those of one uninterrupted
    run (the local backend's: seeds belong to episodes, not to where they ran)."""
    argv = ["evaluate", "--policy", "standin:oracle", "--scene", "pick_place", "--axis", "pick_y", "--levels", "0:1",
            "--episodes", "4", "--max-steps", "10", "--workers", "3", "--backend", "ray"]  # fmt: skip
    out = tmp_path / "ray"
    env = {"RAY_ADDRESS": cluster.address}
    with pytest.MonkeyPatch.context() as mp:
        for k, v in env.items():
            mp.setenv(k, v)
        got = kill_midway(argv, out, total=8, timeout_s=600)
        assert 1 <= got < 8
        from indgen_vla.app.cli import main

        assert main([*argv, "--out", str(out)]) == 0
    if ray.is_initialized():
        ray.shutdown()
    ref = tmp_path / "local"
    evaluate(config(ref, backend="local", workers=1), quiet=True)
    mine, theirs = rows(out)[ROW], rows(ref)[ROW]
    assert sorted(map(tuple, mine.itertuples(index=False))) == sorted(
        map(tuple, theirs.itertuples(index=False))
    )


def gated_oracle(gate: str):
    """The oracle, except that ``act`` waits until the file ``gate`` exists: the run's episodes hold still until the
    test opens it. Defined in a function so Ray ships the class by value (no test module import in the actors)."""
    from scenes.tabletop.oracle import OraclePolicy

    class Gated(OraclePolicy):
        def act(self, observations):
            deadline = time.monotonic() + 600
            while not os.path.exists(gate) and time.monotonic() < deadline:
                time.sleep(0.05)
            return super().act(observations)

    return Gated


@pytest.mark.slow
def test_a_node_added_mid_run_gets_simulators_and_work(joined, tmp_path):
    """--workers 5 on a cluster that holds 3 simulators: a node that joins mid-run gets a policy actor and a
    simulator, which is handed an episode while the first three are still busy (the policy holds every episode
    until then, so the check does not race the queue), and the run finishes with every episode once."""
    from indgen_vla.app.engine.config import plan_episodes
    from indgen_vla.app.engine.ray_backend import run_ray
    from indgen_vla.app.engine.rollout import RunMeta, RunnerConfig
    from scenes.planning import scene_levels

    gate, added = tmp_path / "go", []
    cfg = config(tmp_path / "unused", episodes=6, workers=5)
    jobs = plan_episodes(cfg, ["milk"], {"pick_y": [0, 1]}, {("milk", "pick_y", k): 0.03 * k for k in (0, 1)})
    rc = RunnerConfig(levels=scene_levels(get_scene("pick_place"), ["pick_y"]), cameras=(), image_size=(64, 64),
                      max_steps=10, privileged=True)  # fmt: skip

    got, stats, failed = [], {}, []

    def run() -> None:
        try:
            run_ray(jobs, rc, cfg, RunMeta("r", "standin:oracle", "", "pick_place"), got.append, 5,
                    make_policy=gated_oracle(str(gate)), stats=stats)  # fmt: skip
        except BaseException as e:  # noqa: BLE001 - failed below
            failed.append(e)

    def until(ready: Callable[[], bool]) -> None:
        deadline = time.monotonic() + 600
        while not ready() and time.monotonic() < deadline:
            time.sleep(0.2)

    runner = threading.Thread(
        target=run, daemon=True
    )  # the run in a thread: a node is added from the main one
    runner.start()
    try:
        until(lambda: len(actor_pids("_SimActor.run")) >= 3 or not runner.is_alive())
        added.append(joined.add_node(num_cpus=2))
        until(lambda: len(actor_pids("_SimActor.run")) >= 4 or not runner.is_alive())
        gate.touch()  # the fourth simulator, on the new node, holds an episode: let them all go
        runner.join(600)
        assert not failed and not runner.is_alive(), failed
        assert sorted(r.key for r in got) == sorted(j.key for j in jobs) and all(
            r.status == "ok" for r in got
        )
        assert stats["faults"]["nodes_joined"] == 1 and stats["faults"]["simulator_actors_started"] == 4
        assert len(stats["episodes_per_node"]) == 4  # the new node's simulator ran episodes too
    finally:
        gate.touch()
        runner.join(60)
        for node in added:
            joined.remove_node(node)


@pytest.mark.slow
def test_killed_simulator_and_policy_actors_are_replaced_and_no_episode_is_lost(joined, tmp_path):
    """SIGKILL a simulator actor (a segfault, an OOM kill) and then a policy actor: the simulator's episode goes
    back in the queue and a replacement starts; the policy actor's simulators reconnect to its replacement."""
    out = tmp_path / "run"
    done = []

    def kill(name: str) -> None:
        pids = actor_pids(name)
        if pids:
            os.kill(pids[0], signal.SIGKILL)
            done.append(name)

    killer = when(lambda: episodes_on_disk(out) >= 1, lambda: kill("_SimActor"))
    killer2 = when(lambda: episodes_on_disk(out) >= 4, lambda: kill("_PolicyActor"))
    evaluate(config(out, episodes=6, max_steps=20), quiet=True)
    killer.join(10)
    killer2.join(10)
    check_once(out, 12)
    faults = ray_entry(out)["faults"]
    assert done == ["_SimActor", "_PolicyActor"]
    assert faults["simulator_actors_lost"] >= 1 and faults["policy_actors_lost"] >= 1
    assert faults["simulator_actors_started"] >= 4 and faults["policy_actors_started"] >= 3


@pytest.mark.slow
def test_an_openpi_server_that_stops_and_restarts_pauses_the_ray_run_and_loses_nothing(joined, tmp_path):
    """As locally (test_faults.test_server_restart_mid_run_loses_nothing): `indgen serve` stopped after the first
    episode and back 2 s later; the simulator actors wait (run_episode's backoff) and rerun from the seed."""
    from policy_wrappers.serve import PolicyServer
    from policy_wrappers.specs import load_policy
    from tests.indgen_vla.app.engine.test_faults import soak

    port = soak.free_port()
    server = [PolicyServer(load_policy("standin:random"), port=port)]
    server[0].start_background()

    def bounce() -> None:
        server[0].stop()
        time.sleep(2.0)
        server[0] = PolicyServer(load_policy("standin:random"), port=port)
        server[0].start_background()

    out = tmp_path / "run"
    bouncer = when(lambda: episodes_on_disk(out) >= 1, bounce)
    try:
        spec = f"openpi:ws://127.0.0.1:{port}?render=64&size=64&timeout=5"
        evaluate(config(out, policy=spec, levels="0", episodes=4, workers=2), quiet=True)
    finally:
        bouncer.join(10)
        server[0].stop()
    check_once(out, 4)


@pytest.mark.slow  # 5 blocker actors start first (90 s under load 20)
def test_a_cluster_whose_cpus_are_all_taken_stops_in_one_line_after_the_patience(joined, tmp_path, capsys):
    """Another job holds every CPU of a shared cluster: the run's actors wait for room, and with no episode running
    for --server-patience seconds it stops with one line and exit 4 (before, it waited forever)."""
    from indgen_vla.app.cli import main

    ray.init(address=joined.address, log_to_driver=False)
    blocker = ray.remote(num_cpus=1)(type("Blocker", (), {"ping": lambda self: 1}))
    holders = [blocker.remote() for _ in range(5)]
    ray.get([h.ping.remote() for h in holders])
    try:
        argv = ["evaluate", "--policy", "standin:oracle", "--scene", "pick_place", "--axis", "pick_y", "--levels",
                "0", "--episodes", "2", "--max-steps", "10", "--workers", "2", "--backend", "ray",
                "--server-patience", "3", "--out", str(tmp_path / "run")]  # fmt: skip
        assert main(argv) == 4
        last = capsys.readouterr().err.strip().splitlines()[-1]
        assert last.startswith("error: no episode could run on the Ray cluster for 3 s (--server-patience)")
        assert last.endswith("finished episodes are saved, re-run the same command to resume")
    finally:
        for h in holders:
            ray.kill(h)


@pytest.mark.slow
@pytest.mark.timeout(3600)
def test_forty_oracle_episodes_on_three_nodes_one_removed_halfway(joined, tmp_path):
    """The issue's done-when check: 40 oracle episodes, a video each, on the 3-node cluster; one worker node is
    SIGKILLed once 20 are on disk. 40 ok rows, none twice, every video in the run directory. Last in the file: it
    takes a node of the module's cluster away (and puts one back)."""
    out = tmp_path / "run"
    victim = [n for n in joined.list_all_nodes() if not n.head][0]
    killer = when(
        lambda: episodes_on_disk(out) >= 20, lambda: joined.remove_node(victim, allow_graceful=False)
    )
    try:
        evaluate(config(out, episodes=20, max_steps=25, video=True, video_per_level=20), quiet=True)
        killer.join(60)
        df = check_once(out, 40)
        assert (df["video"].str.len() > 0).all() and len(list((out / "videos").glob("*.mp4"))) == 40
        assert ray_entry(out)["faults"]["nodes_lost"] == 1
    finally:
        joined.add_node(num_cpus=2)


@pytest.mark.slow  # ~15 s: its own two-node cluster; test_engine_ray's sim_options test keeps the options' content
def test_a_node_whose_environment_names_another_split_builds_the_drivers(tmp_path, monkeypatch):
    """A worker node started with INDGEN_ROBOCASA_SPLIT=target runs a simulator actor that sees the driver's 'all'."""
    from ray.cluster_utils import Cluster

    from indgen_vla.app.engine.ray_backend import sim_options
    from scenes.planning import scene_levels

    monkeypatch.setenv("INDGEN_ROBOCASA_SPLIT", "target")  # the environment the node's raylet starts with
    c = Cluster(initialize_head=True, head_node_args={"num_cpus": 0, "include_dashboard": False})
    c.add_node(num_cpus=1)
    c.wait_for_nodes()
    try:
        monkeypatch.setenv("INDGEN_ROBOCASA_SPLIT", "all")  # the driver's choice
        ray.init(address=c.address, log_to_driver=False)

        class Probe:
            def split(self) -> tuple[str, str]:
                return os.environ.get("INDGEN_ROBOCASA_SPLIT", ""), ray.get_runtime_context().get_node_id()

        plain = ray.remote(num_cpus=1)(Probe).remote()
        assert ray.get(plain.split.remote())[0] == "target"  # the node's own value, what an actor read before
        ray.kill(plain)
        carried = ray.remote(num_cpus=1, **sim_options(scene_levels(get_scene("robocasa"), ["base_y"])))(
            Probe
        ).remote()
        assert ray.get(carried.split.remote())[0] == "all"
    finally:
        ray.shutdown()
        c.shutdown()
