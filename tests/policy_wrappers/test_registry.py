"""Spec parsing, the family/stand-in registries and ``indgen policies``."""

from __future__ import annotations

import json
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

import indgen_vla.app.engine  # noqa: F401  (the application registers standin:oracle)
from indgen_vla.core.errors import ConfigError, PolicyError, UnknownNameError
from indgen_vla.core.protocol.interface import Policy, validate_chunk
from policy_wrappers.specs import load_policy, parse_spec


def test_parse_spec_splits_family_target_options():
    p = parse_spec("openpi:ws://gpu:8000?replan=4&api_key=a:b")
    assert (p.family, p.target, p.options) == ("openpi", "ws://gpu:8000", {"replan": "4", "api_key": "a:b"})
    assert parse_spec("lerobot:lerobot/smolvla_libero").target == "lerobot/smolvla_libero"


@pytest.mark.parametrize(
    "spec, fragment",
    [
        ("lerobot:", "nothing after 'lerobot:'"),
        ("openpy:ws://x:1", "did you mean 'openpi'"),
        ("oracle", "did you mean 'standin:oracle'"),
        ("", "empty policy spec"),
        ("openpi:http://127.0.0.1:8000", "takes ws:// or wss://"),
        ("openpi:127.0.0.1:8000", "takes ws://"),
        ("groot:ws://h:5555", "takes tcp://"),
        ("openvla-oft:ftp://h:1", "takes http:// or https://"),
        ("openpi:ws://h:notaport", "bad port"),
        ("openpi:ws://h:8000/x", "unexpected path"),
        ("standin:oracel", "did you mean 'oracle'"),
        ("act:checkpoints/act_pick_place_human", "with lerobot:checkpoints/act_pick_place_human"),
        ("pi05:", "with lerobot:HUB_ID_OR_DIR"),
        ("standin:noop?chunck=3", "did you mean 'chunk'"),
        ("standin:random?chunk=x", "must be an integer"),
        ("openvla-oft:http://h:1?variant=oftt", "did you mean 'oft'"),
    ],
)
def test_bad_specs_fail_with_one_clear_line(spec, fragment):
    with pytest.raises(ConfigError) as err:
        load_policy(spec)
    msg = str(err.value)
    assert fragment in msg and "\n" not in msg


def test_unknown_family_lists_choices():
    with pytest.raises(UnknownNameError) as err:
        parse_spec("gr00t:tcp://h:1")
    assert "groot" in str(err.value) and "lerobot" in str(err.value)


def test_noop_and_random_are_policies():
    for spec in ("standin:noop", "standin:random", "standin:random?chunk=4&scale=0.1"):
        policy = load_policy(spec)
        assert isinstance(policy, Policy)
        assert policy.spec.family == "standin" and policy.spec.name == spec and policy.spec.cameras == ()


def test_scene_reaches_only_loaders_that_take_it():
    """The engine passes the scene; families without scene-dependent defaults never see it (nor as an option)."""
    policy = load_policy("standin:noop", scene="libero_object")
    assert policy.spec.family == "standin"
    with pytest.raises(UnknownNameError, match="scene"):
        load_policy("standin:noop?scene=libero_object")  # as a spec option it is still a typo


def test_oracle_is_lazy(monkeypatch):
    try:
        import scenes.oracles  # noqa: F401
    except ModuleNotFoundError:
        with pytest.raises(PolicyError, match="not installed yet"):
            load_policy("standin:oracle")
    else:
        assert load_policy("standin:oracle").spec.privileged


def test_policies_main_json(capsys):
    from indgen_vla.app.cli.catalog import main

    assert main(SimpleNamespace(command="policies", json=True)) == 0
    data = json.loads(capsys.readouterr().out)
    families = {"lerobot", "openpi", "openvla-oft", "groot", "univla", "rynnvla", "standin"}
    assert {f["name"] for f in data["families"]} == families
    assert {"standin:oracle", "standin:random", "standin:noop"} <= {s["name"] for s in data["standins"]}
    assert main(SimpleNamespace(command="policies", json=False)) == 0
    assert "openpi:" in capsys.readouterr().out


def test_import_is_light():
    code = (
        "import sys, policy_wrappers, policy_wrappers.specs; "
        "bad = [m for m in ('torch', 'lerobot', 'transformers', 'zmq', 'websockets') if m in sys.modules]; "
        "print(bad); sys.exit(1 if bad else 0)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr


def test_validate_chunk_names_the_policy():
    with pytest.raises(PolicyError, match="standin:x"):
        validate_chunk(np.full((1, 2, 7), np.nan), 1, "standin:x")
