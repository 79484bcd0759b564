"""``--station FILE.toml`` of ``observability --crlb`` and ``design``: the station read for the budget before the run
(:mod:`inscal.uncertainty.before_run`), a file that cannot be used ending the command with one line."""

from __future__ import annotations

from inscal.cli.common import fail


def read_station_option(path):
    """The station of ``--station FILE.toml`` (None without it); a file that cannot be used ends the command with
    one line (:class:`inscal.uncertainty.station.StationError`)."""
    if path is None:
        return None
    from inscal.uncertainty.station import StationError, read_station

    try:
        return read_station(path)
    except StationError as exc:
        raise fail(f"--station {path}: {exc}") from None
