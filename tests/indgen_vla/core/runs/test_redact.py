"""A policy spec's secret (``?api_key=``) reaches the server, never the run directory or what evaluate prints."""

from __future__ import annotations

import pytest

from indgen_vla.app.cli import main
from indgen_vla.core.runs.redact import redact, redact_tree
from policy_wrappers.serve import PolicyServer
from policy_wrappers.specs import load_policy, parse_spec

SECRET = "s3cr3t-Key_42"


@pytest.mark.parametrize(
    "text, masked",
    [
        ("openpi:ws://h:8000?api_key=abc", "openpi:ws://h:8000?api_key=***"),
        (
            "openpi:ws://h:8000?replan=5&api_key=a:b&chunk=10",
            "openpi:ws://h:8000?replan=5&api_key=***&chunk=10",
        ),
        ("groot:tcp://h:5555?api_token=t0k", "groot:tcp://h:5555?api_token=***"),
        (
            "indgen evaluate --policy 'openpi:ws://h?api_key=abc' --out r",
            "indgen evaluate --policy 'openpi:ws://h?api_key=***' --out r",
        ),
        ("lerobot:org/api_key=model", "lerobot:org/api_key=model"),  # a path, not an option
        ("standin:random", "standin:random"),
    ],
)
def test_redact_masks_only_secret_options(text, masked):
    assert redact(text) == masked


def test_redact_tree_reaches_every_string():
    tree = {
        "policy": "openpi:ws://h?api_key=x",
        "plan": {"policy": "openpi:ws://h?api_key=x", "n": 3},
        "l": ["?api_token=y"],
    }
    assert redact_tree(tree) == {"policy": "openpi:ws://h?api_key=***", "plan": {"policy": "openpi:ws://h?api_key=***", "n": 3}, "l": ["?api_token=***"]}  # fmt: skip


def test_the_policy_gets_the_key_and_its_name_does_not():
    parsed = parse_spec(f"openpi:ws://gpu:8000?api_key={SECRET}")
    assert parsed.options["api_key"] == SECRET and SECRET not in parsed.spec


def test_evaluate_never_records_the_api_key(tmp_path, capsys):
    server = PolicyServer(load_policy("standin:random"), port=0, api_key=SECRET)
    port = server.start_background()
    out = tmp_path / "run"
    try:
        rc = main(["evaluate", "--scene", "pick_place", "--axis", "pick_y", "--levels", "0", "--workers", "1",
                   "--max-steps", "5", "--episodes", "1", "--out", str(out),
                   "--policy", f"openpi:ws://127.0.0.1:{port}?api_key={SECRET}&render=64&size=64"])  # fmt: skip
        again = main(["evaluate", "--scene", "pick_place", "--axis", "pick_y", "--levels", "0", "--workers", "1",
                      "--max-steps", "5", "--episodes", "1", "--out", str(out),
                      "--policy", f"openpi:ws://127.0.0.1:{port}?api_key={SECRET}&render=64&size=64"])  # fmt: skip
    finally:
        server.stop()
    printed = capsys.readouterr()
    assert rc == 0 and again == 0, printed.err[
        -1500:
    ]  # the key reached the server (else 401), the resume matched
    files = [p for p in out.rglob("*") if p.is_file()]
    assert any(p.name == "episodes.parquet" for p in files) and any(p.name == "manifest.json" for p in files)
    leaked = [str(p.relative_to(out)) for p in files if SECRET.encode() in p.read_bytes()]
    assert not leaked and SECRET not in printed.out + printed.err, leaked
    assert "api_key=***" in (out / "manifest.json").read_text()
