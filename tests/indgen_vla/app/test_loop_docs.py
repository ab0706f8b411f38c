"""docs/loop.md's recipes run as written: the training-loop evaluation inside a real (tiny) LeRobot training loop, and
the GitHub Actions workflow's indgen commands parse with today's flags."""

import re
from pathlib import Path

import pytest
import yaml

from indgen_vla.app.cli import build_parser
from indgen_vla.core.runs.records import RunDir
from tests.docs.fences import code_blocks

pytestmark = pytest.mark.filterwarnings("ignore")
ROOT = Path(__file__).resolve().parents[3]
DOC = (ROOT / "docs" / "loop.md").read_text()


def blocks(lang: str) -> list[str]:
    return code_blocks(DOC, lang)


@pytest.mark.slow  # 67 s of training and evaluating; the policy-object path itself is test_engine_objects'
def test_the_training_loop_recipe_runs_between_optimizer_steps(tmp_path):
    pytest.importorskip("lerobot")
    import torch

    from policy_wrappers.lerobot_import import one_package_scan, policy_package

    with one_package_scan():
        policy_package("act")
        from lerobot.configs.policies import PreTrainedConfig
        from lerobot.policies.factory import get_policy_class, make_pre_post_processors
    path = str(ROOT / "checkpoints" / "act_pick_place_human")
    config = PreTrainedConfig.from_pretrained(path)
    policy = get_policy_class(config.type).from_pretrained(path, config=config)
    preprocessor, postprocessor = make_pre_post_processors(config, pretrained_path=path)
    (recipe,) = [b for b in blocks("python") if b.startswith("# indgen-recipe")]
    ns: dict = {}
    exec(compile(recipe, "docs/loop.md", "exec"), ns)
    policy.train()
    opt = torch.optim.Adam(policy.parameters(), lr=1e-4)
    gen = torch.Generator().manual_seed(0)
    chunk = policy.config.chunk_size
    runs, losses = [], []
    for step in range(1, 4):  # a training loop: a batch through the preprocessor, a loss, an update
        batch = {"observation.state": torch.randn(4, 8, generator=gen), "action": torch.randn(4, chunk, 7, generator=gen),
                 "action_is_pad": torch.zeros(4, chunk, dtype=torch.bool)}  # fmt: skip
        loss, _ = policy.forward(preprocessor(batch))
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(float(loss))
        if step % 2 == 0:  # the docs' `if step % N == 0`
            runs.append(ns["indgen_eval"](policy, preprocessor, postprocessor, step, tmp_path / "train",
                                          levels="0", episodes=1, max_steps=10))  # fmt: skip
            assert policy.training  # handed back in train mode: the next update trains
    assert len(losses) == 3 and all(map(lambda x: x == x, losses))
    (run,) = runs
    assert run == tmp_path / "train" / "indgen" / "step_000000002"
    r = RunDir.open(run)
    assert r.manifest["policy"] == "object:ACTPolicy@step2" and len(r.episodes()) == 1


def test_the_workflow_runs_valid_indgen_commands():
    (workflow,) = [b for b in blocks("yaml") if "indgen gate" in b]
    steps = yaml.safe_load(workflow)["jobs"]["gate"]["steps"]
    commands = [line.strip() for s in steps for line in s.get("run", "").splitlines() if "indgen " in line]
    commands = [re.split(r" > | \|\| ", c)[0] for c in commands if c.startswith("indgen ")]
    assert {c.split()[1] for c in commands} == {"evaluate", "gate"}
    parser = build_parser()
    for c in commands:
        args = parser.parse_args(c.split()[1:])
        assert args.command in ("evaluate", "gate")


def test_the_workflow_fails_on_an_undecided_gate_and_runs_the_planned_episodes():
    """The gate step's last command is the gate itself (its exit code, 5 included, is the step's), and the smoke runs
    the episodes ``gate --plan`` gives for the rates the text names (95 %, 90 %, 90 %, margin 0.1)."""
    from indgen_vla.core.comparison.gate_plan import plan_episodes

    (workflow,) = [b for b in blocks("yaml") if "indgen gate" in b]
    steps = yaml.safe_load(workflow)["jobs"]["gate"]["steps"]
    gate_step = next(s["run"] for s in steps if "indgen gate" in s.get("run", ""))
    last = gate_step.strip().splitlines()[-1].strip()
    assert (
        last.startswith("indgen gate ") and "||" not in last and ";" not in last and "exit" not in gate_step
    )
    episodes = int(re.search(r"--episodes (\d+)", workflow).group(1))
    assert episodes == plan_episodes([0.95, 0.9, 0.9], 0.1)["episodes"]
    assert f"says **{episodes} episodes a level**" in DOC
