"""The options of ``inscal calibrate``: those of calibrate alone (the shared ones are :mod:`inscal.cli.options`),
all of them as one object (:class:`CalibrateOptions`), and their checks before the calibration runs: the
station description of the budget, its thermal model, the thermal orders, the no-turntable methods' options
in their functions' units (the database that ``--serial`` records in: :mod:`inscal.cli.calibrate_outputs`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import typer

from inscal.cli.common import CliError
from inscal.cli.options import (
    CalibrationNoiseOption,
    EncoderLatencyOption,
    EncoderSigmaOption,
    FilterRateOption,
    MinStaticOption,
    SettleOption,
    SkipEncoderCheckOption,
    arw_option,
    gravity_option,
    option,
    states_option,
    vrw_option,
)

# ----------------------------------------------------------------------------- the options of calibrate alone
STATES_HELP = ("systematic: auto (the default: async, lever9, g-sensitivity off-diagonals and cross-coupling chosen "
               "by F-tests on the innovations) | 51 | 30, plus options lever9, async, psins, gimbal, gdiag, nocross, "
               "auto (e.g. 51,lever9 or auto,psins), and thermal: the thermal coefficients as states, the record's "
               "/temperature a known input, T_ref 20 degC (thermal: orders 2,2,3,2 and the dT/dt term; "
               "thermal=GSABR: orders of gyro bias, gyro scale factor, accel bias, accel scale factor 0-3 and the "
               "dT/dt term 0-1, e.g. 51,thermal=11110); unified: extra options (e.g. lever9, auto)")
STATION_HELP = ("the turntable / station of the run: its name (with --serial), or a station description FILE.toml "
                "(n25, six-position, twelve-position, joint, systematic51, systematic30, multi-position, ferraris): "
                "the GUM uncertainty budget is computed, printed and, with --serial, stored with the result")


StatesOption = states_option(STATES_HELP)
ArwOption = arw_option("from the data")
VrwOption = vrw_option("from the data")
GravityOption = gravity_option("the record's")


QuadraticOption = Annotated[bool, typer.Option("--quadratic", help=(
    "multi-position: estimate the quadratic accelerometer terms too (12 parameters: at least 12 poses, and "
    "more for the fit to have accelerometer degrees of freedom)"))]
AlphaOption = option(
    "--alpha", "multi-position, ferraris: false-alarm probability of the still-pose tests "
    "(default 1e-3; ferraris 1e-4)", metavar="P")
GravityTolOption = option(
    "--gravity-tol", "multi-position, ferraris: the largest relative difference between "
    "the poses' specific force and the site's gravity (default 0.15; ferraris 0.1)",
    metavar="RATIO")
FaceTiltOption = option(
    "--face-tilt-deg", "ferraris: rms angle in deg between a face and the horizontal when "
    "it rests on a table (flatness, squareness, the table's level; in the sigma) (default "
    "0.3; 0: exact faces)")
MinTurnEndOption = option(
    "--min-turn-end-s", "ferraris: shortest still pose in s at the ends of a turn, after "
    "--settle-s at both ends (default 0.3)")
TurnTolOption = option(
    "--turn-tol-deg", "ferraris: how far from 360 deg a whole turn may be, in deg "
    "(default 30)")
TurnClosureOption = option(
    "--turn-closure-deg", "ferraris: rms difference in deg between a whole turn's angle "
    "and 360 deg (a turn by hand against a stop; in the sigma) (default 0.2; 0: exact "
    "turns)")
TremorDpsOption = option(
    "--tremor-dps", "multi-position: the hand tremor a still pose may hold [deg/s rms] "
    "(default 3; the accelerometers judge a pose, the gyros may tremble up to this)")
PlotsOption = option(
    "--plots", "systematic: folder for the convergence plots (PNG)", Path, "FOLDER")
PerPlateauOption = option(
    "--per-plateau", "thermal-plateaus: the method run on each temperature plateau "
    "(default n25; any other method)", str, "METHOD")
ThermalOrderOption = option(
    "--thermal-order", "thermal-plateaus: NAME=ORDER, the polynomial order of a "
    "thermal term in T - T_ref (repeatable; default gyro_bias, gyro_scale_factor, "
    "accel_bias, accel_scale_factor = 2, misalignments 0 = constant, at most 1; an order "
    "not named is raised while its fit misfits the plateaus)", list[str],
    "NAME=ORDER")
TRefOption = option(
    "--t-ref", "thermal-plateaus: reference temperature of the model [deg C] (default 20; "
    "inside the plateaus' range)", metavar="DEGC")
PlateauTolOption = Annotated[float, typer.Option("--plateau-tol", metavar="DEGC", help=(
    "thermal-plateaus: a plateau's readings stay within this of their mean [deg C]"))]
TemperatureSensorOption = Annotated[str, typer.Option("--temperature-sensor", metavar="SENSOR", help=(
    "thermal-plateaus: the temperature sensor (default: the mean of the record's sensors)"))]
ChamberLabelOption = Annotated[str, typer.Option("--chamber-label", metavar="LABEL", help=(
    "thermal-plateaus: label prefix of the path's chamber transitions (the plateaus are cut there; without "
    "them they are found in the temperature)"))]
AcceptUnconvergedOption = Annotated[bool, typer.Option("--accept-unconverged", help=(
    "systematic: keep the last iterate of a run that does not converge (a note in the text, the JSON and "
    "the parameter file) instead of ending with exit 2"))]
McSeedOption = Annotated[int, typer.Option("--mc-seed", metavar="SEED", help="seed of the Monte Carlo")]
ThermalModelOption = option(
    "--thermal-model", "with --station FILE.toml: a parameter file with a thermal model "
    "([thermal], from thermal-plateaus or thermal states) whose slope dy/dT propagates the "
    "chamber's temperature stability (default: the unit's newest result in the database "
    "that has one)", Path, "PARAMS.toml")


@dataclass(frozen=True, kw_only=True)
class SetupOptions:
    """The options of a calibration that ``inscal calibrate`` and ``inscal batch`` share (None: the method's own
    default), each declared once here as its command-line option (:func:`inscal.cli.options.with_options` gives
    both commands these parameters), as the library's :class:`~inscal.runs.calibration.CalibrationSetup` takes
    them (:meth:`calibration_setup`)."""

    settle: SettleOption = None
    min_static: MinStaticOption = None
    states: StatesOption = None
    filter_rate: FilterRateOption = 1.0
    arw: ArwOption = None
    vrw: VrwOption = None
    gravity: GravityOption = None
    encoder_sigma: EncoderSigmaOption = None
    encoder_latency: EncoderLatencyOption = 0.0
    skip_encoder_check: SkipEncoderCheckOption = False
    noise: CalibrationNoiseOption = None

    def calibration_setup(self, method: str, noise: str | None, **more):
        """The library's setup (:class:`~inscal.runs.calibration.CalibrationSetup`) of ``method`` with these
        options, the noise model ``noise`` (a path) and ``more`` of the setup's fields."""
        from inscal.runs.calibration import CalibrationSetup  # numpy and the methods: on first use (fast start)

        return CalibrationSetup(method, self.states, self.settle, self.min_static, self.filter_rate, self.arw, self.vrw,
                                self.gravity, self.encoder_sigma, self.encoder_latency, not self.skip_encoder_check,
                                noise=noise, **more)


