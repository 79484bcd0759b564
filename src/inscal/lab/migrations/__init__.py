"""The Alembic migrations of the calibration database (run by :mod:`inscal.lab.database`; no
``alembic.ini`` needed): ``env.py`` and one module per revision in ``versions/``."""
