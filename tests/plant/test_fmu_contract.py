"""The FMU as docs/design.md §4 names it: validates, loads, declares the contract, builds reproducibly."""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu

from rig.plant.build import build

INPUTS = ["pwm1_us", "pwm2_us", "pwm3_us", "pwm4_us", "wind_n", "wind_e", "wind_d", "f_ext_n",
          "f_ext_e", "f_ext_d", "tau_ext_x", "tau_ext_y", "tau_ext_z", "motor_health1",
          "motor_health2", "motor_health3", "motor_health4"]
PARAMETERS = ["mass", "arm_length", "k_thrust", "k_torque", "Ixx", "Iyy", "Izz", "frame", "motor_tau",
              "omega_max", "esc_min_us", "esc_max_us", "drag_n", "drag_e", "drag_d", "gravity", "stand",
              "roll0", "pitch0", "yaw0", "pn0", "pe0", "pd0", "mag_n", "mag_e", "mag_d", "p_ground",
              "t_ground", "h_max_step"] + [f"esc_{k}{i}" for k in ("gain", "offset") for i in range(1, 5)]
ADDITIONS = ["stand_damping", "esc_start_us"]  # beyond docs/design.md's "at least" list, in docs/plant.md
OUTPUTS = ["pn", "pe", "pd", "vn", "ve", "vd", "qw", "qx", "qy", "qz", "roll", "pitch", "yaw", "p", "q",
           "r", "fx", "fy", "fz", "mag_x", "mag_y", "mag_z", "pressure", "temperature", "omega1",
           "omega2", "omega3", "omega4", "thrust1", "thrust2", "thrust3", "thrust4", "on_ground"]

# docs/design.md §4 start values and seed 001 Table 1.
DEFAULTS = {"pwm1_us": 1000, "pwm4_us": 1000, "motor_health1": 1, "wind_n": 0, "mass": 1.2,
            "arm_length": 0.2, "k_thrust": 3.13e-5, "k_torque": 7.5e-7, "Ixx": 2.353e-3,
            "Iyy": 2.353e-3, "Izz": 5.262e-2, "gravity": 9.80665, "p_ground": 101325, "stand": 0,
            "frame": 0}
UNITS = {"pwm1_us": "us", "wind_n": "m/s", "f_ext_d": "N", "tau_ext_z": "N.m", "pd": "m",
         "p": "rad/s", "fz": "m/s2", "mag_z": "G", "pressure": "Pa", "omega3": "rad/s",
         "thrust2": "N", "roll": "rad", "mass": "kg", "Izz": "kg.m2"}


def test_fmpy_validate_finds_no_problems(fmu_path):
    assert validate_fmu(str(fmu_path)) == []


def test_model_description_declares_the_contract(fmu_path):
    md = read_model_description(str(fmu_path))
    assert md.fmiVersion == "2.0"
    assert md.coSimulation.modelIdentifier == "quadrotor"
    assert md.coSimulation.canGetAndSetFMUstate
    by_name = {v.name: v for v in md.modelVariables}
    for names, causality in ((INPUTS, "input"), (PARAMETERS, "parameter"), (OUTPUTS, "output")):
        for name in names:
            assert name in by_name, name
            assert by_name[name].causality == causality, name
    for name, start in DEFAULTS.items():
        assert float(by_name[name].start) == pytest.approx(start, rel=1e-12), name
    for name, unit in UNITS.items():
        assert by_name[name].unit == unit, name
    assert by_name["on_ground"].type == "Boolean"
    assert by_name["stand"].type == "Integer"


def test_every_declared_variable_reads_after_initialisation(fmu_path, tmp_path):
    """Through fmpy's own high-level API, not the rig's fast path."""
    md = read_model_description(str(fmu_path))
    unzip = extract(str(fmu_path), unzipdir=str(tmp_path / "fmu"))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier="quadrotor", instanceName="t")
    fmu.instantiate()
    try:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        read = {"Real": fmu.getReal, "Integer": fmu.getInteger, "Boolean": fmu.getBoolean}
        values = {v.name: read[v.type]([v.valueReference])[0] for v in md.modelVariables}
        fmu.doStep(0.0, 0.01)
        after = {v.name: read[v.type]([v.valueReference])[0] for v in md.modelVariables}
    finally:
        fmu.terminate()
        fmu.freeInstance()
    assert set(values) == set(INPUTS + PARAMETERS + ADDITIONS + OUTPUTS)
    assert values["qw"] == 1.0 and values["pressure"] == pytest.approx(101325.0)
    assert after["on_ground"] and after["pd"] == 0.0


def test_build_is_byte_reproducible(tmp_path):
    first = build(tmp_path / "a")
    second = build(tmp_path / "b")
    digest = [hashlib.sha256(Path(p).read_bytes()).hexdigest() for p in (first, second)]
    assert digest[0] == digest[1]
    shutil.rmtree(tmp_path / "a")


def test_fmu_ships_the_vendored_header_licence(fmu_path):
    import zipfile

    with zipfile.ZipFile(fmu_path) as zf:
        names = zf.namelist()
        assert "binaries/linux64/quadrotor.so" in names
        assert "BSD" in zf.read("documentation/licenses/fmi2-headers.txt").decode()
        assert names == sorted(names)
        assert {i.date_time for i in zf.infolist()} == {(1980, 1, 1, 0, 0, 0)}
