"""A client of the shim's protocol written by hand, which sends an I2C_WRITE notice (a write the session
promised to acknowledge) to an address nobody promised, on a connection of its own; then uses the bus
normally. A DUT's bytes are not trusted: the session must close that connection alone."""
import os
import socket
import struct

from smbus2 import SMBus

HELLO, I2C_WRITE, VERSION = 1, 6, 4
s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
s.connect(os.environ["RIG_SOCKET"])
s.sendall(struct.pack("<IHHQ", 8, HELLO, 0, 0) + struct.pack("<II", VERSION, os.getpid()))
s.recv(64)  # the HELLO's reply
write = struct.pack("<HH", 1, 1) + struct.pack("<HHHH", 0x50, 0, 1, 0) + b"\x00"
s.sendall(struct.pack("<IHHQ", len(write), I2C_WRITE, 0, 0) + write)
closed = s.recv(64) == b""
s.close()
with SMBus(1) as bus:
    print(closed, hex(bus.read_byte_data(0x68, 0x75)))
