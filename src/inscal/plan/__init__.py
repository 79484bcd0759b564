"""Planning a calibration without data: the Cramér-Rao bound of a path (:mod:`~inscal.plan.bound`),
the observability of its states (:mod:`~inscal.plan.observability`) and path design (:mod:`~inscal.plan.design`)."""
