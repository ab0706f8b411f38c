"""``evaluate --adaptive kstar`` end to end on LIBERO-Object (miniature assets): decisions, failure labels."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

pytest.importorskip("libero")

from indgen_vla.app.engine.config import EvalConfig  # noqa: E402
from indgen_vla.core.stats.sprt import SequentialRule  # noqa: E402
from tests.fixtures.resolved import evaluate  # noqa: E402

pytestmark = pytest.mark.filterwarnings("ignore")


@pytest.mark.slow  # ~20 s idle: a LIBERO reset rebuilds the MJCF each episode
def test_adaptive_kstar_on_libero_object(mini, tmp_path):
    need = SequentialRule(max_episodes=30).decide([False] * 30).episodes  # a never-succeeding policy
    cfg = EvalConfig.from_flat(policy="standin:noop", scene="libero_object", axes=("pick_y",), levels="-1:1", episodes=30,
                     workers=1, max_steps=2, adaptive="kstar", out=str(tmp_path / "run"))  # fmt: skip
    run = Path(evaluate(cfg, quiet=True))
    eps = pd.read_parquet(run / "episodes.parquet")
    # level 0 is decided broken after `need` failures, which settles k* on both sides: nothing else runs
    assert set(eps["level"]) == {0} and len(eps) == need and not eps["success"].any()
    assert set(eps["failure"]) == {"no_contact"}  # the gripper never moved: the simulator says so
    axis = json.loads((run / "summary.json").read_text())["axes"]["pick_y"]
    lv = {r["level"]: r for r in axis["levels"]}
    assert lv[0]["decision"] == "broken" and lv[0]["sequential"]["episodes_used"] == need
    assert lv[1]["n"] == lv[-1]["n"] == 0 and axis["break_level"]["pos"] == 0
