"""``BudgetConfig`` and ``SeriesConfig``: evaluate's protocol plus their own options, their flags made from the fields,
each bad value refused in one line naming the flag."""

import pytest

from indgen_vla.app.config_fields import flat_options, from_flat
from indgen_vla.app.engine.config import EvalConfig
from indgen_vla.app.studies.config import BudgetConfig, SeriesConfig
from indgen_vla.core.errors import ConfigError

PROTOCOL = EvalConfig.from_flat(policy="standin:oracle", scene="pick_place", axes=("pick_y",), out="(budget)")


def test_budget_reads_its_comma_lists_and_defaults_to_the_cores():
    cfg = from_flat(
        BudgetConfig, {"protocol": PROTOCOL, "workers": "8,16", "assume": "0.9,0.5"}, command="budget"
    )
    assert cfg.workers == (8, 16) and cfg.assume == (0.9, 0.5) and cfg.ci == "wilson"
    assert BudgetConfig(protocol=PROTOCOL).workers[0] >= 1
    assert "protocol" in flat_options(BudgetConfig) and flat_options(BudgetConfig)["protocol"].flag is None


@pytest.mark.parametrize(
    ("values", "says"),
    [
        ({"workers": "8,x"}, "--workers takes a comma list, e.g. 8,16; got '8,x'"),
        ({"workers": (0,)}, "--workers must be positive counts"),
        ({"timing": "run", "steps_per_s": 10.0}, "give --timing RUN or --steps-per-s, not both"),
        ({"assume": (0.9,), "pilot": "run"}, "give --assume or --pilot RUN, not both"),
        ({"drop": 1.5}, "--drop must be in (0, 1), got 1.5"),
        ({"ci": "exact"}, "--ci must be one of wilson, clopper-pearson"),
        ({"protocol": "pick_place"}, "budget's protocol must be an EvalConfig"),
    ],
)
def test_budget_refuses_bad_values_in_one_line(values, says):
    with pytest.raises(ConfigError) as e:
        BudgetConfig(**{"protocol": PROTOCOL, **values})
    assert says in str(e.value) and "\n" not in str(e.value)


def test_series_config_checks_its_options():
    cfg = SeriesConfig(protocol=PROTOCOL, roots="ckpt", out="s")
    assert cfg.roots == ("ckpt",) and (cfg.poll, cfg.idle_stop, cfg.follow) == (60.0, 3600.0, False)
    with pytest.raises(ConfigError, match="--poll must be > 0 and --idle-stop >= 0 seconds"):
        SeriesConfig(protocol=PROTOCOL, roots=("ckpt",), out="s", poll=0)
    with pytest.raises(ConfigError, match="series needs a ROOT"):
        SeriesConfig(protocol=PROTOCOL, roots=(), out="s")
