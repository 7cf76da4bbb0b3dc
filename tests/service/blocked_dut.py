"""A DUT that stays running until it is stopped, without moving lockstep's virtual time: it writes its
pid into argv[1] (a FIFO, tests/waits.py), then blocks opening argv[2], a FIFO nobody writes to. (A
spinner on the clock would move virtual time and end its run at the scenario's duration at once.)"""

import os
import sys

with open(sys.argv[1], "w") as f:
    f.write(f"{os.getpid()}\n")
open(sys.argv[2]).read()  # blocks: no writer ever comes
