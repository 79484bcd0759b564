"""Running calibrations into the calibration database (:mod:`inscal.lab`): the layer that composes the estimators
(:mod:`inscal.calibrate`), the record files (:mod:`inscal.io`) and the database into one calibration run, as a
command does it without its parsing.

- :mod:`inscal.runs.calibration`: one record, exactly as ``inscal calibrate`` runs it (the options that decide the
  result, :class:`~inscal.runs.calibration.CalibrationSetup`; :func:`~inscal.runs.calibration.calibrate_record`);
- :mod:`inscal.runs.batch`: many records with one method on Dask or in this process, resumable
  (``inscal batch``, :func:`~inscal.runs.batch.run_batch`).

Its modules load the estimators (numba, SciPy) and, for a batch, SQLAlchemy: import the one you need.
"""
