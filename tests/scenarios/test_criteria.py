"""Metrics against analytic responses: a second-order step with known overshoot, rise and settling."""

from __future__ import annotations

import math

import numpy as np

from rig.scenarios.criteria import measure


def second_order(zeta: float, wn: float, t: np.ndarray) -> np.ndarray:
    wd = wn * math.sqrt(1 - zeta**2)
    phi = math.acos(zeta)
    return 1 - np.exp(-zeta * wn * t) / math.sqrt(1 - zeta**2) * np.sin(wd * t + phi)


T = np.arange(0, 20, 0.001)


def m(metric: str, x: np.ndarray, **kw: float) -> float:
    return measure(
        "c", metric, "roll", T, x, 0.0, 20.0, kw.get("target"), kw.get("band"), None, 1e9, ""
    ).value


def test_overshoot_matches_the_analytic_percentage() -> None:
    zeta = 0.4
    expected = 100 * math.exp(-zeta * math.pi / math.sqrt(1 - zeta**2))
    assert abs(m("overshoot", 10 * second_order(zeta, 3.0, T), target=10.0) - expected) < 0.05


def test_settling_time_matches_the_envelope_bound() -> None:
    zeta, wn = 0.5, 4.0
    ts = m("settling_time", second_order(zeta, wn, T), target=1.0, band=0.02)
    assert ts <= -math.log(0.02 * math.sqrt(1 - zeta**2)) / (zeta * wn) + 1e-3  # the envelope's bound
    assert ts > 0.8 * (4 / (zeta * wn))


def test_rise_time_of_a_first_order_lag_is_tau_ln9() -> None:
    tau = 0.3
    assert abs(m("rise_time", 1 - np.exp(-T / tau), target=1.0) - tau * math.log(9)) < 2e-3


def test_a_step_never_reached_fails_instead_of_passing() -> None:
    r = measure("c", "settling_time", "roll", T, 0.5 * np.ones_like(T), 0.0, 20.0, 1.0, 0.1, None, 5.0, "s")
    assert r.value == math.inf and r.outcome == "fail"
    r = measure("c", "max", "est_roll", T, np.full_like(T, math.nan), 0.0, 20.0, None, None, None, 5.0, "deg")
    assert r.outcome == "fail" and "not reported" in r.reason


def test_time_in_band_and_rms() -> None:
    x = np.sin(2 * math.pi * T)
    assert abs(m("rms_error", x) - 1 / math.sqrt(2)) < 1e-3
    assert abs(m("time_in_band", x, band=math.sin(math.pi / 4)) - 50.0) < 0.1


def test_a_baseline_target_counts_from_the_signal_at_that_time() -> None:
    """A 1-unit second-order step that starts from 2.5: target 1.0 from the baseline at t = 0 measures
    it exactly as the same step from 0 with an absolute target, whatever window the metric uses."""
    zeta = 0.4
    x = 2.5 + second_order(zeta, 3.0, T)
    expected = 100 * math.exp(-zeta * math.pi / math.sqrt(1 - zeta**2))
    r = measure("c", "overshoot", "alt", T, x, 0.0, 20.0, 1.0, None, None, 1e9, "%", baseline_at=0.0)
    assert abs(r.value - expected) < 0.05
    late = measure(
        "c", "steady_state_error", "alt", T, x, 15.0, 20.0, 1.0, None, None, 1e9, "m", baseline_at=0.0
    )
    assert late.value < 1e-4  # settled at 3.5 = 2.5 + 1
    absolute = measure("c", "steady_state_error", "alt", T, x, 15.0, 20.0, 1.0, None, None, 1e9, "m")
    assert abs(absolute.value - 2.5) < 1e-4


def test_a_step_never_reached_has_no_overshoot() -> None:
    """A DUT that never moved passed "overshoot <= 20 %" at 0 %: the step must be reached (90 % of it)
    before its overshoot means anything."""
    flat = np.zeros_like(T)
    half = 10 * (1 - np.exp(-T)) * 0.5  # creeps to half the step
    for x in (flat, half):
        r = measure("c", "overshoot", "roll", T, x, 0.0, 20.0, 10.0, None, None, 20.0, "%")
        assert math.isnan(r.value) and r.outcome == "fail"
        assert "the step was never reached" in r.reason
    rising = 10 * (1 - np.exp(-T))
    reached = measure("c", "overshoot", "roll", T, rising, 0.0, 20.0, 10.0, None, None, 20.0, "%")
    assert reached.value == 0.0 and reached.outcome == "pass"  # an overdamped response that got there
