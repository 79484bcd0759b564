"""One calibration of one record, exactly as ``inscal calibrate`` runs it: the options that decide
the result (:class:`CalibrationSetup`, checked up front), the memory the record asks for, the
check of its encoder angles against the gyros (:mod:`inscal.io.encoders`), the gravity model, the
estimator and the parameter file's metadata.  ``inscal calibrate`` and a batch of calibrations
(:mod:`inscal.lab.batch`) both call :func:`calibrate_record`, so the same record with the same
options gives the same parameter file (:func:`inscal.lab.record.param_file_text`) either way.

This module loads the estimators (numba, SciPy): it is imported on its own, not by ``inscal.lab``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inscal.calibrate import METHODS, RECORD_METHODS, calibrate
from inscal.calibrate.systematic.driver import samples_per_step, systematic_bytes
from inscal.calibrate.systematic.selection import largest_states
from inscal.calibrate.windows import CalibrationError
from inscal.core import units
from inscal.core.earth import parse_gravity
from inscal.io.encoders import apply_latency, check_record_encoders
from inscal.io.records import (
    DataFileError,
    Record,
    RecordInfo,
    read_record,
    record_attrs,
)
from inscal.lab.record import calibration_options


class RecordError(ValueError):
    """A calibration option refused, or a record that cannot be calibrated with the options: one line."""


@dataclass(frozen=True)
class CalibrationSetup:
    """The options of a calibration, as ``inscal calibrate`` takes them (field units: ``arw``
    deg/sqrt(h), ``vrw`` ug/sqrt(Hz), ``encoder_sigma`` arcsec; times in s): ``states``, ``arw``,
    ``vrw``, ``encoder_sigma`` and ``filter_rate_hz`` apply to the systematic methods, ``settle`` and
    ``min_static`` to the window-mean ones; ``gravity`` (wgs84 | psins | m/s^2) overrides the
    record's gravity model; ``encoder_latency`` shifts the encoder angles [s]; ``check_encoders``
    compares them with the gyros before calibrating."""

    method: str
    states: str | None = None
    settle: float = 1.0
    min_static: float = 20.0
    filter_rate_hz: float = 1.0
    arw: float | None = None
    vrw: float | None = None
    gravity: str | None = None
    encoder_sigma: float | None = None
    encoder_latency: float = 0.0
    check_encoders: bool = True

    @property
    def systematic(self) -> bool:
        """Whether the method reads the record itself (the systematic filter and ``unified``)."""
        return self.method in RECORD_METHODS

    def problem(self, plots: bool = False) -> str | None:
        """The one-line refusal of a bad option (``plots``: convergence plots are asked for), None if
        the options are usable; checked before any record is read."""
        if self.method not in METHODS:
            return f"unknown method {self.method!r}; choose one of: {', '.join(METHODS)}"
        if not self.systematic and (self.states or plots or self.arw is not None or self.vrw is not None
                                    or self.encoder_sigma is not None):
            return f"--states, --plots, --arw, --vrw and --encoder-sigma apply to the systematic methods, not {self.method}"
        for name, v in (("--arw", self.arw), ("--vrw", self.vrw)):
            if v is not None and not (math.isfinite(v) and v > 0):
                return (f"{name} must be a white-noise level > 0 ({'deg/sqrt(h)' if name == '--arw' else 'ug/sqrt(Hz)'}), "
                        f"got {v}")
        if not (math.isfinite(self.filter_rate_hz) and self.filter_rate_hz > 0):
            return f"--filter-rate-hz must be > 0, got {self.filter_rate_hz}"
        if self.encoder_sigma is not None and not (np.isfinite(self.encoder_sigma) and self.encoder_sigma > 0):
            return f"--encoder-sigma must be > 0 arcsec, got {self.encoder_sigma}"
        if not math.isfinite(self.encoder_latency) or abs(self.encoder_latency) > 1.0:
            return f"--encoder-latency must be a finite shift of at most 1 s, got {self.encoder_latency}"
        if self.gravity is not None:
            try:
                parse_gravity(self.gravity)
            except ValueError as exc:
                return f"--gravity: {exc}"
        return None

    def options(self) -> dict:
        """The canonical options (:func:`inscal.lab.record.calibration_options`): what identifies "the
        same calibration of the same record" in the database."""
        return calibration_options(self.method, states=self.states, settle=self.settle, min_static=self.min_static,
                                   filter_rate_hz=self.filter_rate_hz, arw=self.arw, vrw=self.vrw, gravity=self.gravity,
                                   encoder_sigma=self.encoder_sigma, encoder_latency=self.encoder_latency,
                                   check_encoders=self.check_encoders)

    def memory_needs(self, info: RecordInfo, name: str) -> list[tuple[float, str, str]]:
        """What calibrating the record of ``info`` (called ``name`` in the messages) holds in memory at
        its peaks, ``[(bytes, what, hint)]``: the record read, then the systematic filter's per-step stores."""
        if not (math.isfinite(info.rate_hz) and info.rate_hz > 0):
            return []
        n, rate = info.n_samples, info.rate_hz
        what = f"{name} ({n} samples, {n / rate:.4g} s at {rate:g} Hz)"
        # float64 time, increments and encoder angles, and at the peak a working copy's worth (measured: 104 B
        # per sample in the encoder check, 80 B in the window means; the systematic driver's own below)
        held = 8.0 * (7 + (2 if info.has_gimbal else 0)) * n
        out = [(held + 104.0 * n, f"reading {what}", "calibrate a shorter record")]
        try:
            st = largest_states({"systematic30": "30", "unified": "unified"}.get(self.method, "51"), self.states) \
                if self.systematic else None
        except CalibrationError:
            st = None  # the calibration names the bad state set
        if st is not None:
            steps = n // samples_per_step(rate, self.filter_rate_hz)
            out.append((held + systematic_bytes(n, rate, st, self.filter_rate_hz),
                        (f"the {st.n_states}-state filter's {steps} steps at --filter-rate-hz {self.filter_rate_hz:g} "
                         f"over {what}"),
                        ("lower --filter-rate-hz (the default 1 Hz suits a turntable record) or calibrate a shorter "
                         "record")))
        return out


