"""Noise identification of inertial sensor records: the streamed Allan/Haar wavelet variance
(:mod:`.estimators`) and their intervals (:mod:`.intervals`), the GMWM-type fit of a sum of processes
(:mod:`.fit`, its grid of correlation times :mod:`.projection`) and the choice among nested models
(:mod:`.selection`).  The processes themselves, with
their exact variances, are physics: :mod:`inscal.core.noise_models`."""
