"""The options that several commands take, declared once (``Annotated`` types for Typer), and the help's
look: every value named by what it is (``PATH``, ``HZ``, ``SECONDS``, ``SEED``, ``N``), flags shown without
a value, and each command's examples (:mod:`inscal.cli.examples`) under its options.

A command declares ``db: DbOption = None`` instead of repeating ``typer.Option(None, "--db", help=...)``;
an option whose help names a command's own default is made by a small function (``arw_option("the
scenario's")``).  :class:`Command` gives every option without a declared metavar one from its name and
type (:func:`metavar_of`), so that no help shows a type name (``<str>``) or a value for a flag.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import typing
from pathlib import Path
from typing import Annotated

import typer
from typer.core import TyperArgument, TyperCommand, TyperGroup

from inscal.cli.applies import check_context
from inscal.cli.common import CliError, fail

DB_HELP = ("calibration database: a file (SQLite) or postgresql://USER@HOST/NAME (default: $INSCAL_DB, else "
           "calib.sqlite)")


def option(name: str, help: str, kind: type = float, metavar: str | None = None) -> object:
    """An option that is None unless given, of type ``kind`` (its metavar from :func:`metavar_of` unless
    ``metavar``): ``cable_wrap: option("--cable-wrap", "largest net rotation of each axis [deg]", metavar="DEG")
    = None`` in a command's options dataclass."""
    return Annotated[kind | None, typer.Option(name, metavar=metavar, help=help)]


# --------------------------------------------------------------------------- shared by many commands
JsonOption = Annotated[bool, typer.Option("--json", help="print the result as JSON (one document on stdout)")]
ForceOption = Annotated[bool, typer.Option("--force", help="overwrite existing outputs")]
DbOption = Annotated[str | None, typer.Option("--db", metavar="DB", help=DB_HELP)]
WaitOption = option("--wait", "seconds to wait for another writer of the database (default: refused after 2 s, naming "
                    "it)", metavar="SECONDS")
SeedOption = Annotated[int, typer.Option("--seed", metavar="SEED", help=(
    "seed of the random draws (>= 0; the same seed gives the same result)"))]
ParamsOption = Annotated[Path | None, typer.Option("--params", "-p", metavar="PARAMS.toml", help=(
    "calibration parameter file (TOML, from inscal calibrate)"))]
SerialOption = option("--serial", "record the result in the calibration database as a calibration of this unit "
                      "(registered with inscal db add)", str, "SERIAL")
OperatorOption = option("--operator", "who ran the calibration", str, "NAME")
DateOption = option("--date", "when the record was taken, YYYY-MM-DD or ISO time (UTC; default: the record's creation "
                    "time)", str, "DATE")
TemperatureCOption = option("--temperature-c", "the IMU's temperature during the run [deg C]", metavar="DEGC")
SupersedesOption = option("--supersedes", "id of an earlier result this one replaces (e.g. the same record calibrated "
                          "again)", int, "RESULT")
ResultOption = option("--result", "this result id (default: the unit's current calibration)", int, "RESULT")
SerialArgument = Annotated[str, typer.Argument(metavar="SERIAL", help="the unit's serial number")]
KOption = Annotated[float, typer.Option("--k", "-k", metavar="K", help=(
    "flag a parameter that moved more than k sigma"))]
TemperatureOption = option("--temperature", "constant temperature in degC for the parameter file's thermal model (a "
                           "record without /temperature; in place of the record's readings otherwise)", metavar="DEGC")
NoProgressOption = Annotated[bool, typer.Option("--no-progress", help="no progress bar or progress lines")]
WorkersOption = option("--workers", "worker processes of the local Dask cluster (default: the CPU cores)", int, "N")
McWorkersOption = Annotated[int, typer.Option("--mc-workers", metavar="N", help=(
    "Dask workers of the budget's Monte Carlo (1: this process)"))]
McOption = option("--mc", "with --station: the budget's JCGM 101 Monte Carlo, at most N trials (adaptive: it stops "
                  "when every component's linear interval is validated or not; e.g. 10000)", int, "N")
FilterRateOption = Annotated[float, typer.Option("--filter-rate-hz", metavar="HZ", help=(
    "systematic: filter update rate [Hz]"))]

# --------------------------------------------------------------------------- a calibration's (calibrate, batch)
METHODS_HELP = ("six-position | twelve-position | n25 | joint | systematic51 | systematic30 | unified | "
                "thermal-plateaus (a turntable record) | multi-position | ferraris (no turntable: still poses at "
                "unknown orientations; six faces and three whole turns)")
