"""Where the Ray backend puts its actors, decided from the nodes alone (no Ray here): a run fits itself to the cluster
or says in one line what it lacks, never waits for an actor that cannot be placed; and the helpers that bring
episode files home."""

from __future__ import annotations

import pytest

from indgen_vla.app.engine.config import EvalConfig
from indgen_vla.app.engine.ray_cluster import Need, Node, capacity, first_fit, local_cpus, place
from indgen_vla.app.engine.ray_files import FileRoute, Scratch, deliver, not_shared, route, sees, write_probe
from indgen_vla.app.engine.scheduler import JobQueue
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.plan import EpisodeJob

CPU = Need(cpus_per_sim=1.0, cpus_per_policy=1.0)
GPU = Need(cpus_per_sim=1.0, cpus_per_policy=1.0, gpus_per_policy=1.0)


def nodes(*spec: tuple[float, float]) -> list[Node]:
    return [Node(f"n{i}", cpus, gpus) for i, (cpus, gpus) in enumerate(spec)]


def test_the_issue_cluster_fits_three_simulators_and_says_it_lacks_one_cpu():
    """5 logical CPUs (1 + 2 + 2) and --workers 4: before, one policy actor per node took 3 CPUs and two
    simulators waited forever for room. Now the run places what fits and says what is missing in one line."""
    plan, note = first_fit(nodes((1, 0), (2, 0), (2, 0)), CPU, workers=4, jobs=40)
    assert sorted(plan.policies) == ["n1", "n2"]  # the 1-CPU node would have no CPU left for a simulator
    assert sorted(plan.sims) == ["n0", "n1", "n2"]  # spread: one per node
    assert note.startswith("the Ray cluster holds 3 of the 4 simulator actors asked for (--workers)")
    assert "it lacks 1 CPU;" in note and "5 CPUs" in note and "\n" not in note
    assert capacity(nodes((1, 0), (2, 0), (2, 0)), CPU) == 3


def test_a_cluster_too_small_for_any_simulator_is_refused_in_one_line():
    with pytest.raises(
        ConfigError, match=r"no room for a simulator actor beside its policy actor \(1 live node"
    ):
        first_fit(nodes((1, 0)), CPU, workers=2, jobs=10)
    with pytest.raises(ConfigError, match="no room for a policy actor"):
        first_fit(nodes((0.5, 0)), Need(0.5, 1.0), workers=2, jobs=10)
    with pytest.raises(ConfigError, match="--device cuda but the Ray cluster has 0 GPUs"):
        first_fit(nodes((8, 0)), GPU, workers=2, jobs=10)
    # a policy actor that reserves no CPU (clients of a policy server) leaves the one CPU to a simulator
    plan, note = first_fit(nodes((1, 0)), Need(1.0, 0.0), workers=1, jobs=10)
    assert plan.policies == ("n0",) and plan.sims == ("n0",) and note == ""


def test_policy_actors_follow_the_gpus_and_come_before_simulators():
    plan = place(nodes((4, 2), (4, 0)), {}, 6, GPU)
    assert plan.policies == ("n0", "n0")  # one per GPU, each with its CPU reserved first
    assert sorted(plan.sims) == ["n0", "n0", "n1", "n1", "n1", "n1"]
    # a GPU node joins mid-run: its GPU gets a policy actor even when no simulator is wanted
    held = {"n0": (2, 2), "n1": (4, 0)}
    assert place(nodes((4, 2), (4, 0), (2, 1)), held, 0, GPU).policies == ("n2",)
    # never more policy actors than simulators
    assert place(nodes((8, 4)), {}, 1, GPU).policies == ("n0",)


def test_a_node_that_lost_its_policy_actor_gets_one_and_a_joining_node_gets_actors():
    held = {"n0": (1, 0), "n1": (1, 1)}  # n0's policy actor died, its simulator runs on
    assert place(nodes((2, 0), (2, 0)), held, 0, CPU).policies == ("n0",)
    joined = place(nodes((2, 0), (2, 0), (3, 0)), {"n0": (1, 1), "n1": (1, 1)}, 4, CPU)
    assert joined.policies == ("n2",) and joined.sims == ("n2", "n2")  # what fits of the 4 wanted


def test_need_and_knob_checks():
    with pytest.raises(ConfigError):
        Need(0, 1)
    assert local_cpus(4, CPU) == 5 and local_cpus(3, Need(0.5, 0.0)) == 2
    from indgen_vla.app.engine.ray_backend import ray_knobs

    assert ray_knobs({"INDGEN_RAY_CPUS_PER_POLICY": "0"})["INDGEN_RAY_CPUS_PER_POLICY"] == 0
    with pytest.raises(ConfigError, match="INDGEN_RAY_CPUS_PER_POLICY='-1'.*>= 0"):
        ray_knobs({"INDGEN_RAY_CPUS_PER_POLICY": "-1"})


