"""Files: the HDF5 record format (``/time``, ``/dtheta``, ``/dvel``, ``/gimbal``, ``/truth``), parameter
files, JSON and TOML helpers, the importers and exporters of other tools' formats, and atomic writes.

This face re-exports the record and file helpers, so ``from inscal import io; io.read_record(path)``
works; parameter files are :mod:`inscal.io.paramfile`, the importers :mod:`inscal.io.importers`, the
formats they read :mod:`inscal.io.formats`.  The names are imported on first use, so that reading the
format table (the command line does, when it starts) costs no NumPy or h5py."""

import importlib

#: the modules that hold the names of this face
_FILES = ("REMOVED_PARTS", "atomic_path", "file_hash", "remove_live_parts", "remove_part")
_RECORDS = ("KIND", "UNITS", "DataFileError", "Record", "RecordInfo", "Temperature", "Truth", "compensated_with",
            "record_attrs", "validate_arrays", "validate_temperature")
_RECORDFILE = ("check_datasets", "load_record", "read_record", "read_temperature", "record_info", "truth_groups",
               "write_record", "write_stream")
_STREAMING = ("LazyArray", "Window", "iter_chunks", "iter_window", "open_record", "record_window")
#: name -> the module that defines it
FACE = {**{n: "inscal.core.cancel" for n in ("cancel", "check_cancel")}, **{n: "inscal.io.files" for n in _FILES},
        **{n: "inscal.io.records" for n in _RECORDS}, **{n: "inscal.io.recordfile" for n in _RECORDFILE},
        **{n: "inscal.io.streaming" for n in _STREAMING}}


def __getattr__(name: str):
    """A name of :data:`FACE`, from its module (imported on first use)."""
    if name not in FACE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(FACE[name]), name)


def __dir__():
    return sorted(set(globals()) | set(FACE))


__all__ = ['REMOVED_PARTS', 'cancel', 'check_cancel', 'atomic_path', 'remove_part', 'remove_live_parts', 'file_hash', 'KIND', 'UNITS', 'DataFileError', 'Truth', 'Temperature', 'validate_temperature', 'read_temperature', 'Record', 'write_stream', 'write_record', 'validate_arrays', 'truth_groups', 'read_record', 'RecordInfo', 'record_info', 'iter_chunks', 'check_datasets', 'Window', 'record_window', 'iter_window', 'LazyArray', 'open_record', 'record_attrs', 'compensated_with', 'load_record']
