"""Small helpers shared by the ``cli_*`` modules (no domain logic here)."""

from __future__ import annotations

import contextlib
import importlib
import json
import os
import re
from pathlib import Path

import typer


class LazyModule:
    """A module imported on first attribute access: ``np = LazyModule("numpy")`` keeps NumPy (and
    heavier modules) off the start of ``inscal --help`` / ``--version`` (see bench/bench_startup.py)."""

    def __init__(self, name: str):
        self._name = name

    def __getattr__(self, attr):
        return getattr(importlib.import_module(self._name), attr)

    def __repr__(self) -> str:
        return f"<lazy module {self._name!r}>"


np = LazyModule("numpy")


class CliError(Exception):
    """An error to report to the user as one line (exit code 2)."""


def fail(msg: str, code: int = 2) -> typer.Exit:
    """Print a one-line error to stderr and return an Exit to raise: ``raise fail("...")``."""
    msg = re.sub(r"\S{%d,}" % (MAX_ECHO + 1), lambda m: short(m.group()), " ".join(str(msg).split("\n")))
    if len(msg) > 5 * MAX_ECHO:  # a message quoting a very long user string
        msg = short(msg, 5 * MAX_ECHO)
    typer.echo(f"inscal: error: {msg}", err=True)
    return typer.Exit(code)


def call(fn, *args, **kwargs):
    """``fn(*args, **kwargs)`` for a command: a :class:`CliError` is its one line on standard error, exit 2."""
    try:
        return fn(*args, **kwargs)
    except CliError as exc:
        raise fail(str(exc)) from None


def warn(text: str) -> None:
    """A warning of the command on standard error (``inscal: warning: ...``)."""
    typer.echo(f"inscal: warning: {text}", err=True)


def write_figure(draw, plot: Path, *args, **kwargs):
    """``draw(plot, *args, **kwargs)``: a figure written, an OSError as a one-line :class:`CliError`."""
    try:
        return draw(plot, *args, **kwargs)
    except OSError as exc:
        raise CliError(f"cannot write {short(plot)}: {exc.strerror or exc}") from None


def check_output(path: Path, force: bool) -> None:
    """Refuse to overwrite an existing output unless ``force``; the parent folder must exist and be
    writable.  Then take the output's lock for the rest of the command (:func:`inscal.io.files.claim_output`,
    dropped when the command ends): a second inscal process writing the same output is refused
    up front, before either does any work."""
    from inscal.io.files import OutputBusyError, claim_output

    path = Path(path)
    if not path.parent.exists():
        raise CliError(f"folder {short(path.parent)} does not exist")
    if not path.parent.is_dir():
        raise CliError(f"{short(path.parent)} is not a folder")
    if not os.access(path.parent, os.W_OK | os.X_OK):
        raise CliError(f"folder {short(path.parent)} is read-only (or not writable by this user): nothing can be "
                       "written there")
    if len(os.fsencode(path.name)) > 255:
        raise CliError(f"{short(path.name)}: a file name of {len(os.fsencode(path.name))} bytes (the most is 255)")
    if path.is_dir():
        raise CliError(f"{short(path)} is a folder, not a file name: give a file name (--force replaces files only)")
    try:
        claim_output(path)
    except OutputBusyError as exc:
        raise CliError(short(exc, 5 * MAX_ECHO)) from None
    except OSError as exc:
        raise CliError(f"cannot lock {short(path)}: {exc.strerror or exc}") from None
    if path.exists() and not force:
        raise CliError(f"{short(path)} exists; use --force to overwrite it")


def check_not_input(out: Path, *inputs: Path | None, what: str = "--out", role: str = "input") -> None:
    """Refuse (one line, exit 2 via :class:`CliError`) an output that is one of the inputs, so that
    ``--force`` never destroys an input record or parameter file (paths are resolved, links followed)."""
    try:
        ro = Path(out).resolve()
    except (OSError, RuntimeError):
        return
    for inp in inputs:
        if inp is None:
            continue
        try:
            same = Path(inp).resolve() == ro or (ro.exists() and Path(inp).exists() and ro.samefile(inp))
        except (OSError, RuntimeError):
            continue
        if same:
            raise CliError(f"{what} must differ from the {role} {short(inp)} (writing it would destroy it)")


def read_record(path: Path):
    """The record of ``path`` (:func:`inscal.io.recordfile.load_record`: a malformed record, increments that are
    not floating point) with every failure a one-line :class:`CliError`."""
    from inscal import io

    try:
        return io.load_record(path, short)
    except io.DataFileError as exc:
        raise CliError(str(exc)) from None


@contextlib.contextmanager
def record_errors(data: Path, *also: type[Exception]):
    """Reading the record ``data`` inside: its failures leave as one-line :class:`CliError` s, a
    :class:`~inscal.io.DataFileError` (or one of ``also``) by its message, a ``KeyError``, ``TypeError`` or
    ``ValueError`` of a malformed file as "not a valid inscal record"."""
    from inscal import io

    try:
        yield
    except (io.DataFileError, *also) as exc:
        raise CliError(str(exc)) from None
    except (KeyError, TypeError, ValueError) as exc:
        raise CliError(f"{short(data)}: not a valid inscal record ({type(exc).__name__}: {short(exc)})") from None


#: echoed user strings longer than this are cut (a 100,000-character name is not echoed in full)
MAX_ECHO = 200


