"""One ``inscal demo --quick`` for the test session: part 0 of the README's command block runs the command as
written (``tests/cli/readme_block.py``) and leaves a copy of its ``demo-output/`` folder and its stdout in a
folder every xdist worker of the session sees (``tmp_path_factory.getbasetemp().parent``; the session's own
base folder without xdist); ``tests/cli/test_demo_html.py`` checks that copy, or runs the same command itself
where the README's part has not run (yet) in this session.  An ``fcntl.flock`` on a file of that folder orders
the two: the README's part holds it while its demo runs, so that the page test on the other worker waits for
the copy rather than running the demo beside it."""

from __future__ import annotations

import contextlib
import fcntl
import os
import shutil
from pathlib import Path

#: the demo's output folder in the README's line (its ``--out`` default) and in the shared copy
FOLDER = "demo-output"
#: the record files the demo simulates: the page test reads none of them, so the copy leaves them out
SKIP = ("*.h5",)


def shared_dir(tmp_path_factory) -> Path:
    """The folder the workers of this test session share (created)."""
    base = tmp_path_factory.getbasetemp()
    d = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "demo-quick-shared"
    d.mkdir(exist_ok=True)
    return d


@contextlib.contextmanager
def locked(shared: Path):
    """Hold the session's demo lock (blocking until the holder, a test on another worker, lets it go)."""
    with open(shared / "lock", "w") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def publish(shared: Path, run_folder: Path, stdout: str) -> None:
    """Copy ``run_folder/demo-output`` (the records left out) and the command's stdout into ``shared``; call it
    while holding :func:`locked`.  The ``done`` file is written last: a copy cut short is not taken."""
    shutil.copytree(run_folder / FOLDER, shared / FOLDER, ignore=shutil.ignore_patterns(*SKIP), dirs_exist_ok=True)
    (shared / "stdout.txt").write_text(stdout, encoding="utf-8")
    (shared / "done").write_text("", encoding="utf-8")


def published(shared: Path) -> str | None:
    """The stdout of the README's demo run when its copy is complete in ``shared``, else None; call it while
    holding :func:`locked`."""
    if not (shared / "done").exists():
        return None
    return (shared / "stdout.txt").read_text(encoding="utf-8")