SettleOption = option("--settle-s", "settling time dropped at both ends of each window [s] (default 1; "
                      "multi-position, ferraris: 0.25)", metavar="SECONDS")
MinStaticOption = option("--min-static-s", "shortest static window used [s] (default 20; multi-position: 1; ferraris: "
                         "2)", metavar="SECONDS")
EncoderSigmaOption = option("--encoder-sigma", "unified / gimbal states: white noise of each encoder angle [arcsec] "
                            "(default 1)", metavar="ARCSEC")
EncoderLatencyOption = Annotated[float, typer.Option("--encoder-latency", metavar="SECONDS", help=(
    "shift the encoder angles by this many seconds before calibrating (> 0: encoders that lag the IMU)"))]
SkipEncoderCheckOption = Annotated[bool, typer.Option("--skip-encoder-check", help=(
    "calibrate even when the encoder angles do not follow the gyros"))]
CalibrationNoiseOption = option("--noise", "systematic: an identified noise model (noise.toml of inscal noise): its "
                                "white terms weight the filter, its Gauss-Markov terms become bias states", Path,
                                "NOISE.toml")


def method_option(help: str = METHODS_HELP) -> object:
    """``--method/-m``: the calibration method (required)."""
    return Annotated[str, typer.Option("--method", "-m", metavar="METHOD", help=help)]


def scheduler_option(default: str) -> object:
    """``--scheduler``: where the Dask work runs; ``default`` says what the command does without it."""
    return Annotated[str | None, typer.Option("--scheduler", metavar="SCHEDULER", help=(
        f"local (a Dask LocalCluster of --workers), none (in this process) or a Dask scheduler's address "
        f"tcp://HOST:PORT (default: {default})"))]


def out_option(what: str, required: bool = True) -> object:
    """``--out/-o``: the file the command writes, ``what`` it is."""
    if required:
        return Annotated[Path, typer.Option("--out", "-o", metavar="PATH", help=what)]
    return Annotated[Path | None, typer.Option("--out", "-o", metavar="PATH", help=what)]


def plot_option(what: str) -> object:
    """``--plot``: a figure of the command's result (``what``)."""
    return Annotated[Path | None, typer.Option("--plot", metavar="PATH", help=what)]


def arw_option(default: str) -> object:
    """``--arw``: the gyro white noise, ``default`` the value without it."""
    return Annotated[float | None, typer.Option("--arw", metavar="DEG/SQRT(H)", help=(
        f"gyro white noise (angle random walk) [deg/sqrt(h)] (default: {default})"))]


def vrw_option(default: str) -> object:
    """``--vrw``: the accelerometer white noise, ``default`` the value without it."""
    return Annotated[float | None, typer.Option("--vrw", metavar="UG/SQRT(HZ)", help=(
        f"accelerometer white noise (velocity random walk) [ug/sqrt(Hz)] (default: {default})"))]


def gravity_option(default: str) -> object:
    """``--gravity``: the gravity model, ``default`` the one without it."""
    return Annotated[str | None, typer.Option("--gravity", metavar="MODEL", help=(
        f"gravity model: wgs84 | psins | a measured value in m/s^2 at the site height (default: {default})"))]


def states_option(help: str) -> object:
    """``--states``: the systematic filter's state set (``help`` says which sets the command takes)."""
    return Annotated[str | None, typer.Option("--states", metavar="STATES", help=help)]


def noise_option(help: str) -> object:
    """``--noise``: an identified noise model (noise.toml of ``inscal noise --out``)."""
    return Annotated[Path | None, typer.Option("--noise", metavar="NOISE.toml", help=help)]


def station_option(help: str, kind: type = str) -> object:
    """``--station``: a station's name or description file."""
    return Annotated[kind | None, typer.Option("--station", metavar="STATION", help=help)]


# --------------------------------------------------------------------------- the help's look
#: option-name endings that say the value's unit (longest first)
UNIT_SUFFIXES = (("-rate-hz", "HZ"), ("-hz", "HZ"), ("-deg", "DEG"), ("-dps", "DEG/S"), ("-min", "MINUTES"),
                 ("-s", "SECONDS"), ("-c", "DEGC"))


