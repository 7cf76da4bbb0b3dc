"""The preloaded shim (C) and its build; see rigshim.c and protocol.h."""
