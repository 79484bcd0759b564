"""inscal: calibration of high-accuracy IMUs and dual-axis rotational INS."""

__version__ = "0.1.0"
#: Version of the HDF5 data and TOML parameter file schemas written by this package.
SCHEMA_VERSION = 1
