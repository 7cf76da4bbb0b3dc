"""How a measurement, its limits and margin, and the run's metadata read, the same in every report."""

from __future__ import annotations

import math
import re
import signal
from collections.abc import Callable, Mapping
from typing import Any

from rig.scenarios.criteria import MARGINAL_PCT, Measurement
from rig.scenarios.signals import SIGNALS


def fmt_value(v: float, units: str) -> str:
    if math.isnan(v):
        return "not measured"
    if math.isinf(v):
        return "never" if units == "s" else ("+inf" if v > 0 else "-inf")
    return f"{v:.4g} {units}".strip()


def fmt_limits(m: Measurement) -> str:
    lo = "" if m.min is None else f"{m.min:g}"
    hi = "" if m.max is None else f"{m.max:g}"
    if lo and hi:
        return f"{lo} .. {hi} {m.units}".strip()
    return (f">= {lo}" if lo else f"<= {hi}") + (f" {m.units}" if m.units else "")


def fmt_margin(m: Measurement) -> str:
    """The margin in % of the nearer limit, "marginal" when a pass is within MARGINAL_PCT of it."""
    if m.margin is None:
        return "n/a"
    text = f"{m.margin:.1f} %"
    return f"{text} (marginal)" if m.marginal else text


def fmt_target(m: Measurement) -> str:
    """What the metric measured against: the target and the band around it, when it has them."""
    units = SIGNALS[m.signal].units if m.signal in SIGNALS else ""  # (the signal's, not the metric's: %, s)
    parts = []
    if m.target is not None:
        parts.append(f"target {m.target:.4g} {units}".rstrip())
    if m.band is not None:
        parts.append(f"band ±{m.band:g} {units}".rstrip())
    return ", ".join(parts)


def outcome_text(m: Measurement) -> str:
    """pass, marginal pass, fail or not judged: the word every report uses for this measurement."""
    return "marginal pass" if m.outcome == "pass" and m.marginal else m.outcome


def outcome_class(m: Measurement) -> str:
    return "marginal" if m.outcome == "pass" and m.marginal else m.outcome.replace(" ", "-")


def json_number(v: float) -> dict[str, float | str | None]:
    """A measurement's value as result.json keeps it (``rig-result/1``): JSON has no NaN or infinity,
    so those are ``"value": null`` with ``"value_reason"`` saying which: ``"nan"`` (not measured: no
    sample of the signal), ``"inf"`` or ``"-inf"`` (a time that never came; an unbounded value). A
    finite value has no reason. Valid JSON for every reader; nothing to mistake for a number."""
    if math.isfinite(v):
        return {"value": v}
    return {"value": None, "value_reason": "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")}


def from_json_number(value: object, reason: object = None) -> float:
    """``json_number``'s pair read back as a float (NaN for anything else)."""
    if isinstance(value, int | float) and not isinstance(value, bool):
        return float(value)
    return {"inf": math.inf, "-inf": -math.inf}.get(str(reason), math.nan)


# ---- the run's metadata ---------------------------------------------------------------------------


#: what names a bench bridge, as the bridge session's link figures give it (rig/bridge/session.py)
BRIDGE_IDENTITY = {
    "bridge_id": "id",
    "protocol": "protocol",
    "core_version": "core",
    "firmware_sha256_8": "firmware",
}


def mode_text(meta: Mapping[str, Any]) -> str:
    """lockstep, real time or bridge with the bridge's identity: its port, name, protocol, core version
    and firmware hash, read from ``bridge`` (a port, or the bridge session's figures) or beside it."""
    mode = meta.get("mode") or ("lockstep" if meta.get("lockstep", True) else "real time")
    bridge = meta.get("bridge")
    src: Mapping[str, Any] = bridge if isinstance(bridge, Mapping) else meta
    port = (
        bridge
        if isinstance(bridge, str)
        else src.get("bridge")
        if isinstance(src.get("bridge"), str)
        else None
    )
    ident = [f"{label} {src[k]}" for k, label in BRIDGE_IDENTITY.items() if src.get(k) not in (None, "")]
    if port:
        ident.insert(0, f"port {port}")
    if not ident and mode != "bridge":
        return str(mode)
    return f"bridge (bench: {', '.join(ident)})" if ident else "bridge"


def returncode_text(code: object, verdict: str) -> str:
    """The DUT's exit status in words: -15 at the end of a judged run is the rig's normal stop."""
    if not isinstance(code, int):
        return "none (the DUT did not run to an exit the rig saw)"
    if code >= 0:
        return f"{code} (the DUT exited by itself)"
    try:
        name = signal.Signals(-code).name
    except ValueError:
        name = f"signal {-code}"
    if code == -signal.SIGTERM and verdict in ("pass", "fail"):
        return f"{code} ({name}: the rig stopped the DUT at the end of the scenario, its normal stop)"
    if code == -signal.SIGKILL:
        return f"{code} ({name}: the DUT was killed, having not stopped on SIGTERM)"
    return f"{code} (the DUT was ended by {name})"


def _s(v: object, digits: int = 3) -> str:
    return f"{float(v):.{digits}f} s" if isinstance(v, int | float) else "—"


def _dict(v: object) -> str:
    if not isinstance(v, dict):
        return str(v)
    return ", ".join(f"{k} {val:.4g}" if isinstance(val, float) else f"{k} {val}" for k, val in v.items())


