"""Building the rig's own C libraries: a missing compiler or a compile error is a clear message."""

from __future__ import annotations

import os

import pytest

from rig.emulators.native import SAMPLING_SOURCE
from rig.plant.native_build import NativeBuildError, compile_shared, is_stale


def test_a_missing_compiler_is_named(tmp_path) -> None:
    with pytest.raises(NativeBuildError, match="no-such-cc not found \\(install gcc\\)"):
        compile_shared([SAMPLING_SOURCE], tmp_path / "lib.so", "the test library", cc="no-such-cc")
    assert not list(tmp_path.iterdir())


def test_a_compile_error_carries_the_compilers_words_and_leaves_nothing(tmp_path) -> None:
    bad = tmp_path / "bad.c"
    bad.write_text("int f(void) { return undeclared; }\n")
    with pytest.raises(NativeBuildError, match="building the test library failed:(.|\n)*undeclared"):
        compile_shared([bad], tmp_path / "lib.so", "the test library")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.c"]


def test_a_library_is_stale_when_missing_or_older_than_a_source(tmp_path) -> None:
    src, lib = tmp_path / "a.c", tmp_path / "a.so"
    src.write_text("int f(void) { return 1; }\n")
    assert is_stale(lib, [src])
    compile_shared([src], lib, "the test library")
    assert not is_stale(lib, [src])
    t = lib.stat().st_mtime
    os.utime(src, (t + 10, t + 10))
    assert is_stale(lib, [src])


def test_the_per_cycle_entry_points_refuse_wrong_arguments_with_a_clear_error() -> None:
    from rig.emulators.native import BLOCK, fast

    m = fast()
    with pytest.raises(TypeError, match="lowpass_run takes 6 arguments \\(2 given\\)"):
        m.lowpass_run(1, 2)
    with pytest.raises(TypeError):  # a float where an address goes, before any C runs
        m.channel_measure(0.5, 1, 0, 0, 0, 0)
    with pytest.raises(TypeError):
        m.imu_measure(0, 0, [], [], 0, "warm", 0)
    with pytest.raises(ValueError, match="as many rows as times"):  # refused before any C runs
        m.imu_measure(0, 0, [0.0, 0.001], [0], 0, 10.0, 0)
    with pytest.raises(ValueError, match=f"at most {BLOCK}"):  # the C side's limit is the Python side's
        m.imu_measure(0, 0, [0.0] * (BLOCK + 1), [0] * (BLOCK + 1), 0, 10.0, 0)
    with pytest.raises(TypeError):  # a time that is not a number
        m.imu_measure(0, 0, ["noon"], [0], 0, 10.0, 0)


def test_one_library_serves_both_ctypes_and_the_module() -> None:
    from rig.emulators.native import LIB, fast, sampling

    assert fast().__file__ == str(LIB)
    assert sampling()._name == str(LIB)
    assert sampling().rig_lowpass_max_depth() > 0


def test_the_plant_steps_refuse_wrong_arguments_with_a_clear_error() -> None:
    from rig.plant.steps import plant_steps

    with pytest.raises(TypeError, match="plant_steps takes 5 arguments \\(0 given\\)"):
        plant_steps()()  # type: ignore[call-arg]
    with pytest.raises(TypeError):
        plant_steps()(0, 1, "a step", 1, 0)  # type: ignore[arg-type]
    from rig.plant.steps import get_boolean

    with pytest.raises(TypeError, match="get_boolean takes 3 arguments \\(1 given\\)"):
        get_boolean()(0)  # type: ignore[call-arg]
    with pytest.raises(ValueError, match="a function and a component"):
        get_boolean()(0, 0, 1)


def test_on_ground_read_in_c_is_the_fmus_own_answer() -> None:
    """The plant's on_ground (read through _plantsteps.get_boolean) against fmi2GetBoolean through
    ctypes, at rest and in the air."""
    import ctypes

    from rig.plant.fmu import Plant

    plant = Plant()
    out = (ctypes.c_int * 1)()

    def by_ctypes() -> bool:
        assert plant._get_int["Boolean"](plant._component, plant._on_ground_vr, 1, out) == 0
        return bool(out[0])

    assert plant.on_ground and by_ctypes()
    for name in ("pwm1_us", "pwm2_us", "pwm3_us", "pwm4_us"):
        plant.u[plant.u_index[name]] = 2000.0
    plant.run(0.5, 0.001)
    assert not plant.on_ground and not by_ctypes()
