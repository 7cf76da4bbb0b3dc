"""The sweep spec (scenarios/sweep.py): key paths, grid and random expansion, and every way a spec or
one of its variants can be wrong, each named before anything runs."""

from __future__ import annotations

import statistics
from pathlib import Path

import pytest

from rig.run_cmd import LIBRARY
from rig.scenarios.sweep import SweepError, load_sweep, parse_key, set_key
from tests.sweep import SHOW


def spec(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "spec.toml"
    p.write_text(text)
    return p




def test_key_paths_and_setting_them() -> None:
    assert parse_key("faults[0].start") == ["faults", 0, "start"]
    assert parse_key("environment.wind[2]") == ["environment", "wind", 2]
    data: dict = {"faults": [{"start": 1.0}], "environment": {"wind": [1.0, 0.5, 0.0]}}
    set_key(data, "faults[0].start", 2.5)
    set_key(data, "environment.wind[0]", 4.0)
    set_key(data, "vehicle.mass", 1.3)  # a table the scenario did not have
    assert data == {
        "faults": [{"start": 2.5}],
        "environment": {"wind": [4.0, 0.5, 0.0]},
        "vehicle": {"mass": 1.3},
    }
    for bad in ("faults[1].start", "environment.gust[0]", "faults[0].start.x"):
        with pytest.raises(ValueError):
            set_key(data, bad, 1)
    for bad in ("", "a..b", "a[x]", "1a", "a b"):
        with pytest.raises(ValueError):
            parse_key(bad)


def test_a_grid_is_every_combination_times_every_seed(tmp_path: Path) -> None:
    sw = load_sweep(spec(tmp_path, SHOW), LIBRARY)
    assert len(sw.variants) == 2 * 3 * 4 and sw.columns == ["vehicle.mass", "environment.wind[0]"]
    combos = {(v.values["vehicle.mass"], v.values["environment.wind[0]"], v.seed) for v in sw.variants}
    assert len(combos) == 24 and len({v.id for v in sw.variants}) == 24
    v = next(v for v in sw.variants if v.values == {"vehicle.mass": 1.3, "environment.wind[0]": 4.0})
    assert v.data["vehicle"]["mass"] == 1.3 and v.data["environment"]["wind"] == [4.0, 0.5, 0.0]
    assert sw.scenario.plant.get("mass") is None  # the nominal scenario is untouched
    # the same spec again: the same ids (what a resumed sweep finds its runs by)
    assert [v.id for v in load_sweep(spec(tmp_path, SHOW), LIBRARY).variants] == [v.id for v in sw.variants]


def test_random_draws_follow_their_distributions_and_their_own_seed(tmp_path: Path) -> None:
    text = """
[sweep]
scenario = "step_roll"
mode = "random"
samples = 400
seed = 7

[[sweep.vary]]
key = "vehicle.mass"
uniform = [1.0, 1.4]

[[sweep.vary]]
key = "fc.rate_kp"
normal = [0.1, 0.01]
"""
    sw = load_sweep(spec(tmp_path, text), LIBRARY)
    mass = [v.values["vehicle.mass"] for v in sw.variants]
    kp = [v.values["fc.rate_kp"] for v in sw.variants]
    assert len(sw.variants) == 400 and all(1.0 <= m <= 1.4 for m in mass)
    # 400 draws: the mean within 4 standard errors of the distribution's
    assert abs(statistics.fmean(mass) - 1.2) < 4 * (0.4 / 12**0.5) / 20
    assert abs(statistics.fmean(kp) - 0.1) < 4 * 0.01 / 20 and 0.008 < statistics.stdev(kp) < 0.012
    again = load_sweep(spec(tmp_path, text), LIBRARY)
    assert [v.values for v in again.variants] == [v.values for v in sw.variants]
    other = load_sweep(spec(tmp_path, text.replace("seed = 7", "seed = 8")), LIBRARY)
    assert [v.values for v in other.variants] != [v.values for v in sw.variants]


@pytest.mark.parametrize(
    "text, where",
    [
        ("[sweep]\nseeds = 2\n", "sweep.scenario"),
        ('[sweep]\nscenario = "no_such"\n', "sweep.scenario"),
        ('[sweep]\nscenario = "step_roll"\nmode = "latin"\n', "sweep.mode"),
        ('[sweep]\nscenario = "step_roll"\nseeds = 0\n', "sweep.seeds"),
        ('[sweep]\nscenario = "step_roll"\nseeds = [1, 1]\n', "sweep.seeds"),
        ('[sweep]\nscenario = "step_roll"\ncolour = 1\n', "sweep"),
        ('[sweep]\nscenario = "step_roll"\n[[sweep.vary]]\nkey = "vehicle.mass"\n', "sweep.vary[0]"),
        (
            '[sweep]\nscenario = "step_roll"\n[[sweep.vary]]\nkey = "vehicle.mass"\nuniform = [1, 2]\n',
            "sweep.vary[0].uniform",
        ),
        (
            '[sweep]\nscenario = "step_roll"\nmode = "random"\n'
            '[[sweep.vary]]\nkey = "vehicle.mass"\nuniform = [1, 2]\n',
            "sweep.samples",
        ),
        (
            '[sweep]\nscenario = "step_roll"\n[[sweep.vary]]\nkey = "vehicle.mass"\nvalues = [1.1, 1.1]\n',
            "sweep.vary",
        ),
        # a variant the scenario checker refuses: named with the values that made it
        (
            '[sweep]\nscenario = "step_roll"\n[[sweep.vary]]\nkey = "vehicle.mass"\nvalues = [1.2, -1.0]\n',
            "variant vehicle.mass = -1.0",
        ),
        (
            '[sweep]\nscenario = "step_roll"\n[[sweep.vary]]\nkey = "vehicle.colour"\nvalues = [1]\n',
            "variant vehicle.colour = 1",
        ),
        (
            '[sweep]\nscenario = "step_roll"\n[[sweep.vary]]\nkey = "faults[3].start"\nvalues = [1]\n',
            "variant faults[3].start = 1",
        ),
        ("not toml [", "spec.toml"),
    ],
)
def test_a_bad_spec_or_variant_is_named(tmp_path: Path, text: str, where: str) -> None:
    with pytest.raises(SweepError) as e:
        load_sweep(spec(tmp_path, text), LIBRARY)
    assert str(e.value).startswith(where) or where in str(e.value), str(e.value)
