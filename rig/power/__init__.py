"""Bench power: the supply that feeds the board under test, so the rig can power-cycle it before a
bench run and record what it draws (docs/power.md). Each make of supply speaks its own protocol
behind the small interface in ``supply.py``."""
