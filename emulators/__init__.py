"""Byte-accurate device models (MPU-6050, HMC5883L, MS5611), the I2C bus, sensor error models and faults."""
