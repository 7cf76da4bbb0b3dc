"""``Plant.step_many``: several steps in one call into C (plant/c/plant_steps.c) must be exactly
``step`` called that many times (the second implementation it is checked against), and fail the way
``step`` fails."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rig.plant import PlantError
from tests.plant.helpers import DT, HOVER_PWM, flying

WOBBLE = (HOVER_PWM + 40, HOVER_PWM - 30, HOVER_PWM + 10, HOVER_PWM)


def test_many_steps_in_one_call_are_the_steps_one_by_one_bit_for_bit() -> None:
    with flying(WOBBLE) as a, flying(WOBBLE) as b:
        ring = np.full((7, len(a.y)), np.nan)
        rows: list[np.ndarray] = []
        for n, wind in ((4, 0.0), (1, 3.0), (10, -2.0), (0, 5.0)):  # 15 steps: the ring wraps twice
            a.set_input("wind_n", wind)
            b.set_input("wind_n", wind)
            a.step_many(n, DT, ring=ring, first_row=len(rows) + 1)
            for _ in range(n):
                b.step(DT)
                rows.append(b.y.copy())
            assert np.array_equal(a.y, b.y) and a.time == b.time
        assert a.time == pytest.approx(15 * DT)
        assert a.get_value("wind_n") == -2.0  # no steps, nothing written
        for k, row in enumerate(rows, start=1):  # the last write of each slot is the latest step there
            if k > len(rows) - len(ring):
                assert np.array_equal(ring[k % len(ring)], row)


def test_inputs_are_written_once_unless_asked() -> None:
    with flying(WOBBLE) as a, flying(WOBBLE) as b:
        a.set_input("wind_n", 4.0)
        a.step_many(3, DT, write_inputs=False)  # u changed, but the FMU was not told
        b.run(3 * DT, DT)
        assert np.array_equal(a.y, b.y)
        assert a.get_value("wind_n") == 0.0


def test_a_call_the_fmu_refuses_raises_with_the_fmus_words_and_moves_no_time() -> None:
    with flying(WOBBLE) as a:
        with pytest.raises(PlantError, match="fmi2DoStep returned Error: .*communication step"):
            a.step_many(2, -DT)
        assert a.time == 0.0
        a.set_input("pwm3_us", math.nan)
        with pytest.raises(PlantError, match="fmi2SetReal returned Error: .*pwm3_us"):
            a.step_many(2, DT)
        assert a.time == 0.0


def test_a_ring_of_the_wrong_shape_is_refused() -> None:
    with flying() as a:
        for bad in (np.zeros((4, len(a.y) + 1)), np.zeros((4, len(a.y)), dtype=np.float32),
                    np.zeros((len(a.y), 4)).T):
            with pytest.raises(ValueError, match="C-contiguous float64 rows"):
                a.step_many(1, DT, ring=bad)
        assert a.time == 0.0


def test_a_reader_gives_the_outputs_and_inputs_numpy_indexing_gives() -> None:
    """Plant.reader (one C call over the buffers, into a row) against numpy's own indexing of the same
    buffers, as a flight changes them, with the extras after them and the row's neighbours untouched;
    indices outside a buffer and rows longer than their room are refused, by the Python check and by
    the C one."""
    from rig.plant.steps import gather

    with flying(WOBBLE) as a:
        outputs, inputs = [3, 0, len(a.y) - 1, 3], [len(a.u) - 1, 0]
        read = a.reader(outputs, inputs)
        table = np.full(16, -7.0)
        for n in (0, 1, 7):
            a.step_many(n, DT)
            a.set_input("wind_n", float(n))
            read(table.ctypes.data + 8, 9, (float(n), 2))
            want = a.y[outputs].tolist() + a.u[inputs].tolist() + [float(n), 2.0]
            assert table.tolist() == [-7.0, *want, *[-7.0] * 7]
        a.reader([], [])(table.ctypes.data, 0, ())  # nothing to write: no room needed
        for bad_out, bad_in in (([len(a.y)], []), ([], [-1])):
            with pytest.raises(IndexError, match="outside the plant's"):
                a.reader(bad_out, bad_in)
        with pytest.raises(IndexError, match="a row of 8 values where 7 are left"):
            read(table.ctypes.data, 7, (1.0, 2.0))
        with pytest.raises(TypeError, match="must be real number"):
            read(table.ctypes.data, 16, ("1.0",))  # type: ignore[arg-type]
        y_addr, u_addr, out = a.y.ctypes.data, a.u.ctypes.data, table.ctypes.data
        with pytest.raises(IndexError, match="index 5 outside 5"):
            gather()(y_addr, 5, (0, 5), u_addr, 1, (), out, 16, ())
        with pytest.raises(TypeError, match="tuples"):
            gather()(y_addr, 5, [0], u_addr, 1, (), out, 16, ())  # type: ignore[arg-type]
        with pytest.raises(ValueError, match="addresses"):
            gather()(0, 5, (0,), u_addr, 1, (), out, 16, ())
        with pytest.raises(ValueError, match="addresses"):
            gather()(y_addr, 5, (0,), u_addr, 1, (), 0, 16, ())
        with pytest.raises(TypeError, match="9 arguments"):
            gather()(y_addr, 5, (0,), u_addr, 1, ())  # type: ignore[call-arg]
