"""run.mcap: one run as an MCAP file (Foxglove's container, as the ``mcap`` package's writer writes it:
reports/mcap_container.py), so the tools flight-software teams already use to look at flight logs
(Foxglove, PlotJuggler) open a rig run as they open a drone's log, with no CSV import step.

Why these choices:

* JSON messages with JSON schemas (``message_encoding="json"``, schema encoding ``jsonschema``): every
  MCAP viewer reads them with no generated code, and a test can read them back with the plain reader.
* One channel per signal group, each message stamped with its sim time in nanoseconds (log and publish
  time alike): the recorder's 100 Hz grid for the flight (``/attitude``: attitude, rates, altitude,
  setpoints, sticks and what the DUT reported; ``/motors``: the pulse widths), every I2C transfer at
  the sim time it reached the chips (``/i2c``), the sensor chips' own words decoded from those
  transfers (``/sensors``), every RC frame sent (``/rc``), the scheduled faults' switching as events
  (``/faults``) and the criteria as one final message (``/criteria``).
* "Sensors as the chips reported them" is taken literally: the raw counts the DUT read from each chip's
  data registers (the MPU-6050's 14 bytes from 0x3B, the HMC5883L's 6 bytes from 0x03, in a read that
  covers them; the MS5611's 24-bit ADC result), decoded from the I2C channel's bytes. That is what the
  firmware saw, faults and noise included, which the plant's truth on ``/attitude`` is not.
* The run's metadata (result.json's ``metadata``, each value as JSON text, since MCAP metadata maps
  strings to strings) goes in a metadata record ``result``; the verdict, error and notes in ``run``;
  a record ``mcap`` says which channels are empty and why (a target that cannot see the bus, an old
  run written again by ``rig report --mcap``, the transaction cap).

The attitude and motor channels hold exactly telemetry.csv's columns, sample for sample (NaN as null).
"""

from __future__ import annotations

import json
import math
import operator
import struct
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import IO, Any, Final, cast

import numpy as np

from rig.reports import foxglove, result_json
from rig.reports.mcap_container import ContainerWriter
from rig.scenarios.result import I2CRecord, RcFrame, RunResult
from rig.scenarios.schema import Scenario
from rig.scenarios.signals import BENCH_SIGNALS, SIGNALS

NS: Final = 1_000_000_000
PROFILE: Final = ""  # (no ROS profile: plain JSON channels)
#: the channels, in the order they are declared
ATTITUDE: Final = tuple(n for n in SIGNALS if not n.startswith("pwm") and n not in BENCH_SIGNALS)
MOTORS_GROUP: Final = tuple(n for n in SIGNALS if n.startswith("pwm"))
BENCH: Final = BENCH_SIGNALS
#: the rig's own channels (plot-only JSON), then those in Foxglove's well-known schemas (reports/foxglove.py)
RIG_TOPICS: Final = ("/attitude", "/motors", "/sensors", "/i2c", "/rc", "/faults", "/criteria")
TOPICS: Final = RIG_TOPICS + foxglove.TOPICS


def _number_schema(names: Iterable[str]) -> dict[str, Any]:
    props: dict[str, Any] = {"t": {"type": "number", "description": "sim time, s"}}
    for n in names:
        s = SIGNALS[n]
        props[n] = {"type": ["number", "null"], "description": f"{s.text} [{s.units}]" if s.units else s.text}
    return {"type": "object", "properties": props, "required": list(props)}


