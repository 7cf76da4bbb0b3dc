"""Sends garbage to the session's socket on connections of its own, then uses the bus normally."""
import os
import socket
import struct

from smbus2 import SMBus

path = os.environ["RIG_SOCKET"]
for junk in (struct.pack("<IHHQ", 0, 99, 0, 0),                   # unknown message type
             struct.pack("<IHHQ", 8, 1, 0, 0) + b"\x01\0\0\0\x02\0\0\0"
             + struct.pack("<IHHQ", 4, 2, 0, 0) + b"\x01\0\x09\0",  # HELLO, then an I2C request cut short
             struct.pack("<IHHQ", 0xFFFFFFF0, 1, 0, 0)):                    # a length far beyond the limit
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    s.connect(path)
    s.sendall(junk)
    s.recv(64)       # the session answers the HELLO or just closes; either way it must not hang us
    s.close()
with SMBus(1) as bus:
    print(hex(bus.read_byte_data(0x68, 0x75)))
