"""Byte-accurate device models (MPU-6050, HMC5883L, MS5611), the I2C bus, sensor error models and faults."""

from rig.compiled import install as _install_compiled

_install_compiled()  # the hot modules from build/mypyc while they match their sources (rig/compiled.py)