def test_workers_auto_is_for_the_ray_backend_only():
    base = dict(policy="standin:oracle", scene="pick_place", axes=("pick_y",), out="x")
    assert EvalConfig.from_flat(**base, workers="auto", backend="ray").run.workers == "auto"
    with pytest.raises(
        ConfigError, match="--workers auto follows a Ray cluster's CPUs: use it with --backend ray"
    ):
        EvalConfig.from_flat(**base, workers="auto")
    with pytest.raises(ConfigError, match="--workers must be a number >= 1 or auto"):
        EvalConfig.from_flat(**base, workers=0)
    from indgen_vla.app.cli import build_parser

    args = build_parser().parse_args(["evaluate", "--workers", "auto"])
    assert args.workers == "auto" and build_parser().parse_args(["evaluate", "--workers", "3"]).workers == 3


def test_a_queue_takes_back_the_episode_of_a_slot_that_died():
    jobs = [EpisodeJob("t", "a", 0, i, seed=i, param=0.0) for i in range(3)]
    q = JobQueue(jobs)
    first = q.take(7)
    q.put_back(7, first)  # slot 7's actor died with episode 0
    assert q.take(8) == first  # the next slot runs it first, from the same job (same seed)
    assert [q.take(8).episode, q.take(8).episode, q.take(8)] == [1, 2, None]


def test_episode_files_travel_home_and_a_shared_route_is_checked(tmp_path):
    scratch = Scratch()
    try:
        videos = scratch.video_dir(str(tmp_path / "run" / "videos"))
        assert videos.startswith(str(scratch.root)) and videos.endswith("videos")
        (scratch.root / "videos").mkdir()
        (scratch.root / "videos" / "a_ep0_fail.mp4").write_bytes(b"mp4")
        (scratch.root / "videos" / ".a_ep1.partial.mp4").write_bytes(b"half")
        files = scratch.collect()
        assert files == {"videos/a_ep0_fail.mp4": b"mp4"} and not any(scratch.root.iterdir())
    finally:
        scratch.close()
    deliver(str(tmp_path / "run"), files)
    assert (tmp_path / "run" / "videos" / "a_ep0_fail.mp4").read_bytes() == b"mp4"
    with pytest.raises(ConfigError, match="outside the run directory"):
        deliver(str(tmp_path / "run"), {"../escape.mp4": b""})

    assert route(tmp_path / "run", {}).manifest() == {"files": "shipped"}
    shared = route(tmp_path / "run", {"INDGEN_RAY_SHARED_OUT": "1"})
    assert shared.manifest() == {"files": "shared", "shared_path": str((tmp_path / "run").resolve())}
    with pytest.raises(ConfigError, match="INDGEN_RAY_SHARED_OUT='yes'"):
        route(tmp_path, {"INDGEN_RAY_SHARED_OUT": "yes"})
    with pytest.raises(ConfigError, match="absolute"):
        FileRoute("relative/run")
    token = write_probe(shared.run_dir)
    assert (
        sees(shared.run_dir, token) and not sees(shared.run_dir, "other") and not sees(str(tmp_path), token)
    )
    line = str(not_shared(shared.run_dir, "10.0.0.7 (abcd1234)"))
    assert (
        line.startswith("INDGEN_RAY_SHARED_OUT=1 but node 10.0.0.7 (abcd1234) does not see")
        and "\n" not in line
    )


@pytest.mark.timeout(30)
@pytest.mark.parametrize("form", ["127.0.0.1:{port}", "ray://127.0.0.1:{port}", "nohost.invalid:{port}"])
def test_a_ray_address_where_no_cluster_answers_is_one_line_in_seconds(monkeypatch, form):
    """RAY_ADDRESS naming a port where nothing listens (a typo, a head that died): ray.init retried it for more than
    8 minutes with Ray 2.60, the docs promise one error line; it is refused before ray.init is called."""
    import socket

    from indgen_vla.app.engine.ray_cluster import join, unanswered

    with socket.socket() as s:  # a port that was free a moment ago
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    address = form.format(port=port)
    monkeypatch.setenv("RAY_ADDRESS", address)
    with pytest.raises(
        ConfigError, match=rf"^RAY_ADDRESS={address}: no Ray cluster answers there \(cannot connect"
    ):
        join(1)
    with socket.socket() as s:  # something that answers is left to ray.init; other forms are Ray's to check
        s.bind(("127.0.0.1", 0))
        s.listen()
        assert unanswered(f"127.0.0.1:{s.getsockname()[1]}") == ""
    assert unanswered("auto") == unanswered("http://127.0.0.1:8265") == ""


def test_a_dashboard_ray_address_names_the_gcs_address_to_use_instead(monkeypatch):
    """RAY_ADDRESS=http://HEAD:8265 (the job API's address, which 'ray job submit' takes): Ray's first line ended in
    'To fix this, either:' with the fix on lines the error dropped; the line now says which address to give."""
    from indgen_vla.app.engine.ray_cluster import join

    monkeypatch.setenv("RAY_ADDRESS", "http://127.0.0.1:8265")
    with pytest.raises(
        ConfigError, match=r"dashboard's \(job API\) address.*the head's GCS address HOST:PORT"
    ):
        join(1)
