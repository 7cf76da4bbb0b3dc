"""The magnetometer's and barometer's samples in the lockstep fast path (rig/lockstep/mag_feed.c,
baro_feed.c) against the Python producers (emulators/chips/board.py MagFeed over MagModel, BaroFeed
over BaroModel and ms5611.encode), their reference: a flight controller that reads the HMC5883L through
the MPU's bypass, changes its rate and its mode (a new anchor: the Python producer's case), and reads
the MS5611's conversions at three OSRs, must get the same bytes, and leave the chip core's state (the
samples as float64, to the bit) and the producers' clocks the same, with the samples made in C; what C
does not make (a disturbance that is not a window, noise, the float encoding, a model replaced after
set-up) stays Python's."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

import pytest

import rig.protocol as P
from rig import scenarios
from rig.emulators import ms5611
from rig.emulators.chips.board import CHIP_BARO, CHIP_HMC, BaroFeed, MagFeed
from rig.emulators.sensor_models import AxisErrors, BaroModel, MagModel
from rig.scenarios.schema import load
from rig.session import Session
from rig.world import World, _WorldTruth
from tests.rig.test_lockstep_fastpath import CYCLE_NS, _fly, _i2c, _msg, _pwm, _same, _wait

HMC, MPU, BARO = 0x1E, 0x68, 0x77


def _script() -> list[bytes]:
    rd = P.I2C_M_RD
    out = [_msg(0, P.HELLO_MSG.pack(P.PROTOCOL_VERSION, 1234), P.MSG_HELLO)]
    out += [_i2c(0, [(MPU, 0, 2, bytes(rv))]) for rv in ((0x6B, 0x00), (0x1A, 0x03), (0x37, 0x02))]
    out += [_i2c(0, [(HMC, 0, 2, bytes(rv))]) for rv in ((0x00, 0x18), (0x02, 0x00))]  # 75 Hz, continuous
    out.append(_i2c(0, [(BARO, 0, 1, b"\x1e")]))  # reset (the PROM loaded)
    out += [_pwm(0, 0, P.PWM_EXPORT, 0), _pwm(0, 0, P.PWM_PERIOD, 2_500_000), _pwm(0, 0, P.PWM_ENABLE, 1)]
    t = 10_000_000
    for k in range(150):
        out.append(_i2c(t, [(MPU, 0, 1, b"\x3b"), (MPU, rd, 14, b"")]))
        if k % 3 == 0:
            out.append(_i2c(t + 100, [(HMC, 0, 1, b"\x03"), (HMC, rd, 6, b"")]))
        # OSR 256, then 1024 (0.6 and 2.3 ms at most) every cycle, then 4096 (8.2 ms typical, 9.0 at
        # most: the truth of another plant step) every third
        osr, every = (0, 1) if k < 70 else (2, 1) if k < 120 else (4, 3)
        if k % every == 0:
            out.append(_i2c(t + 300, [(BARO, 0, 1, b"\x00"), (BARO, rd, 3, b"")]))  # the last conversion
            d1 = (k // every) % 2
            out.append(_i2c(t + 400, [(BARO, 0, 1, bytes([(0x40 if d1 else 0x50) + 2 * osr]))]))
        if k == 60:
            out.append(_i2c(t + 200, [(HMC, 0, 2, b"\x00\x14")]))  # 30 Hz from now on
        if k == 100:
            out.append(_i2c(t + 200, [(HMC, 0, 2, b"\x02\x01")]))  # single: the clock anchored anew
        if k == 110:
            out.append(_i2c(t + 200, [(HMC, 0, 2, b"\x02\x00")]))  # continuous again
        out.append(_pwm(t + 1000, 0, P.PWM_DUTY, 1_100_000 + 1000 * k))
        out.append(_wait(t + 2000, t + CYCLE_NS, P.WAIT_SLEEP))
        t += CYCLE_NS
    return out


def _spinning(world: World) -> World:
    """The vehicle lifted and turned by external force and torque: the field it measures changes from
    one plant step to the next, so a sample taken from the wrong history row reads differently."""
    world.set_input("f_ext_d", -30.0)
    world.set_input("tau_ext_z", 0.2)
    return world


def _disturbed() -> World:
    """A world whose magnetometer sees a scenario's disturbance window, from 0.2 s to 0.4 s."""
    sc = load(Path(scenarios.__file__).parent / "library" / "hover_turbulence.toml")
    sc = dataclasses.replace(sc, mag_disturbance=(0.3, -0.2, 0.1), mag_disturbance_start=0.2,
                             mag_disturbance_end=0.4)
    return _spinning(World.at_rest(seed=3, mag_disturbance=sc.mag_disturbance_at))


