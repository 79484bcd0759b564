"""inscal: calibration of high-accuracy IMUs and dual-axis rotational INS (S16: systematic
calibration, Sensors 2016; N25: gimbal non-orthogonality self-calibration, NAVIGATION 2025).

Conventions, used by every module without re-explaining them:

- Units: SI inside (rad, rad/s, m/s^2, m, s); the field's units (ppm, arcsec, deg/h, ug, ug/g^2,
  deg/h/g, cm) only in files, reports and the command line, converted in :mod:`inscal.core.units`.
- Frames: n = East-North-Up navigation frame; s = the IMU frame of N25 (z = inner gimbal axis,
  x = projection of the outer axis at zero angle); b = the base of the turntable.
- ``C_a_b`` / ``C_a^b`` maps a-frame vectors into b; elementary rotations are active (right-handed);
  Euler angles ``[roll, pitch, yaw]`` with ``C_b^n = R_z(yaw) R_y(pitch) R_x(roll)`` (N25 eq. 8).
- Errors are reported as estimate minus truth.

Layers (each imports only from those below it; ``lint-imports`` checks it): ``core`` < ``io`` <
``sim`` | ``nav`` < ``calibrate`` < ``plan`` | ``analysis`` | ``lab`` < ``uncertainty`` < ``report`` <
``runs`` < ``cli``.  ``lab`` is the calibration database (schema, store, journal, drift); ``uncertainty`` the
GUM budget (station, sensitivities, combination, the JCGM 101 Monte Carlo on the Monte Carlo engine of
``analysis``, the budget before the run and of a calibration run); ``runs`` runs calibrations into the
database (one record, a batch).  ``lab`` and ``runs`` import neither ``sim`` nor ``nav``, and ``calibrate``
neither ``io`` nor ``sim``.  One home per idea: attitude (quaternions, DCMs, rotation vectors; NumPy and
scalar/array numba faces) in :mod:`inscal.core.attitude`, the Kalman steps in :mod:`inscal.core.kalman`, units
in :mod:`inscal.core.units`, the budget's distributions in :mod:`inscal.uncertainty.distributions`.
"""

__version__ = "0.1.0"
#: Version of the HDF5 record layout (:mod:`inscal.io.records`), the navigation output and the
#: scenario and design TOML files.  Parameter files have their own
#: (:data:`inscal.io.paramfile.PARAM_SCHEMA_VERSION`), as have Monte Carlo run files
#: (:data:`inscal.analysis.montecarlo.SCHEMA_VERSION`).
SCHEMA_VERSION = 1
