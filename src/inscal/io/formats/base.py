"""What every format's reader returns and shares: the :class:`Raw` block of columns read from a source
(converted to SI, not yet checked), its :class:`RawTemperature`, the options a reader is given
(:class:`ReadOptions`), the gimbal-angle limits (:func:`check_angles`), reading a file's bytes with the
input checks (:func:`file_bytes`) and the 17-digit rows of the text exports (:func:`write_rows`)."""

from __future__ import annotations

import math

from dataclasses import dataclass
from io import StringIO
from pathlib import Path as FsPath

import numpy as np

from inscal.core.units import DEG
from inscal.io.files import check_input
from inscal.io.mapping import MAX_ANGLE, MAX_RATE, ImportFileError, Mapping


@dataclass
class RawTemperature:
    """Temperature readings as read, in degC, not yet checked: ``values`` (M, S) with NaN where a cell is
    empty (that sensor has no reading there), at ``time`` (M,) s, or at the rows of the IMU samples
    they came with (``time`` None)."""

    time: np.ndarray | None
    values: np.ndarray
    names: tuple  # sensor names
    labels: tuple  # each sensor's column, for messages
    lines: np.ndarray | None = None  # file line of each row
    units: tuple = ()  # the unit each sensor's values were declared in (degC, K, degF)
    fix: str = ""  # how to declare a sensor's unit ("{unit}": the unit, "{name}": the sensor)
    where: str = ""  # the file

    def at(self, i: int) -> str:
        """Where reading ``i`` came from, for messages: ``line N`` of a text file, else ``row N`` (1-based)."""
        return f"line {int(self.lines[i])}" if self.lines is not None else f"row {i + 1}"


@dataclass
class Raw:
    """Columns read from a source, converted to SI but not yet checked."""

    time: np.ndarray | None  # (N,) s, or None (then a rate is required)
    gyro: np.ndarray  # (N, 3) rad (increments) or rad/s (rates), IMU axes
    accel: np.ndarray  # (N, 3) m/s or m/s^2
    kind: str  # "increments" | "rates"
    gimbal: np.ndarray | None  # (N, 2) rad, from columns of the same file
    labels: tuple  # names of the 6 channels (for messages)
    lines: np.ndarray | None = None  # file line of each row (text); None: rows counted from 1
    hint: str = ""  # appended to time-base messages (e.g. a dtype hint)
    raw_channels: np.ndarray | None = None  # (N, 6) as read (before scaling), for the plausibility checks
    counts: tuple = (False, False)  # gyro / accel given in counts (whole numbers expected)
    time_label: str = "time"
    header_site: tuple | None = None  # (latitude deg, longitude deg, height m) the file's own header gives
    axes: tuple = (0, 1, 2)  # IMU axis of each file channel (1st, 2nd, 3rd of the gyros and of the accelerometers)
    time_unit: str = "s"  # the unit the time column was read in
    time_fix: str = ""  # how to declare the time column's unit here ("{unit}": the unit, "{factor}": the factor)
    temperature: RawTemperature | None = None  # temperature columns of the same file
    integration: object | None = None  # rates integrated onto a grid (inscal.io.formats.rates.RateIntegration)
    source_info: dict | None = None  # what a reader adds to the record's ``source`` attribute (JSON-ready)

    def at(self, i: int) -> str:
        """Where sample ``i`` came from, for messages: ``line N`` of a text file, else ``row N`` (1-based)."""
        return f"line {int(self.lines[i])}" if self.lines is not None else f"row {i + 1}"


@dataclass(frozen=True)
class ReadOptions:
    """What ``inscal import`` gives a format's reader beside the source (each reader takes the ones its
    row of :data:`inscal.io.formats.REGISTRY` names in ``options``, and ignores the others)."""

    fmt: str  # the --format the source is read as
    mapping: Mapping | None = None  # csv / txt: the columns and units (None: the inscal export layout)
    dtype: str = "float64"  # psins .bin: float64 | float32
    variable: str | None = None  # .mat: the N x 7 variable (None: the first)
    rates: bool = False  # psins / mat: the rows are rates w, f, t
    topic: str | None = None  # rosbag: the sensor_msgs/Imu topic
    stamps: str = "header"  # rosbag: header | receive
    rate_hz: float | None = None  # the grid of rates sampled at their own stamps (None: their mean rate)


