"""The chip core: the three chips' register behaviour in portable C (chip_core.h), its generated
register tables (gen.py) and the host side that feeds it samples and runs it on the rig's bus (board.py)."""