@dataclass(frozen=True)
class CalibrateOptions(SetupOptions):
    """Everything ``inscal calibrate`` is asked: calibrate ``data`` with ``method`` and write ``out``.

    ``states``/``plots``/``filter_rate``/``arw`` [deg/sqrt(h)]/``vrw`` [ug/sqrt(Hz)] apply to the systematic
    methods.  ``gravity`` (wgs84 | psins | m/s^2) overrides the record's gravity model.  ``encoder_sigma``
    [arcsec]: white noise of each encoder angle for the gimbal states (method ``unified``, or ``--states
    ...,gimbal``).  A record with encoder angles has them compared with the gyros first
    (:mod:`inscal.io.encoders`): a unit, sign, column or time-offset error stops the calibration with one line
    unless ``skip_encoder_check``; ``encoder_latency`` [s] shifts the angles before (encoders that lag: > 0).
    ``serial``: record the result in the calibration database ``db`` (:mod:`inscal.lab`; None: ``INSCAL_DB``,
    else calib.sqlite) as a calibration of that unit, with the session's ``station``, ``operator``, ``date`` and
    ``temperature_c``, committed together with the parameter file (a failure of either leaves neither);
    ``supersedes``: the id of an earlier result this one replaces; ``wait`` [s] for another writer.
    Method ``thermal-plateaus``: ``per_plateau`` (default n25) runs on each temperature plateau, then the
    thermal model is fitted with ``thermal_order`` (``("gyro_bias=2", ...)``), ``t_ref`` [degC] (default 20),
    ``plateau_tol`` [degC], ``temperature_sensor`` and ``chamber_label`` (:mod:`inscal.calibrate.thermal`).
    ``accept_unconverged``: a systematic run that does not converge keeps its last iterate, with a note,
    instead of ending with one line (:class:`inscal.calibrate.systematic.driver.NotConverged`).
    ``settle``, ``min_static`` [s]: None, the method's own default (:class:`~inscal.runs.calibration.CalibrationSetup`);
    ``quadratic``: ``multi-position`` estimates the quadratic accelerometer terms too; ``method_options``: the
    no-turntable method's keyword options given (:func:`method_options`); ``tremor_dps``: the hand tremor a
    still pose may hold [deg/s rms] (multi-position; None: its default).  ``noise``: a noise.toml (``inscal
    noise --out``) whose white terms weight the systematic filter and whose Gauss-Markov terms become bias
    states (:mod:`inscal.calibrate.systematic.gm_states`).  ``station`` a description FILE.toml: the GUM budget;
    its chamber temperature stability goes through ``thermal_model`` (a parameter file with a ``[thermal]``
    table) or else the unit's newest thermal result in the database, at ``temperature_c`` (allowed without
    ``serial`` then) or the record's mean temperature; ``mc`` trials at most of the budget's JCGM 101 Monte
    Carlo (:mod:`inscal.cli.budget_mc`; seed ``mc_seed``, ``mc_workers`` Dask workers).
    """

    data: Path
    method: str
    out: Path
    force: bool = False
    plots: Path | None = None
    db: str | None = None
    serial: str | None = None
    station: str | None = None
    operator: str | None = None
    date: str | None = None
    temperature_c: float | None = None
    supersedes: int | None = None
    per_plateau: str | None = None
    thermal_order: tuple[str, ...] | None = None
    t_ref: float | None = None
    plateau_tol: float = 0.5
    temperature_sensor: str = ""
    chamber_label: str = "chamber"
    wait: float | None = None
    accept_unconverged: bool = False
    quadratic: bool = False
    thermal_model: Path | None = None
    mc: int | None = None
    mc_seed: int = 0
    mc_workers: int = 1
    method_options: tuple[tuple[str, float], ...] = ()
    tremor_dps: float | None = None


