"""Scenario schema, metrics and criteria, and the scenario library (``*.toml``)."""
