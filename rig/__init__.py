"""The rig: sessions and their clock, DUT adapters, transports and the command line."""

__version__ = "0.1.0"
