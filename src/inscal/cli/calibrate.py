"""``inscal calibrate``: estimate IMU and gimbal errors from a turntable record, or IMU errors from a
hand-held one (``multi-position``, ``ferraris``).  The options are one :class:`~inscal.cli.calibrate_setup.
CalibrateOptions`; the outputs are written by :mod:`inscal.cli.calibrate_outputs`."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from inscal.cli.calibrate_outputs import open_lab, recorded, write_outputs
from inscal.cli.calibrate_setup import (
    AcceptUnconvergedOption,
    AlphaOption,
    CalibrateOptions,
    ChamberLabelOption,
    FaceTiltOption,
    GravityTolOption,
    McSeedOption,
    MinTurnEndOption,
    PerPlateauOption,
    PlateauTolOption,
    PlotsOption,
    SetupOptions,
    QuadraticOption,
    STATION_HELP,
    TRefOption,
    TemperatureSensorOption,
    ThermalModelOption,
    ThermalOrderOption,
    TremorDpsOption,
    TurnClosureOption,
    TurnTolOption,
    budget_thermal_model,
    method_options,
    parse_orders,
    station_description,
)
from inscal.cli.common import CliError, call, check_not_input, check_output, print_json, read_record
from inscal.cli.guards import check_outputs
from inscal.cli.limits import check_mc_trials
from inscal.cli.options import (
    DateOption,
    DbOption,
    ForceOption,
    JsonOption,
    McOption,
    McWorkersOption,
    OperatorOption,
    SerialOption,
    SupersedesOption,
    TemperatureCOption,
    WaitOption,
    method_option,
    options_of,
    out_option,
    with_options,
    station_option,
)

def run_calibrate(o: CalibrateOptions) -> dict:
    """Calibrate ``o.data`` with ``o.method`` and write ``o.out`` (the options: :class:`CalibrateOptions`);
    returns the JSON report.  Nothing is written unless the calibration succeeds; the GUM budget of a
    ``--station FILE.toml`` is :func:`_budget`."""
    from inscal.io.files import input_problem

    setup = o.calibration_setup(o.method, None if o.noise is None else str(o.noise), per_plateau=o.per_plateau,
                                thermal_orders=parse_orders(o.thermal_order), t_ref=o.t_ref,
                                plateau_tol=o.plateau_tol, temperature_sensor=o.temperature_sensor,
                                chamber_label=o.chamber_label, accept_unconverged=o.accept_unconverged,
                                quadratic=o.quadratic, method_options=o.method_options, tremor=o.tremor_dps)
    if (msg := setup.problem(o.plots is not None)) is not None:
        raise CliError(msg)
    if (msg := input_problem(o.data, "data file")) is not None:
        raise CliError(msg)
    check_outputs([("--out", o.out), ("--plots", o.plots)], [o.data, o.thermal_model], o.db, o.serial is not None)
    check_output(o.out, o.force)
    check_not_input(o.out, o.data)
    if o.plots is not None and (o.plots.exists() and not o.plots.is_dir() or not o.plots.parent.is_dir()):
        raise CliError(f"--plots {o.plots}: not a folder, nor one that can be created here")
    desc = station_description(o.station, o.method)
    thermal = budget_thermal_model(o.thermal_model, desc, o.temperature_c if o.serial is None else None)
    if o.mc is not None and desc is None:
        raise CliError("--mc is the Monte Carlo of the uncertainty budget: give --station FILE.toml")
    check_mc_trials(o.mc)
    if o.mc is not None:
        from inscal.uncertainty.sensitivity import WINDOW_METHODS

        if o.method not in WINDOW_METHODS:
            raise CliError(f"--mc: the Monte Carlo of the budget runs the window-mean methods "
                           f"({', '.join(WINDOW_METHODS)}), not {o.method}: the site and clock enter a filter "
                           "linearly, and a thousand filter runs would take hours")
    budget_opts = None if desc is None else {"station": desc, "thermal": thermal, "temperature_c": o.temperature_c,
                                             "mc": o.mc, "mc_seed": o.mc_seed, "mc_workers": o.mc_workers}
    station = o.station if desc is None else desc.name  # the session's station: the description's name
    session = desc is None or o.serial is not None  # the station and temperature are the session's
    lab_db = open_lab(o.db, o.serial, station if session else None, o.operator, o.date,
                      o.temperature_c if session else None, o.supersedes, o.data, setup.options(), o.wait)
    if lab_db is None:
        return _calibrate(o.data, setup, o.out, o.force, o.plots, lab_db, budget_opts)
    try:
        return _calibrate(o.data, setup, o.out, o.force, o.plots, lab_db, budget_opts)
    finally:  # committed with the files when the command's output unit publishes them, else rolled back
        from inscal.io.files import after_unit

        after_unit(lambda: (lab_db["staged"].close() if "staged" in lab_db else None, lab_db["db"].close()))


def _calibrate(data: Path, setup, out: Path, force: bool, plots, lab_db: dict | None, budget_opts=None) -> dict:
    """The calibration of :func:`run_calibrate` once its options are checked (the record's own part:
    :func:`inscal.runs.calibration.calibrate_record`, which a batch of calibrations runs too); ``budget_opts``:
    the station description and what :func:`_budget` takes with it (None: no budget)."""
    from inscal import io
    from inscal.cli.common import short
    from inscal.cli.limits import check_memory
    from inscal.io.files import output_unit
    from inscal.runs.calibration import RecordError, calibrate_record

    # the size first, before the record is read: the record in memory, then the filter's per-step stores
    try:
        info = io.record_info(data)
    except (io.DataFileError, OSError, KeyError, TypeError, ValueError):
        info = None  # read_record names what is wrong with the file
    if info is not None:
        for need, what, hint in setup.memory_needs(info, short(data, 60)):
            check_memory(need, what, hint)
    try:
        rec = read_record(data)
    except OSError as exc:
        raise CliError(str(exc)) from None
    if budget_opts is not None:  # a station of another site: refused before the calibration runs
        from inscal.uncertainty.station import StationError, site_check

        try:
            site_check(budget_opts["station"], rec.site.latitude, rec.site.height, None)
        except StationError as exc:
            raise CliError(f"--station: {exc}") from None
    try:
        cal = calibrate_record(rec, data, setup)
    except RecordError as exc:
        raise CliError(str(exc)) from None
    res, rec, meta, enc_report, systematic = cal.result, cal.record, cal.metadata, cal.encoders, setup.systematic
    budget = None if budget_opts is None else _budget(res, budget_opts["station"], lab_db, rec, setup,
                                                      budget_opts["temperature_c"], budget_opts["thermal"],
                                                      budget_opts)
    try:
        with output_unit() as unit:  # the parameter file, the plots and the database row: all together, or none
            if lab_db is not None:
                lab_db["unit"] = unit
            report = write_outputs(data, out, force, plots, res, rec, meta, enc_report, systematic, lab_db)
            if budget is not None:
                report["budget"] = budget
        if lab_db is not None:
            report["db"] = recorded(lab_db)
    except FileExistsError as exc:  # a file that appeared at an output while this ran is not replaced
        rid = (lab_db or {}).get("result_id")
        if rid is not None:  # the database had committed: its copy of the file is whole
            raise CliError(f"{exc}; the result is recorded in {lab_db['db'].where} as result {rid} (inscal db export "
                           f"{lab_db['serial']} --result {rid} --out FILE writes its parameter file)") from None
        raise CliError(str(exc)) from None
    return report



def _budget(res, station, lab_db: dict | None, rec, setup, temperature_c: float | None = None, thermal=None,
            mc: dict | None = None) -> dict:
    """The uncertainty budget of ``res`` at ``station`` (:func:`inscal.uncertainty.session.session_budget`: with the
    unit's repeatability and newest thermal model when ``lab_db`` is given, the chamber's temperature through
    ``thermal``, and the JCGM 101 Monte Carlo of ``mc``); kept in ``lab_db`` to be stored with the result."""
    from inscal.uncertainty.session import BudgetError, session_budget

    mc = mc or {}
    try:
        sb = session_budget(res, station, rec, setup, db=None if lab_db is None else lab_db["db"],
                            serial=None if lab_db is None else lab_db["serial"], temperature_c=temperature_c,
                            thermal=thermal, mc=mc.get("mc"), mc_seed=mc.get("mc_seed", 0),
                            mc_workers=mc.get("mc_workers", 1))
    except BudgetError as exc:
        raise CliError(f"--mc: {exc}" if exc.part == "monte_carlo" else f"--station: no uncertainty budget: {exc}") \
            from None
    if lab_db is not None:
        lab_db["budget"] = sb.stored()
    return sb.document


def register(app: typer.Typer) -> None:
    @app.command()
    @with_options(SetupOptions, before="quadratic")
    def calibrate(
        data: Annotated[Path, typer.Argument(help="HDF5 record (inscal simulate, or a recorded run)")],
        method: method_option(),
        out: out_option("parameter file to write (TOML)"),
        force: ForceOption = False,
        quadratic: QuadraticOption = False,
        # the no-turntable methods' options (None: the method's own default)
        alpha: AlphaOption = None,
        gravity_tol: GravityTolOption = None,
        face_tilt: FaceTiltOption = None,
        min_turn_end: MinTurnEndOption = None,
        turn_tol: TurnTolOption = None,
        turn_closure: TurnClosureOption = None,
        tremor_dps: TremorDpsOption = None,
        plots: PlotsOption = None,
        serial: SerialOption = None,
        db: DbOption = None,
        station: station_option(STATION_HELP) = None,
        operator: OperatorOption = None,
        date: DateOption = None,
        temperature_c: TemperatureCOption = None,
        supersedes: SupersedesOption = None,
        per_plateau: PerPlateauOption = None,
        thermal_order: ThermalOrderOption = None,
        t_ref: TRefOption = None,
        plateau_tol: PlateauTolOption = 0.5,
        temperature_sensor: TemperatureSensorOption = "",
        chamber_label: ChamberLabelOption = "chamber",
        wait: WaitOption = None,
        accept_unconverged: AcceptUnconvergedOption = False,
        mc: McOption = None,
        mc_seed: McSeedOption = 0,
        mc_workers: McWorkersOption = 1,
        thermal_model: ThermalModelOption = None,
        json_: JsonOption = False,
        **setup,
    ):
        """Calibrate IMU errors (and gimbal non-orthogonality / mounting attitude) from a record."""
        opts = options_of(CalibrateOptions, locals() | setup, thermal_order=tuple(thermal_order or ()) or None,
                          method_options=method_options(alpha, gravity_tol, face_tilt, min_turn_end, turn_tol,
                                                        turn_closure))
        rep = call(run_calibrate, opts)
        if json_:
            print_json({k: v for k, v in rep.items() if k not in ("out", "notes")} | {"notes": rep["notes"]})
            return
        from inscal.report.text import calibration_lines

        for line in calibration_lines(rep):
            typer.echo(line)
