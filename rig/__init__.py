"""The rig: sessions and their clock, DUT adapters, transports and the command line."""

from rig import compiled as _compiled

__version__ = "0.1.0"

_compiled.install()  # the session's hot modules from build/mypyc while they match their sources
