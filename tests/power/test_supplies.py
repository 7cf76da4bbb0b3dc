"""The supply drivers against simulated supplies on real ptys through pyserial: the RD6006's
registers and scales, the Korad's text protocol, and a supply that is silent, answers with bad CRCs or
garbles its numbers gives a PsuError naming it within its timeout (the rig keeps running)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from rig.power.riden import MODELS, RidenSupply, model_of
from rig.power.supply import PsuError, power_cycle
from rig.scenarios.bench import parse_psu
from tests.power.sim_supplies import SimKorad, SimRiden, crc16_modbus


@pytest.fixture
def riden() -> Iterator[SimRiden]:
    s = SimRiden()
    yield s
    s.close()


@pytest.fixture
def korad() -> Iterator[SimKorad]:
    s = SimKorad()
    yield s
    s.close()


def test_crc16_modbus_matches_the_specifications_example() -> None:
    # Modbus over serial line v1.02 §6.2.2 example: read 1 register at 0x0000 of unit 1 -> "84 0A"
    assert crc16_modbus(bytes.fromhex("010300000001")).to_bytes(2, "little") == bytes.fromhex("840a")


def test_spec_parsing() -> None:
    s = parse_psu("riden:/dev/ttyUSB0@115200")
    assert (s.make, s.port, s.baud) == ("riden", "/dev/ttyUSB0", 115200)
    assert parse_psu("korad:/dev/ttyACM0").baud is None
    for bad in ("riden", "owon:/dev/x", "riden:", "riden:/dev/x@fast", "riden:/dev/x@12"):
        with pytest.raises(ValueError, match="MAKE:PORT|baud rate"):
            parse_psu(bad)


def test_models_by_their_id_register() -> None:
    assert model_of(60062).name == "RD6006" and model_of(60062).i_scale == 1000
    assert model_of(60065).v_scale == 1000
    assert model_of(60181).i_scale == 100
    assert len({m.name for m in MODELS}) == len(MODELS)
    with pytest.raises(PsuError, match="60300"):
        model_of(60300)


def test_riden_sets_switches_and_reads_in_volts_and_amps(riden: SimRiden) -> None:
    psu = RidenSupply(riden.path)
    try:
        assert psu.identity() == "Riden RD6006"
        psu.set_voltage(11.1)
        psu.set_current_limit(1.5)
        assert riden.regs[8] == 1110 and riden.regs[9] == 1500  # ÷100 and ÷1000 on the RD6006
        off = psu.read()
        assert (off.output, off.volts, off.amps) == (False, 0.0, 0.0)
        psu.output(True)
        on = psu.read()
        assert on.output and on.volts == pytest.approx(11.1) and on.amps == pytest.approx(0.35)
        assert on.volts_set == pytest.approx(11.1) and on.amps_limit == pytest.approx(1.5)
        assert on.detail == "CV"
        riden.load.amps = 2.0  # more than the limit: constant current at the limit
        cc = psu.read()
        assert cc.amps == pytest.approx(1.5) and cc.detail == "CC"
        assert psu.measure() == pytest.approx((11.1, 1.5))
        with pytest.raises(PsuError, match="outside"):
            psu.set_voltage(61)
        assert riden.writes() == [(8, 1110), (9, 1500), (18, 1)]
    finally:
        psu.close()


def test_riden_power_cycle_is_off_then_on_then_up(riden: SimRiden) -> None:
    psu = RidenSupply(riden.path)
    try:
        r = power_cycle(psu, off_s=0.0)
        assert r.output and r.volts == pytest.approx(12.0)
        assert riden.writes() == [(18, 0), (18, 1)]
    finally:
        psu.close()


@pytest.mark.parametrize("mode, words", [("silent", "no valid answer"), ("bad_crc", "no valid answer")])
def test_riden_that_does_not_answer_properly_is_a_clear_error(riden: SimRiden, mode: str, words: str) -> None:
    riden.mode = mode
    with pytest.raises(PsuError, match=f"riden:{riden.path}: {words}.*within 0.2 s"):
        RidenSupply(riden.path, timeout=0.2)
    assert ("read", (0, 1)) in riden.log  # it heard the question; only the answer was wrong


def test_riden_unknown_model_is_refused() -> None:
    s = SimRiden(model_id=12345)
    try:
        with pytest.raises(PsuError, match="12345, not a model"):
            RidenSupply(s.path, timeout=0.2)
    finally:
        s.close()


def test_korad_text_protocol(korad: SimKorad) -> None:
    from rig.power.korad import KoradSupply

    psu = KoradSupply(korad.path, gap_s=0.0)
    try:
        assert psu.identity().startswith("KORAD KA3005P")
        psu.set_voltage(5.0)
        psu.set_current_limit(0.8)
        r = power_cycle(psu, off_s=0.0)
        assert r.output and r.volts == pytest.approx(5.0) and r.amps == pytest.approx(0.35)
        assert r.amps_limit == pytest.approx(0.8) and r.detail == "CV"
        assert korad.commands()[:4] == ["*IDN?", "VSET1:05.00", "ISET1:0.800", "OUT0"]
        assert "OUT1" in korad.commands()
        korad.garble = True
        with pytest.raises(PsuError, match="VOUT1\\? answered b'1x.0y'"):
            psu.measure()
    finally:
        psu.close()


def test_korad_silent_is_a_clear_error(korad: SimKorad) -> None:
    from rig.power.korad import KoradSupply

    korad.mode = "silent"
    with pytest.raises(PsuError, match="no answer to \\*IDN\\? within 0.2 s"):
        KoradSupply(korad.path, timeout=0.2, gap_s=0.0)


def test_no_such_port_is_a_clear_error() -> None:
    with pytest.raises(PsuError, match="cannot open"):
        RidenSupply("/dev/nonexistent-psu")


def test_a_scenarios_bench_table_is_checked(tmp_path: Path) -> None:
    from rig.scenarios.schema import ScenarioError, load

    base = ('[scenario]\nname = "x"\nduration = 1.0\n'
            '[[criteria]]\nname = "c"\nmetric = "max"\nsignal = "roll"\nmax = 1\n[bench]\n')
    for body, words in (('psu = "owon:/dev/x"', "bench.psu.*MAKE one of riden, korad"),
                        ("max_current = -1", "bench.max_current"), ("off_s = 100", "bench.off_s"),
                        ("volts_set = 3", "bench.volts_set.*unknown key")):
        f = tmp_path / "s.toml"
        f.write_text(base + body + "\n")
        with pytest.raises(ScenarioError, match=words):
            load(f)
    f.write_text(base + 'psu = "korad:/dev/ttyACM0@9600"\nvolts = 5\nmax_current = 1.5\n')
    bench = load(f).bench
    assert (bench.psu, bench.volts, bench.max_current) == ("korad:/dev/ttyACM0@9600", 5.0, 1.5)
    assert bench.off_s == 1.0