SCHEMAS: Final[dict[str, dict[str, Any]]] = {
    "/attitude": {"title": "rig.Attitude", **_number_schema(ATTITUDE)},
    "/motors": {"title": "rig.Motors", **_number_schema(MOTORS_GROUP + BENCH)},
    "/sensors": {
        "title": "rig.SensorReading",
        "type": "object",
        "properties": {
            "chip": {"type": "string", "description": "MPU-6050, HMC5883L or MS5611"},
            "address": {"type": "integer"},
            "register": {"type": "integer"},
            "values": {"type": "object", "additionalProperties": {"type": "integer"},
                       "description": "raw counts as the chip reported them"},
        },
        "required": ["chip", "address", "register", "values"],
    },
    "/i2c": {
        "title": "rig.I2CTransaction",
        "type": "object",
        "properties": {
            "t_ns": {"type": "integer", "description": "sim time the transfer reached the bus, ns"},
            "address": {"type": "integer", "description": "7-bit address of the first message"},
            "register": {"type": ["integer", "null"], "description": "the first byte written, if any"},
            "wrote": {"type": "string", "description": "bytes written, hex"},
            "read": {"type": "string", "description": "bytes read, hex"},
            "ok": {"type": "boolean", "description": "false: NACK or protocol error"},
        },
        "required": ["t_ns", "address", "register", "wrote", "read", "ok"],
    },
    "/rc": {
        "title": "rig.RcFrame",
        "type": "object",
        "properties": {
            "channels": {"type": "array", "items": {"type": "integer"}, "description": "SBUS values 0..2047"},
            "failsafe": {"type": "boolean"},
        },
        "required": ["channels", "failsafe"],
    },
    "/faults": {
        "title": "rig.FaultEvent",
        "type": "object",
        "properties": {
            "event": {"type": "string", "enum": ["active", "cleared"]},
            "what": {"type": "string"},
        },
        "required": ["event", "what"],
    },
    "/criteria": {
        "title": "rig.Criteria",
        "type": "object",
        "properties": {
            "verdict": {"type": "string"},
            "error": {"type": ["string", "null"]},
            "measurements": {"type": "array", "items": {"type": "object"}},
        },
        "required": ["verdict", "error", "measurements"],
    },
    **foxglove.SCHEMAS,
}

# the chips' data registers (emulators/chips): (addresses, first data register, chip, struct format,
# field names). A read that covers them, from that register or one before it (a firmware reading
# INT_STATUS or I2C_MST_STATUS with the samples in one burst), is decoded; other reads are configuration,
# left to /i2c. (The MPU-6050's EXT_SENS_DATA is laid out as each firmware sets its aux master up: left
# to /i2c too.)
_MPU = ("MPU-6050", ">7h", ("ax", "ay", "az", "temp", "gx", "gy", "gz"))
_HMC = ("HMC5883L", ">3h", ("x", "z", "y"))
SENSOR_WINDOWS: Final[tuple[tuple[tuple[int, ...], int, tuple[str, str, tuple[str, ...]]], ...]] = (
    ((0x68, 0x69), 0x3B, _MPU),
    ((0x1E,), 0x03, _HMC),
)
_MS5611 = (0x76, 0x77)
#: one encoder for the messages built as dicts (json.dumps with options makes a new one per call), compact
_JSON: Final = json.JSONEncoder(allow_nan=False, separators=(",", ":"))


def _template(fields: Sequence[tuple[str, str]]) -> str:
    """A %-format of one JSON object as ``_JSON`` writes it, for fields whose values need no escaping:
    ``(name, "%d" | "%s" | '"%s"' | the JSON of a constant or a nested template)``."""
    return "{" + ",".join(f"{json.dumps(k)}:{v}" for k, v in fields) + "}"


# /i2c and /sensors by bytes formatting: their fields are ints, hex and names with nothing to escape,
# and they are four fifths of a run's messages; the JSON encoder's dicts were about a third of
# writing run.mcap, a sweep run's largest report (tests/scenarios/test_mcap_encoding.py checks them
# against json.dumps)
_I2C: Final = _template([("t_ns", "%d"), ("address", "%d"), ("register", "%s"), ("wrote", '"%s"'),
                         ("read", '"%s"'), ("ok", "%s")]).encode()
_BOOL: Final = b"false", b"true"


def _i2c_json(rec: I2CRecord) -> bytes:
    """/i2c's message for ``rec``, as ``_JSON`` writes it."""
    register = b"null" if rec.register is None else b"%d" % rec.register
    return _I2C % (rec.t_ns, rec.address, register, rec.wrote.hex().encode(), rec.read.hex().encode(),
                   _BOOL[bool(rec.ok)])


def _sensor_template(chip: str, register: int, names: Sequence[str]) -> bytes:
    values = _template([(n, "%d") for n in names])
    return _template([("chip", json.dumps(chip)), ("address", "%d"), ("register", str(register)),
                      ("values", values)]).encode()


_MS5611_TEMPLATE: Final = _sensor_template("MS5611", 0, ("adc",))
_SENSOR_TEMPLATES: Final = tuple(_sensor_template(chip, first, names)
                                 for _, first, (chip, _, names) in SENSOR_WINDOWS)


