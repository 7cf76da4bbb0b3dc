"""Scenarios: the file format and its checker, the recorded signals, the metrics and criteria, the
runner, and the scenario library (``scenarios/library/*.toml``)."""
