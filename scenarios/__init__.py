"""Scenarios: the file format and its checker, the recorded signals, the metrics and criteria, the
runner, and the scenario library (``scenarios/library/*.toml``)."""

from rig.compiled import install as _install_compiled

_install_compiled()  # the hot modules from build/mypyc while they match their sources (rig/compiled.py)