def _sensor_json(rec: I2CRecord) -> bytes | None:
    """/sensors' message: the chip's data as it reported them, when ``rec`` read a data register; else
    None."""
    if not rec.ok or rec.register is None or not rec.read:
        return None
    if rec.address in _MS5611 and rec.register == 0x00 and len(rec.read) == 3:
        return _MS5611_TEMPLATE % (rec.address, int.from_bytes(rec.read, "big"))
    for (addresses, first, (_, fmt, _)), template in zip(SENSOR_WINDOWS, _SENSOR_TEMPLATES, strict=True):
        skip = first - rec.register
        if rec.address in addresses and skip >= 0 and len(rec.read) >= skip + struct.calcsize(fmt):
            return template % (rec.address, *struct.unpack_from(fmt, rec.read, skip))
    return None


def _row_dict(t: float, names: Sequence[str], values: Sequence[float]) -> dict[str, Any]:
    """One recorder row as /attitude's or /motors' message: NaN (not recorded) as null."""
    row: dict[str, Any] = {"t": t}
    for n, v in zip(names, values, strict=True):
        row[n] = None if v != v else v
    return row


def _rows(signals: dict[str, np.ndarray], names: Sequence[str]) -> Iterable[tuple[int, bytes]]:
    """/attitude's or /motors' messages, one per recorder row: ``_row_dict`` as ``_JSON`` writes it.

    By string formatting, as /i2c's: ``%r`` of a float is JSON's number, and the encoder's dict per
    row cost about half as much again as the floats' own formatting. A column that is NaN throughout
    (the bench supply's in lockstep, the FC's estimates when it reports none) is null in the template
    itself; a row with another NaN or an infinity goes through ``_JSON`` (NaN: null; infinity: its
    error, as before). tests/scenarios/test_mcap_encoding.py holds the two to the same bytes."""
    t = np.asarray(signals["t"], dtype=np.float64)
    cols = [n for n in names if n in signals and len(signals[n]) == len(t)]
    if not len(t):
        return
    block = np.column_stack([t, *(np.asarray(signals[n], dtype=np.float64) for n in cols)])
    unset = [False, *(bool(np.isnan(block[:, k]).all()) for k in range(1, block.shape[1]))]  # (t: always set)
    kept = [k for k in range(block.shape[1]) if not unset[k]]
    template = _template([("t", "%r"), *((n, "null" if unset[k + 1] else "%r") for k, n in enumerate(cols))])
    values = operator.itemgetter(*kept)
    plain = cast(list[bool], np.isfinite(block[:, kept]).all(axis=1).tolist())
    for row, ok in zip(block.tolist(), plain, strict=True):
        if ok:
            yield round(row[0] * NS), (template % values(row)).encode()
        else:
            yield round(row[0] * NS), _JSON.encode(_row_dict(row[0], cols, row[1:])).encode()


def _fault_events(r: RunResult) -> list[tuple[int, dict[str, Any]]]:
    """The ``fault`` signal's edges (any scheduled sensor fault or magnetic disturbance switching on
    or off), named by the scenario's faults when the run still has them."""
    t, f = r.signals.get("t", np.zeros(0)), r.signals.get("fault", np.zeros(0))
    faults = r.scenario.faults if isinstance(r.scenario, Scenario) else ()
    what = "; ".join(f"{f.target} {f.fault.kind} {f.fault.start:g}..{f.fault.end:g} s" for f in faults)
    what = what or "a scheduled sensor fault or the magnetic disturbance (the signal fault)"
    out, prev = [], 0.0
    for k in range(min(len(t), len(f))):
        now = 0.0 if math.isnan(f[k]) else float(f[k])
        if now != prev:
            out.append((round(float(t[k]) * NS), {"event": "active" if now else "cleared", "what": what}))
        prev = now
    return out


