"""Exercises /dev/i2c-1 the way drivers do, including what the kernel refuses; prints JSON results."""

import errno
import fcntl
import json
import os
import stat
import struct

from smbus2 import SMBus, i2c_msg

I2C_SLAVE, I2C_FUNCS, I2C_PEC = 0x0703, 0x0705, 0x0708
I2C_FUNC_I2C, I2C_FUNC_SMBUS_QUICK, I2C_FUNC_SMBUS_PEC = 0x1, 0x10000, 0x8
I2C_FUNC_SMBUS_READ_BLOCK_DATA = 0x01000000


def err(fn):
    try:
        fn()
    except OSError as e:
        return errno.errorcode[e.errno]
    return "ok"


out: dict[str, object] = {}
st = os.stat("/dev/i2c-1")
out["stat"] = [stat.S_ISCHR(st.st_mode), os.major(st.st_rdev), os.minor(st.st_rdev)]
out["access"] = os.access("/dev/i2c-1", os.R_OK | os.W_OK)
out["other_bus"] = err(lambda: os.open("/dev/i2c-0", os.O_RDWR))

fd = os.open("/dev/i2c-1", os.O_RDWR)
funcs = struct.unpack("L", fcntl.ioctl(fd, I2C_FUNCS, struct.pack("L", 0)))[0]
out["funcs"] = [bool(funcs & f) for f in (I2C_FUNC_I2C, I2C_FUNC_SMBUS_QUICK, I2C_FUNC_SMBUS_READ_BLOCK_DATA,
                                          I2C_FUNC_SMBUS_PEC)]
out["slave_0x80"] = err(lambda: fcntl.ioctl(fd, I2C_SLAVE, 0x80))
out["unknown_ioctl"] = err(lambda: fcntl.ioctl(fd, 0x5401, b"\0" * 64))   # TCGETS on an i2c node
out["read_before_slave"] = err(lambda: os.read(fd, 1))                    # client address 0: nobody
fcntl.ioctl(fd, I2C_SLAVE, 0x68)
os.write(fd, bytes([0x75]))
out["plain_read"] = os.read(fd, 1)[0]
out["pec"] = err(lambda: fcntl.ioctl(fd, I2C_PEC, 1))
out["pread"] = err(lambda: os.pread(fd, 1, 0))                           # i2c-dev has no offsets
os.close(fd)

with SMBus(1) as bus:
    out["quick_68"] = err(lambda: bus.write_quick(0x68))
    out["quick_50"] = err(lambda: bus.write_quick(0x50))
    bus.write_byte_data(0x68, 0x6B, 0x01)                         # wake, PLL on gyro X
    out["word_6b"] = bus.read_word_data(0x68, 0x6B)               # PWR_MGMT_1 | PWR_MGMT_2 << 8
    out["bytes_6b"] = [bus.read_byte_data(0x68, 0x6B), bus.read_byte_data(0x68, 0x6C)]
    bus.write_word_data(0x68, 0x19, 0x0304)                       # SMPLRT_DIV=4, CONFIG=3
    out["after_word_write"] = bus.read_i2c_block_data(0x68, 0x19, 2)
    bus.write_i2c_block_data(0x68, 0x1B, [0x18, 0x08])            # GYRO_CONFIG, ACCEL_CONFIG
    out["after_block_write"] = [bus.read_byte_data(0x68, 0x1B), bus.read_byte_data(0x68, 0x1C)]
    bus.write_byte(0x68, 0x75)
    out["receive_byte"] = bus.read_byte(0x68)
    # WHO_AM_I = 0x68 = 104 is no SMBus block count (1..32): the kernel says EPROTO
    out["block_read"] = err(lambda: bus.read_block_data(0x68, 0x75))
    # writes I2C_SLV0_ADDR/REG, then reads on from the register pointer (0x27, 0x28) without a command
    out["proc_call"] = bus.process_call(0x68, 0x25, 0x1234)
    lo, hi = bus.read_i2c_block_data(0x68, 0x27, 2)
    out["proc_call_expected"] = lo | hi << 8
    out["slv0_addr_reg"] = bus.read_i2c_block_data(0x68, 0x25, 2)
    w, r = i2c_msg.write(0x68, [0x75]), i2c_msg.read(0x68, 1)
    bus.i2c_rdwr(w, r)
    out["rdwr"] = list(bytes(r))
    out["rdwr_nack"] = err(lambda: bus.i2c_rdwr(i2c_msg.write(0x68, [0x75]), i2c_msg.read(0x51, 1)))
print(json.dumps(out))
