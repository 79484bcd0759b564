"""Physics and mathematics, no files: field units (:mod:`~inscal.core.units`), the Earth and the
site (:mod:`~inscal.core.earth`), attitude, the IMU and gimbal error model (:mod:`~inscal.core.error_model`),
the turntable and its rotation paths, the gimbal kinematics (N25 eq. 5-10) and the Kalman core."""
