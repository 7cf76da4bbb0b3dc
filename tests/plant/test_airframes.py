"""Airframes as data (plant/airframes.py): every shipped file loads and cites its source, the plant
refuses inertia no rigid body has and non-positive mass or inertia, and the ESC start threshold."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from rig.plant import Plant, PlantError, airframes
from rig.plant.airframes import AirframeError
from tests.plant.helpers import DT, IXX, IYY, IZZ, MASS, OMEGA_MAX, G, flying, pwms

SHIPPED = ("f450", "racer-250", "seed-001")


def _rigid(ixx: float, iyy: float, izz: float) -> bool:
    """The triangle inequality of principal moments, written here: each at most the other two's sum."""
    return ixx <= iyy + izz and iyy <= ixx + izz and izz <= ixx + iyy


def test_the_shipped_airframes_are_the_seed_and_a_450_and_a_250_class():
    assert tuple(airframes.shipped()) == SHIPPED
    assert airframes.load("f450").airframe_class.startswith("450")
    assert airframes.load("racer-250").airframe_class.startswith("250")


@pytest.mark.parametrize("name", SHIPPED)
def test_each_airframe_loads_and_cites_its_source(name):
    frame = airframes.load(name)
    assert frame.name == name and len(frame.sha256) == 64
    # a citation: authors or a document, and something a reader can look up (a year, a DOI, a URL)
    assert len(frame.source) > 80
    assert re.search(r"\b(19|20)\d\d\b|doi:|https?://|arXiv:", frame.source), frame.source
    for key in ("mass", "arm_length", "k_thrust", "k_torque", "Ixx", "Iyy", "Izz", "motor_tau",
                "esc_start_us"):
        assert key in frame.params, key


@pytest.mark.parametrize("name", ["f450", "racer-250"])
def test_the_measured_airframes_are_rigid_bodies_that_can_hover(name):
    p = airframes.load(name).params
    assert _rigid(p["Ixx"], p["Iyy"], p["Izz"])
    assert not airframes.load(name).inconsistent
    hover = math.sqrt(p["mass"] * G / (4 * p["k_thrust"]))  # thrust = k w^2 carries the weight
    assert hover < 0.8 * p["omega_max"]  # and leaves room to climb and to steer


def test_the_seeds_airframe_is_the_plant_default_and_says_it_is_inconsistent():
    frame = airframes.load("seed-001")
    p = frame.params
    assert p["mass"] == MASS and (p["Ixx"], p["Iyy"], p["Izz"]) == (IXX, IYY, IZZ)
    assert not _rigid(IXX, IYY, IZZ)  # Izz 5.262e-2 > Ixx + Iyy 4.706e-3
    assert "physically inconsistent" in frame.describe() and "seed 001" in frame.describe()
    assert airframes.DEFAULT_AIRFRAME == "seed-001"


def test_the_plant_refuses_inertia_that_breaks_the_triangle_inequality():
    assert not _rigid(1e-3, 1e-3, 1e-2)
    with pytest.raises(PlantError, match=r"Izz must be <= Ixx \+ Iyy"):
        Plant(params={"Ixx": 1e-3, "Iyy": 1e-3, "Izz": 1e-2})
    with pytest.raises(PlantError, match=r"Ixx must be <= Iyy \+ Izz"):
        Plant(params={"Ixx": 0.3, "Iyy": 0.1, "Izz": 0.1})
    # a flat plate: Izz = Ixx + Iyy exactly, a rigid body
    with Plant(params={"Ixx": 0.01, "Iyy": 0.02, "Izz": 0.03}) as plant:
        assert plant.output("pd") == 0.0


MINE = 'name = "mine"\nsource = "Me, bench 2026, https://x"\n'


def _write(tmp_path: Path, params: str, meta: str = MINE) -> Path:
    path = tmp_path / "mine.toml"
    path.write_text(f"[airframe]\n{meta}\n[params]\n{params}\n")
    return path


@pytest.mark.parametrize(("params", "key", "words"), [
    ("mass = 0.0", "params.mass", "mass must be > 0"),
    ("mass = -1.0", "params.mass", "mass must be > 0"),
    ("Ixx = 0.0", "params.Ixx", "Ixx must be > 0"),
    ("Izz = -0.01", "params.Izz", "Izz must be > 0"),
    ("Ixx = 0.01\nIyy = 0.01\nIzz = 0.05", "params.Izz", "triangle inequality"),
    ("masss = 1.0", "params.masss", "did you mean 'mass'"),
    ("mass = \"heavy\"", "params.mass", "expected a number"),
    ("stand = 1", "params.stand", "unknown key"),  # where it stands is the scenario's, not the airframe's
])
def test_a_user_airframe_the_plant_would_refuse_is_refused_naming_the_key(tmp_path, params, key, words):
    with pytest.raises(AirframeError, match=re.escape(key) + ".*" + re.escape(words)):
        airframes.load(_write(tmp_path, params))


def test_an_airframe_must_cite_a_source(tmp_path):
    with pytest.raises(AirframeError, match=r"airframe.source: missing \(an airframe cites"):
        airframes.load(_write(tmp_path, "mass = 1.0", meta='name = "mine"'))
    with pytest.raises(AirframeError, match="airframe.source: empty"):
        airframes.load(_write(tmp_path, "mass = 1.0", meta='name = "mine"\nsource = " "'))


def test_copying_the_seeds_inertia_must_say_it_is_inconsistent(tmp_path):
    params = f"Ixx = {IXX}\nIyy = {IYY}\nIzz = {IZZ}"
    with pytest.raises(AirframeError, match="airframe.inconsistent: missing"):
        airframes.load(_write(tmp_path, params))


def test_an_unknown_airframe_name_suggests_a_shipped_one():
    with pytest.raises(AirframeError, match="did you mean 'f450'"):
        airframes.load("f405")


def test_the_esc_does_not_start_a_motor_below_its_threshold():
    start = 1100.0
    below, above = 1090.0, 1150.0
    with flying(pwm=(below,) * 4, esc_start_us=start) as plant:
        plant.run(0.5, DT)
        assert [plant.output(f"omega{m}") for m in range(1, 5)] == [0.0] * 4
        for m in range(1, 5):
            plant.set_input(f"pwm{m}_us", above)
        plant.run(0.5, DT)  # 25 motor time constants: settled
        expected = OMEGA_MAX * (above - 1000.0) / (2000.0 - 1000.0)  # the linear ESC curve from esc_min_us
        assert plant.output("omega1") == pytest.approx(expected, rel=1e-6)


def test_the_default_threshold_changes_nothing_at_the_bottom_of_the_range():
    with Plant(params={"pd0": -100.0}, inputs=pwms(1001.0, 1001.0, 1001.0, 1001.0)) as plant:
        plant.run(0.5, DT)
        assert plant.output("omega1") == pytest.approx(OMEGA_MAX * 1e-3, rel=1e-6)