def write(out: IO[bytes] | Path, r: RunResult, i2c: Sequence[I2CRecord] | None,
          rc: Sequence[RcFrame] | None, why_empty: dict[str, str] | None = None) -> None:
    """Writes ``r`` as MCAP to ``out``. ``i2c``/``rc``: the run's transactions and frames; None when
    they are not known (the target cannot see the bus, an old run): ``why_empty`` says why, by topic,
    into the ``mcap`` metadata record."""
    if isinstance(out, Path):
        with open(out, "wb") as f:
            write(f, r, i2c, rc, why_empty)
        return
    why = dict(why_empty or {})
    if i2c is None:
        why.setdefault("/i2c", "the run's transactions are not known")
        why.setdefault("/sensors", "decoded from /i2c, which is empty")
    if rc is None:
        why.setdefault("/rc", "the run's RC frames are not known")
    w = ContainerWriter(out)
    w.start(profile=PROFILE, library="rig reports/mcap.py")
    ch: dict[str, int] = {}
    schema_ids: dict[str, int] = {}
    for topic in TOPICS:
        title = SCHEMAS[topic]["title"]
        if title not in schema_ids:  # (the two transforms' channels share foxglove.FrameTransform)
            schema_ids[title] = w.register_schema(name=title, encoding="jsonschema",
                                                  data=json.dumps(SCHEMAS[topic]).encode())
        ch[topic] = w.register_channel(topic=topic, message_encoding="json", schema_id=schema_ids[title])
    seq = dict.fromkeys(TOPICS, 0)

    def messages() -> Iterator[tuple[str, int, bytes]]:
        """(topic, time, JSON) of every message, in the file's order."""
        for t_ns, data in _rows(r.signals, ATTITUDE):
            yield "/attitude", t_ns, data
        for t_ns, data in _rows(r.signals, MOTORS_GROUP + BENCH):
            yield "/motors", t_ns, data
        for rec in i2c or ():
            yield "/i2c", rec.t_ns, _i2c_json(rec)
            reading = _sensor_json(rec)
            if reading is not None:
                yield "/sensors", rec.t_ns, reading
        for frame in rc or ():
            yield "/rc", frame.t_ns, _JSON.encode({"channels": list(frame.channels),
                                                   "failsafe": frame.failsafe}).encode()
        faults = _fault_events(r)
        for t_ns, ev in faults:
            yield "/faults", t_ns, _JSON.encode(ev).encode()
        for t_ns, data in foxglove.transforms(r.signals, "vehicle", "roll", "pitch"):
            yield foxglove.TRANSFORM_TOPIC, t_ns, data
        for t_ns, data in foxglove.transforms(r.signals, "target", "roll_sp", "pitch_sp"):
            yield foxglove.TARGET_TOPIC, t_ns, data
        t = r.signals.get("t", np.zeros(0))
        end = round(float(t[-1]) * NS) if len(t) else 0
        for t_ns, entry in foxglove.logs(end, r.notes, faults, r.stderr, r.verdict, r.error):
            yield foxglove.LOG_TOPIC, t_ns, _JSON.encode(entry).encode()
        measurements = result_json.to_dict(r)["measurements"]
        criteria = {"verdict": r.verdict, "error": r.error, "measurements": measurements}
        yield "/criteria", end, _JSON.encode(criteria).encode()

    def numbered() -> Iterator[tuple[int, int, bytes, int, int]]:
        """The container's (channel, log time, data, publish time, sequence) of each message."""
        for topic, t_ns, data in messages():
            t_ns = max(0, t_ns)  # (MCAP times are unsigned)
            yield ch[topic], t_ns, data, t_ns, seq[topic]
            seq[topic] += 1

    w.add_messages(numbered())
    w.add_metadata("result", {str(k): json.dumps(v, allow_nan=False) for k, v in r.metadata.items()})
    w.add_metadata("run", {"scenario": r.scenario.stem, "verdict": r.verdict, "error": r.error or "",
                           "notes": json.dumps(r.notes), "format": result_json.FORMAT})
    w.add_metadata("mcap", {**{f"note {k}": v for k, v in why.items()},
                            **{f"messages {k}": str(n) for k, n in seq.items()}})
    w.finish()


FILE: Final = "run.mcap"


def write_run(folder: Path, r: RunResult, why_empty: dict[str, str] | None = None) -> Path:
    """``folder``/run.mcap for ``r``, written whole or not at all (a temporary name, then renamed)."""
    why = dict(why_empty or {})
    mode = r.metadata.get("mode", "?")
    if not len(r.signals.get("t", ())):  # (rig/runner.py's not_run: the DUT never started)
        for topic in ("/i2c", "/sensors", "/rc"):
            why.setdefault(topic, "the run recorded nothing: it did not take place")
    if r.i2c is None:
        why.setdefault("/i2c", f"this target ({mode}) cannot see the DUT's I2C transfers: only their count "
                               "(result.json's bus_transactions) is known")
    else:
        total = r.metadata.get("bus_transactions")
        if isinstance(total, int) and total > len(r.i2c):
            why.setdefault("/i2c", f"holds the first {len(r.i2c)} of the run's {total} transfers (the cap "
                                   "keeps a run's memory bounded)")
    path = folder / FILE
    tmp = folder / f".{FILE}.tmp"
    try:
        write(tmp, r, r.i2c, r.rc_frames, why)
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


__all__ = ["FILE", "RIG_TOPICS", "SCHEMAS", "TOPICS", "write", "write_run"]
