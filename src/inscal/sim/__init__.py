"""The simulator of the turntable and the IMU (:mod:`~inscal.sim.simulate`) and the built-in and TOML
scenarios (:mod:`~inscal.sim.scenarios`, with the S16 Table 2 figures)."""
