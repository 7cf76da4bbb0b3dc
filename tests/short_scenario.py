"""A scenario of a few seconds for tests that need a flight to have happened, not a particular one:
armed at zero throttle on the ground, judged level. Shared, so the tests that write it as a file (the
service's uploads, the one-core bench run) fly the same text."""

SHORT_BENCH = """[scenario]
name = "a short bench check"
duration = 2.5
[[timeline]]
t = 1.2
sticks = { arm = true, throttle = 0.0 }
[[criteria]]
name = "level"
metric = "max"
signal = "tilt"
max = 5.0
"""
