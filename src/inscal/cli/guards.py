"""Checks of a command's outputs against its database and inputs, made before any work: an output
that resolves to the calibration database (or its write-ahead log and shared-memory files) or to an
input is refused in one line, so that ``--force`` never replaces the lab's records or a record."""

from __future__ import annotations

from pathlib import Path

import typer

from inscal.cli.common import CliError, check_not_input, short


def database_files(db: str | None) -> list[Path]:
    """The files of the SQLite calibration database ``--db`` names (``$INSCAL_DB``, else ``calib.sqlite``): the
    database, its ``-wal``, ``-shm`` and ``-journal``; none for a server database or a URL that is not one."""
    from inscal.lab import DatabaseError, database_url

    try:
        url = database_url(db)
    except DatabaseError:
        return []  # refused with its reason when the database is opened
    if url.get_backend_name() != "sqlite" or not url.database:
        return []
    base = Path(url.database)
    return [base] + [base.with_name(base.name + sfx) for sfx in ("-wal", "-shm", "-journal")]


def check_not_database(out: Path | None, db: str | None, what: str = "--out") -> None:
    """Refuse (:class:`CliError`) an output ``out`` that is the calibration database ``db`` or one of its files."""
    if out is None:
        return
    for i, f in enumerate(database_files(db)):
        try:
            same = Path(out).resolve() == f.resolve() or (f.exists() and Path(out).exists() and f.samefile(out))
        except (OSError, RuntimeError):
            continue
        if same:
            raise CliError(f"{what} {short(out)} is the calibration database{'' if i == 0 else ' file'} {short(f)}: "
                           "writing it would destroy the lab's records; choose another name")


def check_outputs(outputs: list[tuple[str, Path | None]], inputs: list[Path | None], db: str | None,
                  with_db: bool) -> None:
    """Every output (``(option, path)``) against every input and, when the command uses the database
    (``with_db``), against the database's files; outputs also against each other."""
    seen: dict[Path, str] = {}
    for what, out in outputs:
        if out is None:
            continue
        check_not_input(out, *inputs, what=what)
        if with_db:
            check_not_database(out, db, what)
        try:
            key = Path(out).resolve()
        except (OSError, RuntimeError):
            continue
        if key in seen:
            raise CliError(f"{what} and {seen[key]} name the same file {short(out)}")
        seen[key] = what


def recovery_note(line: str) -> None:
    """Say on standard error what opening the database rolled forward of an interrupted publication."""
    typer.echo(f"inscal: note: an interrupted publication completed: {line}", err=True)


def database_notes(d) -> None:
    """The notes of opening calibration database ``d``: what its opening for writing rolled forward of
    the publication journal (:mod:`inscal.lab.journal`); opened read-only, how many files are owed."""
    from inscal import lab

    if d.readonly:
        n = lab.pending_publications(d)
        if n:
            from inscal.lab.journal import waiting_line

            typer.echo(f"inscal: note: {waiting_line(n, d.where)}", err=True)
        return
    for line in d.recovery.done:
        recovery_note(line)