@dataclass(frozen=True)
class Calibrated:
    """A record calibrated: the :class:`~inscal.calibrate.CalibrationResult`, the record as calibrated
    (its site with the gravity model used), the parameter file's ``metadata`` and the encoder check's
    summary (None without encoder angles or without the check)."""

    result: object
    record: Record
    metadata: dict
    encoders: dict | None


def load_record(path: Path) -> Record:
    """The record of ``path`` in memory; a file that is not a valid record raises :class:`RecordError`
    (or :class:`~inscal.io.records.DataFileError`) in one line."""
    try:
        rec = read_record(path)
    except DataFileError:
        raise
    except (KeyError, TypeError, ValueError) as exc:
        raise RecordError(f"{path}: not a valid inscal record ({type(exc).__name__}: {exc})") from None
    bad = [n for n in ("dtheta", "dvel") if not np.issubdtype(np.asarray(getattr(rec, n)).dtype, np.floating)]
    if bad:
        raise RecordError(f"{path}: {', '.join(bad)} must be floating point (rad, m/s), got "
                          f"{np.asarray(getattr(rec, bad[0])).dtype}")
    return rec


def calibrate_record(rec: Record, data: Path, setup: CalibrationSetup) -> Calibrated:
    """Calibrate record ``rec`` (read from file ``data``) with ``setup`` (checked with
    :meth:`CalibrationSetup.problem`): the encoder latency and check, the gravity model, the estimator
    and the parameter file's metadata.  Raises :class:`RecordError` in one line."""
    enc_report = None
    if rec.gimbal is not None:
        if setup.encoder_latency:
            rec = dataclasses.replace(rec, gimbal=apply_latency(np.asarray(rec.time), np.asarray(rec.gimbal),
                                                                setup.encoder_latency))
        if setup.check_encoders:
            chk = check_record_encoders(rec)
            if not chk.ok:
                raise RecordError(f"{data}: {chk.message} (--skip-encoder-check to calibrate anyway)")
            enc_report = chk.summary() | {"latency_applied_s": setup.encoder_latency}
    elif setup.encoder_latency:
        raise RecordError(f"--encoder-latency: {data} has no encoder angles")
    if setup.gravity is not None:
        try:
            rec = dataclasses.replace(rec, site=rec.site.with_gravity(parse_gravity(setup.gravity)))
        except ValueError as exc:
            raise RecordError(f"--gravity: {exc}") from None
    try:
        if setup.systematic:
            # the state set: chosen from the data unless given (inscal.calibrate.systematic.selection)
            opts = {"states": "auto" if setup.states is None else setup.states, "filter_rate_hz": setup.filter_rate_hz}
            if setup.arw is not None:
                opts["arw"] = units.to_si(setup.arw, "deg/sqrt(h)")
            if setup.vrw is not None:
                opts["vrw"] = units.to_si(setup.vrw, "ug/sqrt(Hz)")
            if setup.encoder_sigma is not None:
                opts["encoder_sigma"] = units.to_si(setup.encoder_sigma, "arcsec")
            res = calibrate(rec, setup.method, **opts)
        else:
            res = calibrate(rec, setup.method, settle=setup.settle, min_static=setup.min_static)
    except CalibrationError as exc:
        raise RecordError(f"{data}: {exc}") from None
    meta = {"scenario": rec.scenario or None, "imu_serial": record_attrs(data, ("imu_serial",))["imu_serial"],
            "windows": len(res.windows.windows) if res.windows else None}
    if setup.systematic:
        d = res.diagnostics
        meta.update({"frame": d["frame"], "states": d["state_options"], "state_count": d["states"],
                     "filter_rate_hz": d["filter_rate_hz"], "nis_mean": d["innovations"]["nis_mean"],
                     "chi2": d["innovations"]["chi2"], "dof": d["innovations"]["dof"],
                     "p_value": d["innovations"]["p_value"]})
    return Calibrated(res, rec, meta, enc_report)
