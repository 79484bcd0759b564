"""Analyses built on the simulator and the calibrations: Monte Carlo studies
(:mod:`inscal.analysis.montecarlo`, built-in experiments in
:mod:`inscal.analysis.studies.common`)."""

from __future__ import annotations



