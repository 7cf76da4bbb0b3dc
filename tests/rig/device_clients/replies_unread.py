"""Writes MPU-6050 burst reads on a connection of its own and never reads a reply, until the session
closes that connection; then uses the bus normally."""
import os
import socket
import struct

from smbus2 import SMBus

HEADER = struct.Struct("<IHHQ")
s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
s.connect(os.environ["RIG_SOCKET"])
s.sendall(HEADER.pack(8, 1, 0, 0) + struct.pack("<II", 4, os.getpid()))  # HELLO, protocol 4
parts = struct.pack("<HHHH", 0x68, 0, 1, 0) + struct.pack("<HHHH", 0x68, 1, 14, 0)  # write 0x3B, read 14
burst = struct.pack("<HH", 1, 2) + parts + b"\x3b"
requests = (HEADER.pack(len(burst), 2, 0, 0) + burst) * 256
try:
    while True:
        s.sendall(requests)
except OSError:  # the session shut the connection: it is not read any more
    pass
with SMBus(1) as bus:
    print(hex(bus.read_byte_data(0x68, 0x75)))