def station_description(station: str | None, method: str):
    """The station description of ``--station FILE.toml`` (:mod:`inscal.uncertainty.station`), None for a station's
    name; refused with one line when it cannot be read or the method has no budget."""
    if station is None or not station.lower().endswith(".toml"):
        return None
    from inscal.uncertainty.sensitivity import BUDGET_METHODS
    from inscal.uncertainty.station import StationError, read_station

    if method not in BUDGET_METHODS:
        raise CliError(f"--station {station}: an uncertainty budget needs one of the methods "
                       f"{', '.join(BUDGET_METHODS)}, not {method}")
    try:
        return read_station(station)
    except StationError as exc:
        raise CliError(str(exc)) from None


def budget_thermal_model(path: Path | None, desc, temperature_c: float | None):
    """``(path, ThermalModel)`` of ``--thermal-model PARAMS.toml`` (None without it), read before the calibration
    runs: refused with one line when there is no budget, the file cannot be read or carries no thermal model.
    ``temperature_c``: a ``--temperature-c`` given without ``--serial`` (the budget's stated temperature), checked."""
    if desc is None:
        if path is not None:
            raise CliError(f"--thermal-model {path}: it serves the uncertainty budget: give --station FILE.toml")
        return None
    if temperature_c is not None and not (math.isfinite(temperature_c) and -100.0 < temperature_c < 200.0):
        raise CliError(f"--temperature-c {temperature_c}: not an IMU temperature in deg C")
    if path is None:
        return None
    from inscal.io.paramfile import ParamFileError, load_params

    try:
        meta = load_params(path)[2]
    except ParamFileError as exc:
        raise CliError(f"--thermal-model: {exc}") from None
    model = meta.get("thermal")
    if model is None or model.is_zero:
        raise CliError(f"--thermal-model {path}: the parameter file has no thermal model (no [thermal] table with "
                       "coefficients; --method thermal-plateaus or --states ...,thermal write one)")
    return path, model


def parse_orders(items: list[str] | None) -> tuple[tuple[str, int], ...]:
    """``--thermal-order NAME=K`` (repeatable; NAME a thermal term, K its polynomial order) as pairs."""
    out = []
    for item in items or []:
        name, sep, k = str(item).partition("=")
        try:
            order = int(k)
        except ValueError:
            order = None
        if not sep or not name.strip() or order is None:
            raise CliError(f"--thermal-order {item!r}: expected NAME=ORDER, e.g. gyro_bias=2 (NAME a thermal term, "
                           "ORDER 0 .. 3; 0: constant)")
        out.append((name.strip(), order))
    return tuple(out)



def method_options(alpha, gravity_tol, face_tilt, min_turn_end, turn_tol, turn_closure) -> tuple:
    """The no-turntable options given on the command line, in the method function's units, as sorted
    ``(name, value)`` pairs (:data:`~inscal.runs.calibration.NO_TABLE_OPTIONS`; ``face_tilt``, ``turn_closure``
    in rad)."""
    from inscal.core import units

    given = {"alpha": alpha, "gravity_tol": gravity_tol, "min_turn_end": min_turn_end, "turn_tol_deg": turn_tol,
             "face_tilt": None if face_tilt is None else units.to_si(face_tilt, "deg"),
             "turn_closure": None if turn_closure is None else units.to_si(turn_closure, "deg")}
    return tuple(sorted((k, float(v)) for k, v in given.items() if v is not None))
