"""Strapdown navigation: the compiled navigator (:mod:`inscal.nav.strapdown`), streams of
increments and their compensation, alignment on a static base, navigation runs and their errors
against the truth, and the closed forms of static error propagation.

This face re-exports the run-level API (``navigate``, ``align``, ``navigation_errors`` ...); the
numba building blocks are in :mod:`inscal.nav.strapdown`."""

from inscal.nav.accuracy import (
    DAY,
    NavErrors,
    fit_oscillation,
    foucault_frequency,
    navigation_errors,
    oscillation_components,
    schuler_frequency,
    summarize,
)
from inscal.nav.align import AlignConfig, AlignResult, align, coarse_align
from inscal.nav.linear_model import (
    accel_bias_closed_form,
    gyro_bias_closed_form,
    linear_error_model,
)
from inscal.nav.run import HeightReference, NavResult, navigate, samples_needed, too_short, write_nav
from inscal.nav.stream import (
    SampleStream,
    ThermalCompensation,
    chunks_of,
    compensated_chunks,
    thermal_chunks,
)

__all__ = ['SampleStream', 'ThermalCompensation', 'chunks_of', 'compensated_chunks', 'thermal_chunks', 'AlignConfig', 'AlignResult', 'coarse_align', 'align', 'DAY', 'NavErrors', 'navigation_errors', 'schuler_frequency', 'foucault_frequency', 'fit_oscillation', 'oscillation_components', 'summarize', 'HeightReference', 'NavResult', 'navigate', 'samples_needed', 'too_short', 'write_nav', 'linear_error_model', 'gyro_bias_closed_form', 'accel_bias_closed_form']
