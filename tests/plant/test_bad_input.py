"""Bad input gets the documented answer (docs/plant.md, "Bad input") and never corrupts the state.

"Not corrupted" is checked against a twin plant that never saw the bad input: after the rejected call,
both continue with the same good inputs and must stay bit-identical.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.simulation import FMICallException
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rig.plant import Plant, PlantError
from rig.plant.variables import PARAMETERS, check_parameters
from tests.plant.helpers import DT, HOVER_PWM, flying, pwms

WOBBLE = (HOVER_PWM + 5, HOVER_PWM - 3, HOVER_PWM + 1, HOVER_PWM)


def _twins() -> tuple[Plant, Plant]:
    return flying(WOBBLE), flying(WOBBLE)


def _continue_together(a: Plant, b: Plant) -> None:
    a.run(0.5, DT)
    b.run(0.5, DT)
    assert np.array_equal(a.y, b.y)
    assert a.time == b.time


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_input_is_rejected_whole_and_changes_nothing(bad):
    a, b = _twins()
    with a, b:
        a.run(0.2, DT)
        b.run(0.2, DT)
        before = a.y.copy()
        a.set_input("wind_n", 7.0)  # a good value in the same call ...
        a.set_input("pwm3_us", bad)  # ... and a bad one
        with pytest.raises(PlantError, match="pwm3_us = .* is not a finite number"):
            a.step(DT)
        assert np.array_equal(a.y, before) and a.time == pytest.approx(0.2)
        assert a.get_value("wind_n") == 0.0  # the good value of the rejected call was not applied
        assert a.get_value("pwm3_us") == pytest.approx(WOBBLE[2])
        a.set_input("wind_n", 0.0)
        a.set_input("pwm3_us", WOBBLE[2])
        _continue_together(a, b)


def test_non_finite_value_by_name_is_rejected():
    with flying() as plant:
        with pytest.raises(PlantError, match="not a finite number"):
            plant.set_value("tau_ext_z", math.nan)
        assert plant.get_value("tau_ext_z") == 0.0


def test_parameter_after_initialisation_is_refused_and_keeps_its_value():
    a, b = _twins()
    with a, b:
        with pytest.raises(PlantError, match="cannot set parameter mass after initialisation"):
            a.set_value("mass", 2.0)
        assert a.get_value("mass") == 1.2
        with pytest.raises(PlantError, match="cannot set parameter stand after initialisation"):
            a.set_value("stand", 1)
        _continue_together(a, b)


def test_outputs_cannot_be_set():
    with flying() as plant:
        with pytest.raises(PlantError, match="cannot set roll: it is an output"):
            plant.set_value("roll", 1.0)


def test_an_unknown_value_reference_is_refused_and_nothing_is_set():
    """fmi2SetReal checks the whole call first: a value reference past the last Real refuses it all."""
    import ctypes

    with flying() as plant:
        before = plant.get_value("wind_n")
        vrs = (ctypes.c_uint * 2)(plant.variables["wind_n"].valueReference, 10_000)
        values = (ctypes.c_double * 2)(3.0, 1.0)
        assert plant._set_real(plant._component, vrs, 2, values) == 3  # fmi2Error
        assert "no Real variable has value reference 10000" in plant.messages[-1]
        assert plant.get_value("wind_n") == before


@pytest.mark.parametrize(("given", "same_as"), [(5000.0, 2000.0), (2000.5, 2000.0), (-50.0, 1000.0),
                                                (0.0, 1000.0), (999.0, 1000.0)])
def test_out_of_range_pulse_widths_are_clamped_by_the_esc(given, same_as):
    with Plant(inputs=pwms(given, 1000, 1000, 1000)) as a, \
            Plant(inputs=pwms(same_as, 1000, 1000, 1000)) as b:
        assert a.get_value("pwm1_us") == given  # stored as given
        a.run(0.3, DT)
        b.run(0.3, DT)
        assert np.array_equal(a.y, b.y)


def test_negative_motor_health_acts_as_zero():
    with flying(pwms_tuple := (HOVER_PWM,) * 4) as a, flying(pwms_tuple) as b:
        a.set_input("motor_health2", -3.0)
        b.set_input("motor_health2", 0.0)
        a.run(0.2, DT)
        b.run(0.2, DT)
        assert a.output("thrust2") == 0.0
        assert np.array_equal(a.y, b.y)


@pytest.mark.parametrize(
    ("params", "message"),
    [({"mass": 0.0}, "mass must be > 0"), ({"Izz": -1.0}, "Izz must be > 0"),
     ({"stand": 7}, "stand must be 0..4"), ({"frame": 2}, "frame must be 0"),
     ({"pd0": 1.0}, "pd0 must be <= 0 in free flight"), ({"h_max_step": 0.0}, "h_max_step"),
     ({"esc_max_us": 900.0}, "esc_max_us must be > esc_min_us"), ({"motor_tau": 0.0}, "motor_tau"),
     ({"p_ground": -5.0}, "p_ground must be > 0"), ({"t_ground": -300.0}, "absolute zero")],
)
def test_meaningless_parameters_fail_initialisation_with_the_parameter_named(params, message):
    with pytest.raises(PlantError, match=message):
        Plant(params=params)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.dictionaries(
    st.sampled_from(sorted(PARAMETERS)),
    st.one_of(st.sampled_from([0.0, -1.0, 1.0, 4.0, 5.0, 0.1, 0.2, 1e-9, -300.0, 2000.0, 500.0]),
              st.floats(-1e4, 1e4, allow_nan=False)),
    max_size=3,
))
def test_the_scenario_checker_refuses_exactly_what_the_fmu_refuses(values):
    """plant.variables.check_parameters (what `rig validate` applies) against the FMU's own check at
    initialisation: the same verdict, and the same words, on random parameter sets."""
    values = {k: (round(v) if PARAMETERS[k].type == "Integer" else v) for k, v in values.items()}
    said = check_parameters(values)
    try:
        Plant(params=values).close()
        refused = None
    except PlantError as e:
        refused = str(e)
    assert (said is None) == (refused is None), (values, said, refused)
    if said is not None:
        assert said in refused


def test_below_ground_start_is_fine_on_a_stand():
    with Plant(params={"stand": 4, "pd0": 1.0}) as plant:
        assert plant.output("pd") == 1.0


def test_unknown_names_and_fractional_integers_are_refused():
    with pytest.raises(PlantError, match="unknown parameter 'masss'.*mass"):
        Plant(params={"masss": 1.0})
    with pytest.raises(PlantError, match="unknown input 'mass'"):
        Plant(inputs={"mass": 1.0})
    with pytest.raises(PlantError, match="stand takes a whole number"):
        Plant(params={"stand": 1.5})
    with flying() as plant:
        with pytest.raises(PlantError, match="unknown input 'pwm5_us'; the plant's inputs are: .*pwm4_us"):
            plant.set_input("pwm5_us", 1000.0)
        with pytest.raises(PlantError, match="unknown output 'rol'"):
            plant.output("rol")


@pytest.mark.parametrize("dt", [0.0, -1e-3, math.nan, math.inf])
def test_bad_step_sizes_are_refused_and_leave_the_state(dt):
    a, b = _twins()
    with a, b:
        with pytest.raises(PlantError, match="communication step"):
            a.step(dt)
        a.time = b.time  # the failed step did not advance the FMU; realign the Python clock
        _continue_together(a, b)


def test_step_at_the_wrong_time_is_refused():
    with flying() as plant:
        plant.time = 5.0
        with pytest.raises(PlantError, match="is not the instance's time"):
            plant.step(DT)


def test_saved_state_restores_bit_exactly():
    with flying(WOBBLE) as plant:
        plant.run(0.3, DT)
        saved = plant.save()
        plant.set_input("wind_e", 4.0)
        plant.run(0.5, DT)
        first = plant.y.copy()
        plant.set_input("wind_e", -9.0)  # diverge after the save ...
        plant.run(0.2, DT)
        plant.restore(saved)  # ... then go back: time, inputs and physics return
        assert plant.time == pytest.approx(0.3) and plant.u[plant.u_index["wind_e"]] == 0.0
        plant.set_input("wind_e", 4.0)
        plant.run(0.5, DT)
        assert np.array_equal(plant.y, first)


def test_serialised_state_round_trips_and_corrupt_bytes_are_refused(fmu_path, tmp_path):
    md = read_model_description(str(fmu_path))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(fmu_path), unzipdir=str(tmp_path)),
                    modelIdentifier="quadrotor", instanceName="s")
    fmu.instantiate()
    try:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.setReal([md.modelVariables[[v.name for v in md.modelVariables].index("pd0")]
                     .valueReference], [-30.0])
        fmu.exitInitializationMode()
        fmu.doStep(0.0, 0.5)
        blob = fmu.serializeFMUstate(fmu.getFMUstate())
        vr_pd = next(v.valueReference for v in md.modelVariables if v.name == "pd")
        pd_then = fmu.getReal([vr_pd])[0]
        fmu.doStep(0.5, 0.5)
        fmu.setFMUstate(fmu.deSerializeFMUstate(blob))
        assert fmu.getReal([vr_pd])[0] == pd_then
        with pytest.raises(FMICallException):
            fmu.deSerializeFMUstate(blob[:-8])
        corrupt = bytearray(blob)
        corrupt[:8] = b"NOTSTATE"
        with pytest.raises(FMICallException):
            fmu.deSerializeFMUstate(bytes(corrupt))
    finally:
        fmu.freeInstance()