def bus_problems_text(v: object) -> str:
    """result.json's ``bus_problems`` (the MCU tier's counts of what the firmware saw go wrong on its
    bus) as words, the kinds with a count only: "none", or "3: address NACKs 2, abandoned waits 1"."""
    if not isinstance(v, Mapping):
        return str(v)
    total = sum(int(n) for n in v.values())
    if total == 0:
        return "none"
    words = [f"{str(k).replace('_', ' ').replace('nacks', 'NACKs')} {n}" for k, n in v.items() if n]
    return f"{total}: " + ", ".join(words)


def _lateness(v: object) -> str:
    if not isinstance(v, dict):
        return str(v)
    said = (
        f"{v.get('late_over_1ms')} of {v.get('events')} scheduled events over 1 ms late; worst "
        f"{float(v.get('max_s') or 0) * 1000:.2f} ms, p99 {float(v.get('p99_s') or 0) * 1000:.2f} ms"
    )
    return said + host_said(v)


def host_said(v: Mapping[str, Any]) -> str:
    """The host's own figures in a run's ``realtime_lateness``, where it has them (rig.pace.HostState):
    how late the loop's paced waits woke, what the hypervisor took, whose each event over 1 ms late was.
    Beside the events' lateness they say whose it was (the report's line, and a paced test's words)."""
    said = ""
    if "wait_p99_s" in v:
        said += (f"; the loop's waits woke p99 {float(v['wait_p99_s'] or 0) * 1000:.2f} ms late, worst "
                 f"{float(v.get('wait_max_s') or 0) * 1000:.1f} ms")
    if "steal_s" in v:
        said += f"; the hypervisor took {float(v['steal_s'] or 0):.2f} s of the host's CPUs"
    causes = v.get("late_causes")
    if isinstance(causes, Mapping) and any(causes.values()):
        said += "; late by cause: " + ", ".join(f"{k.replace('_', ' ')} {n}" for k, n in causes.items() if n)
    return said


#: key -> (label, formatter of the value); the order is the order of the run table
META: dict[str, tuple[str, Callable[[object], str]]] = {
    "started": ("started (UTC)", str),
    "host": ("host", str),
    "mode": ("mode", str),  # (replaced by mode_text, which reads the bridge too)
    "rig_version": ("rig version", str),
    "plant_fmu_sha256": ("plant FMU SHA-256", str),
    "scenario_file": ("scenario file", str),
    "scenario_sha256": ("scenario SHA-256", str),
    "airframe": ("airframe", str),
    "airframe_sha256": ("airframe SHA-256", str),
    "seed": ("random seed", str),
    "dut_command": ("DUT command", str),
    "dut_firmware": ("firmware", str),
    "dut_firmware_sha256": ("firmware SHA-256", lambda v: str(v) if v else "not hashed"),
    "dut_program": ("program", str),
    "dut_program_sha256": ("program SHA-256", lambda v: str(v) if v else "not hashed"),
    "dut_launcher": ("launcher", str),
    "fc_profile": ("FC profile", str),
    "fc_profile_file": ("FC profile file", str),
    "fc_profile_sha256": ("FC profile SHA-256", str),
    "capture": ("PWM capture", str),
    "duration": ("scenario duration", lambda v: _s(v, 1)),
    "sim_time": ("sim time flown", lambda v: _s(v, 3)),
    "wall_time": ("wall time", lambda v: _s(v, 2)),
    "realtime_factor": (
        "real-time factor",
        lambda v: f"{float(v):.1f}×" if isinstance(v, int | float) else "—",
    ),
    "dut_clock_base_s": (
        "DUT clock at sim time 0",
        lambda v: (
            f"{float(v):.3f} s (CLOCK_MONOTONIC; the DUT's t={float(v):.3f} is sim 0 s)"
            if isinstance(v, int | float)
            else "—"
        ),
    ),
    "bus_transactions": ("I2C transfers", lambda v: f"{v:,}" if isinstance(v, int) else str(v)),
    "bus_problems": ("I2C problems the firmware saw", bus_problems_text),
    "capture_stats": ("capture statistics", _dict),
    "realtime_lateness": ("real-time lateness", _lateness),
    "transport": ("lockstep transport", _dict),
}
#: keys shown elsewhere or folded into another row
HIDDEN = {"scenario", "scenario_name", "lockstep", "fc_config", "dut_returncode", "bridge"}


def meta_rows(meta: Mapping[str, Any], verdict: str) -> list[tuple[str, str]]:
    """The run's metadata as (label, text) rows with units and words, not Python's reprs."""
    rows: list[tuple[str, str]] = []
    for key, (label, fmt) in META.items():
        if key == "mode":
            rows.append((label, mode_text(meta)))
        elif key in meta and meta[key] is not None:
            rows.append((label, fmt(meta[key])))
        if key == "realtime_factor" and "dut_returncode" in meta:
            rows.append(("DUT exit status", returncode_text(meta["dut_returncode"], verdict)))
    rows += [(k, _dict(v)) for k, v in meta.items() if k not in META and k not in HIDDEN]
    return rows


_DUT_TIME = re.compile(r"\bt=(\d+(?:\.\d+)?)")


def sim_times_in(text: str, clock_base_s: float | None) -> str:
    """The DUT's own ``t=…`` stamps (its monotonic clock) with the sim time beside each, so a line
    of its stderr can be found on the plots, whose time axis is sim time from 0."""
    if clock_base_s is None:
        return text

    def add(m: re.Match[str]) -> str:
        sim = float(m.group(1)) - clock_base_s
        return f"{m.group(0)} [sim {sim:.3f} s]" if sim > -1.0 else m.group(0)

    return _DUT_TIME.sub(add, text)


__all__ = ["MARGINAL_PCT", "bus_problems_text", "fmt_limits", "fmt_margin", "fmt_target", "fmt_value",
           "from_json_number", "json_number", "meta_rows"]
