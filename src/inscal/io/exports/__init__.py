"""Exports of a calibration into other tools' conventions, one module each (Kalibr, imucal, KF-GINS, C),
each with the convention written out in its docstring."""