def check_angles(angles: np.ndarray, dt, where: str, at, names=("outer angle", "inner angle")) -> None:
    """Gimbal angles [rad] (N, 2) within :data:`~inscal.io.mapping.MAX_ANGLE`, and no jump between two
    readings beyond a wrap (2 pi) plus :data:`~inscal.io.mapping.MAX_RATE` times the interval ``dt`` (a
    scalar or the (N - 1,) steps [s]): a value no encoder reads, named with ``at(i)`` (its row)."""
    for c in range(2):
        x = angles[:, c]
        with np.errstate(all="ignore"):
            big = np.abs(x) > MAX_ANGLE
        if big.any():
            i = int(np.argmax(big))
            raise ImportFileError(f"{where}: {names[c]} is {x[i]:.6g} rad ({x[i] / DEG:.6g} deg) at {at(i)}: beyond "
                                  f"any turntable (limit {MAX_ANGLE:.3g} rad, 1.6 million turns)")
        with np.errstate(all="ignore"):
            jump = np.abs(np.diff(x)) > 2.0 * math.pi + MAX_RATE * np.asarray(dt)
        if jump.any():
            j = int(np.argmax(jump))
            i = j if abs(x[j]) > abs(x[j + 1]) else j + 1  # the reading that does not belong: the larger one
            around = " and ".join(f"{x[m]:.6g}" for m in (i - 1, i + 1) if 0 <= m < x.size)
            raise ImportFileError(
                f"{where}: {names[c]} is {x[i]:.6g} rad ({x[i] / DEG:.6g} deg) at {at(i)}, {around} rad on the rows "
                f"around it: a jump of {abs(x[j + 1] - x[j]):.3g} rad in one interval, beyond a wrap (2 pi) and any "
                f"turntable's rate (limit {MAX_RATE:.0f} rad/s = 100 rev/s)")


def file_bytes(p: FsPath) -> bytes:
    """The bytes of the source ``p`` after the input checks (:func:`~inscal.io.files.check_input`); an empty
    file is refused."""
    check_input(p, "file", ImportFileError)
    b = p.read_bytes()
    if not b:
        raise ImportFileError(f"{p}: file is empty")
    return b


def text_lines(p: FsPath, what: str = "", binary_check: bool = False) -> list[str]:
    """The lines of the text source ``p`` (UTF-8, a byte-order mark dropped) after :func:`file_bytes`;
    ``what`` ends the message of a file that is not UTF-8 (``": a PSINS .imu log is text"``), and
    ``binary_check`` refuses a NUL byte in its first 4 KiB as binary data."""
    b = file_bytes(p)
    if binary_check and b"\x00" in b[:4096]:
        raise ImportFileError(f"{p}: not a text file (binary data)")
    try:
        return b.decode("utf-8-sig").splitlines()
    except UnicodeDecodeError:
        raise ImportFileError(f"{p}: not a text file (not UTF-8){what}") from None


def rows7(a: np.ndarray, where: str, rates: bool, hint: str = "") -> Raw:
    """A (N, 7) PSINS array ``[gyro(3) accel(3) t]`` as a :class:`Raw`."""
    if a.shape[0] < 2:
        raise ImportFileError(f"{where}: {a.shape[0]} row(s); at least 2 samples are needed")
    a = np.asarray(a, dtype=float)
    kind = "rates" if rates else "increments"
    labels = (("wx", "wy", "wz", "fx", "fy", "fz") if rates else ("dthx", "dthy", "dthz", "dvx", "dvy", "dvz"))
    labels = tuple(f"{n} (column {k + 1})" for k, n in enumerate(labels))
    return Raw(a[:, 6].copy(), a[:, 0:3].copy(), a[:, 3:6].copy(), kind, None, labels, None, hint, a[:, :6],
               time_fix="the format holds seconds: divide its time column by {factor} before importing (or read the "
                        "rows as csv through a mapping with [units] time = \"{unit}\")")


def write_rows(fh, a: np.ndarray, blanks: bool = False) -> None:
    """Rows of 17 significant digits; ``blanks``: NaN cells (no temperature reading) are left empty."""
    if not blanks:
        np.savetxt(fh, a, fmt="%.17g", delimiter=",")
        return
    buf = StringIO()
    np.savetxt(buf, a, fmt="%.17g", delimiter=",")
    fh.write(buf.getvalue().replace("nan", ""))  # "%.17g" writes no other "nan" than NaN's