def _own_prom() -> World:
    """Another PROM, set as a test sets it (the chip's and the producer's), and the datasheet's maximum
    conversion times."""
    world = _spinning(World.at_rest(seed=3))
    world.board.baro.prom = ms5611.with_crc((0, 41000, 37000, 24000, 22000, 32000, 29000, 0))
    feed = world.board.feeds[CHIP_BARO]
    assert isinstance(feed, BaroFeed)
    feed.timing = "max"
    world.board.lib.chip_ms5611_max_timing(world.board.addr, True)
    return world


def _air(t_ground: float, p_ground: float) -> Callable[[], World]:
    """Cold air (the datasheet's third tier, below -15 °C) or hot (first order only), thin or dense."""
    return lambda: _spinning(World.at_rest(seed=3, params={"t_ground": t_ground, "p_ground": p_ground}))


@pytest.mark.parametrize("world", [lambda: _spinning(World.at_rest(seed=3)), _disturbed, _own_prom,
                                   _air(-30.0, 70000.0), _air(45.0, 108000.0)],
                         ids=["calm", "disturbed", "prom-max", "cold", "hot"])
def test_the_samples_made_in_c_read_as_from_python(monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
                                                   world: object) -> None:
    py = _fly(monkeypatch, tmp_path, True, 0, script=_script(), world=world)  # type: ignore[arg-type]
    fast = _fly(monkeypatch, tmp_path, False, 0, script=_script(), world=world)  # type: ignore[arg-type]
    assert abs(py["world"]["yaw"]) > 0.1 and py["world"]["pd"] < -0.05  # (it turned and climbed)
    mag = [row.read for row in py["log"] if row.address == HMC and len(row.read) == 6]
    assert len(mag) == 50 and len(set(mag)) > 10  # the field moved between reads
    baro = [row.read for row in py["log"] if row.address == BARO and len(row.read) == 3]
    assert len(baro) == 130 and len(set(baro)) > 20  # D1 and D2 changed as it climbed
    # samples made in C (20 of the 50 magnetometer reads found a new one; each new anchor's first is
    # Python's) and every conversion
    made_mag, made_baro, _ = fast["made_here"]
    assert made_mag >= 15 and made_baro >= 120
    assert py["mag"][0] >= 3  # the clock was anchored anew (the rate, single, continuous again)
    _same(py, fast)


def _python_only() -> World:
    """What C leaves to the Python producers: a disturbance that is not a scenario's window, and the
    barometer's noise."""
    return _spinning(World.at_rest(seed=3, mag_disturbance=lambda t: (0.0, 0.1 * t, 0.0), baro_noise_pa=2.0))


def _float_encoding() -> World:
    world = _spinning(World.at_rest(seed=3))
    feed = world.board.feeds[CHIP_BARO]
    assert isinstance(feed, BaroFeed)
    feed.encoding = "float"
    return world


@pytest.mark.parametrize("world", [_python_only, _float_encoding], ids=["noise", "float"])
def test_what_c_does_not_make_stays_python(monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
                                           world: object) -> None:
    py = _fly(monkeypatch, tmp_path, True, 0, script=_script(), world=world)  # type: ignore[arg-type]
    fast = _fly(monkeypatch, tmp_path, False, 0, script=_script(), world=world)  # type: ignore[arg-type]
    made_mag, made_baro, _ = fast["made_here"]
    assert made_baro == 0 and (made_mag == 0) == (world is _python_only)
    _same(py, fast)


def _new_models(session: Session) -> None:
    """At 0.3 s the magnetometer's and barometer's producers get new models (another seed and hard iron,
    a barometer offset), as a test may set them: C made their samples until then, Python after."""
    def swap(s: Session) -> None:
        board, truth = s.world.board, _WorldTruth(s.world.plant)
        truth.world = s.world
        mag, baro = board.feeds[CHIP_HMC], board.feeds[CHIP_BARO]
        assert isinstance(mag, MagFeed) and isinstance(baro, BaroFeed)
        mag.source = MagModel(truth, errors=AxisErrors(bias=(0.05, 0.0, 0.0)), seed=11)
        baro.source = BaroModel(truth, offset_pa=50.0)
    session.at(0.3, swap)


def test_a_model_replaced_after_set_up_is_served_by_python(monkeypatch: pytest.MonkeyPatch,
                                                           tmp_path: Path) -> None:
    world = lambda: _spinning(World.at_rest(seed=3))  # noqa: E731
    py = _fly(monkeypatch, tmp_path, True, 0, script=_script(), world=world, prepare=_new_models)
    fast = _fly(monkeypatch, tmp_path, False, 0, script=_script(), world=world, prepare=_new_models)
    plain = _fly(monkeypatch, tmp_path, False, 0, script=_script(), world=world)
    made_mag, made_baro, _ = fast["made_here"]
    assert 0 < made_mag < plain["made_here"][0] and 0 < made_baro < plain["made_here"][1]
    assert fast["log"] != plain["log"]  # (the new models read differently)
    _same(py, fast)