def metavar_of(param) -> str | None:
    """The name of an option's value in the help: none for a flag, the unit an option's name ends in
    (``--settle-s SECONDS``), ``SEED``, ``N`` for a count, ``PATH`` for a file, else the option's last
    word (``--method METHOD``)."""
    if getattr(param, "is_flag", False) or getattr(param, "count", False):
        return ""
    if isinstance(param, TyperArgument):
        return param.name.upper()
    long = max((o for o in param.opts if o.startswith("--")), key=len, default=param.opts[0])
    for suffix, name in UNIT_SUFFIXES:
        if long.endswith(suffix):
            return name
    if long.endswith("seed"):
        return "SEED"
    desc = param.type_descriptor
    if desc.is_path:
        return "PATH"
    if param.bare_type() in ("int", "list[int]"):
        return "N"
    return long.lstrip("-").split("-")[-1].upper()


class Argument(TyperArgument):
    """A command's argument in the help: ``DATA`` in the usage line (``[PARAMS]`` when optional), no type column."""

    def _usage_display_name(self) -> str:
        name = self.display_name_raw if self.required else f"[{self.display_name_raw}]"
        return name + ("..." if self.nargs != 1 else "")

    def display_type_rich(self, ctx) -> str | None:
        """None: the argument's name says what it is."""
        return None


class Command(TyperCommand):
    """A command whose help names every value (:func:`metavar_of`) and is read literally (``[s]`` is a unit
    in square brackets, not a style of Rich's markup)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        for param in self.params:
            if param.metavar is None:
                param.metavar = metavar_of(param)
            if type(param) is TyperArgument:
                param.__class__ = Argument

    def get_help_option(self, ctx):
        """``--help``, a flag: no value shown."""
        return _flag(super().get_help_option(ctx))

    def invoke(self, ctx):
        """Run the command once its options pass :func:`inscal.cli.applies.check_context` (else one line, exit 2)."""
        try:
            check_context(ctx)
        except CliError as exc:
            raise fail(str(exc)) from None
        return super().invoke(ctx)

    def format_help(self, ctx, formatter) -> None:
        """Typer's help with the texts' square brackets escaped for Rich."""
        from rich.markup import escape

        saved = [(p, p.help) for p in self.params if getattr(p, "help", None)]
        text, epilog = self.help, self.epilog
        try:
            for p, h in saved:
                p.help = escape(h)
            self.help = text and escape(text)
            self.epilog = epilog and escape(epilog)
            return super().format_help(ctx, formatter)
        finally:
            for p, h in saved:
                p.help = h
            self.help, self.epilog = text, epilog


def options_of(cls, params: dict, /, **extra):
    """``cls`` (a dataclass of a command's options) from the command's parameters by field name (``params``:
    the click context's, or the function's locals), with ``extra`` fields set or overriding."""
    names = {f.name for f in dataclasses.fields(cls)}
    return cls(**({k: v for k, v in params.items() if k in names} | extra))


def with_options(block, before: str):
    """A command's decorator: the command takes the options of the dataclass ``block`` as well, declared once by
    its fields (their ``Annotated`` option types and defaults; a field without one is not an option; the
    class's own fields before those of its bases), shown in the help before the command's own parameter
    ``before`` and handed to the command in its ``**`` parameter (:func:`options_of` then builds the options
    object from them)."""
    def decorate(command):
        hints = typing.get_type_hints(block, include_extras=True)
        empty = inspect.Parameter.empty
        own_first = sorted(dataclasses.fields(block), key=lambda f: f.name not in vars(block).get("__annotations__", {}))
        shared = [inspect.Parameter(f.name, inspect.Parameter.KEYWORD_ONLY, annotation=hints[f.name],
                                    default=empty if f.default is dataclasses.MISSING else f.default)
                  for f in own_first if _declared(hints[f.name])]
        own = [p.replace(kind=inspect.Parameter.KEYWORD_ONLY)
               for p in inspect.signature(command, eval_str=True).parameters.values()
               if p.kind is not inspect.Parameter.VAR_KEYWORD]
        at = [p.name for p in own].index(before)
        params = own[:at] + shared + own[at:]

        @functools.wraps(command)
        def run(**given):
            return command(**given)

        run.__signature__ = inspect.Signature(params)
        run.__annotations__ = {p.name: p.annotation for p in params}
        return run
    return decorate


def _declared(hint) -> bool:
    """Whether a type is an option's or argument's declaration (``Annotated[..., typer.Option(...)]``)."""
    return any(isinstance(m, typer.models.ParameterInfo) for m in getattr(hint, "__metadata__", ()))


def _flag(option):
    if option is not None:
        option.metavar = ""
    return option


class Group(TyperGroup):
    """A group of commands (``inscal``, ``inscal db``) whose flags show no value."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        for param in self.params:
            if param.metavar is None:
                param.metavar = metavar_of(param)

    def get_help_option(self, ctx):
        """``--help``, a flag: no value shown."""
        return _flag(super().get_help_option(ctx))