def normal_serial(serial: str) -> str:
    """A unit's serial as the calibration database stores it (spaces at its ends removed), with a note on
    standard error when that changed what was typed."""
    s = str(serial).strip()
    if s != str(serial) and s:
        typer.echo(f"inscal: note: serial {short(repr(str(serial)))} is stored as {s!r} (spaces at its ends removed)",
                   err=True)
    return s


def short(value, limit: int = MAX_ECHO) -> str:
    """``str(value)`` cut to ``limit`` characters (with an ellipsis and the full length) for messages."""
    s = str(value)
    if len(s) <= limit:
        return s
    return f"{s[:limit - 1]}… ({len(s)} characters)"


def print_json(obj) -> None:
    """Print ``obj`` as JSON on stdout (NumPy types converted, NaN/inf -> null)."""
    from inscal.io.jsonfile import to_jsonable

    typer.echo(json.dumps(to_jsonable(obj), indent=2))


def load_checked_params(path):
    """``(imu, gimbal, meta)`` of a parameter file (:func:`inscal.io.paramfile.load_params`), its method one
    of inscal's calibration methods or of :data:`~inscal.io.paramfile.HAND_METHODS` (a file whose ``method``
    is unknown was not written by inscal and is not used as if it were); every problem is a :class:`CliError`."""
    from inscal.calibrate import METHODS
    from inscal.io.paramfile import HAND_METHODS, ParamFileError, load_params

    try:
        imu, gimbal, meta = load_params(path)
    except (ParamFileError, ValueError) as exc:
        raise CliError(str(exc)) from None
    if meta.get("method") not in METHODS and meta.get("method") not in HAND_METHODS:
        raise CliError(f"{path}: method {meta.get('method')!r} is not an inscal calibration method (known: "
                       f"{', '.join(METHODS)}; a file made by hand says {', '.join(HAND_METHODS)})")
    return imu, gimbal, meta


def check_scheduler(value: str | None, words: tuple[str, ...]) -> str | None:
    """``--scheduler``: None, one of ``words`` (e.g. local, none, synchronous), or a Dask scheduler address
    ``[tcp|tls|ucx|inproc]://HOST:PORT`` or ``HOST:PORT``; anything else is one line, not a traceback."""
    if value is None or value in words:
        return value
    text = str(value).strip()
    rest = text.split("://", 1)[1] if "://" in text else text
    scheme = text.split("://", 1)[0] if "://" in text else "tcp"
    host, _, port = rest.rpartition(":")
    if scheme not in ("tcp", "tls", "ucx", "inproc") or not host or not port.isdigit() or not 0 < int(port) < 65536 \
            or any(c.isspace() for c in rest):
        raise CliError(f"--scheduler {value!r}: not a Dask scheduler address (tcp://HOST:PORT or HOST:PORT) nor one of "
                       f"{', '.join(w for w in words if w)}")
    return text


def parse_gravity_option(text: str):
    """``--gravity wgs84|psins|VALUE`` (VALUE in m/s^2, measured at the site height)."""
    from inscal.core.earth import parse_gravity

    try:
        return parse_gravity(text)
    except ValueError as exc:
        raise CliError(f"--gravity: {exc}") from None


def first_time(data: Path) -> float:
    """The time of a record's first sample (one sample read)."""
    import contextlib

    from inscal import io

    with contextlib.closing(io.iter_chunks(data, chunk_size=1)) as it:
        return float(next(it)[0][0])


def thermal_compensation(data: Path, params: Path, meta: dict, info, imu, temperature: float | None = None):
    """``(ThermalCompensation or None, its survey, warning lines)`` for compensating ``data`` (its ``info``) with the
    parameter file ``params`` (``meta`` from :func:`load_checked_params`, base errors ``imu``): None when
    the file has no thermal model.  The record's temperature is surveyed before any work: a record
    without /temperature (and no ``temperature`` constant [degC]), readings that do not cover the
    samples, and an ``out_of_range = "error"`` model that the temperature leaves are one-line refusals."""
    from inscal import io
    from inscal.core.thermal import ThermalError
    from inscal.nav.stream import ThermalCompensation

    model = meta.get("thermal")
    if model is None:
        if temperature is not None:
            raise CliError(f"--temperature is the temperature of a thermal model, and {short(params)} has none "
                           "(no [thermal] table)")
        return None, None, []
    warnings = []
    if temperature is not None:
        from inscal.io.records import TEMPERATURE_SPAN

        lo, hi = TEMPERATURE_SPAN
        if not lo <= temperature <= hi:  # NaN too
            raise CliError(f"--temperature {temperature:g} degC: outside the plausible {lo:g} .. {hi:g} degC")
        source = temperature
        if info.temperature is not None:
            warnings.append(f"--temperature {temperature:g} degC is used in place of the /temperature readings of "
                            f"{short(data)}")
    elif info.temperature is None:
        raise CliError(f"{short(data)} has no /temperature readings, and {short(params)} has a thermal model "
                       f"([thermal], T_ref {model.t_ref:g} degC) that needs them: give a constant temperature with "
                       "--temperature DEGC, or use a parameter file without [thermal]")
    else:
        source = info.temperature
    try:
        comp = ThermalCompensation(model, imu, source, info.rate_hz, where=short(data))
        survey = comp.survey(first_time(data), info.n_samples)
    except ThermalError as exc:
        raise CliError(str(exc)) from None
    except (io.DataFileError, OSError) as exc:  # the record's first sample unreadable
        raise CliError(str(exc)) from None
    if survey["message"] is not None:
        warnings.append(survey["message"])
    return comp, survey, warnings
