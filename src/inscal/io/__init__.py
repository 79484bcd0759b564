"""Files: the HDF5 record format (``/time``, ``/dtheta``, ``/dvel``, ``/gimbal``, ``/truth``), parameter
files, JSON and TOML helpers, the importers and exporters of other tools' formats, and atomic writes.

This face re-exports the record and file helpers, so ``from inscal import io; io.read_record(path)``
works; parameter files are :mod:`inscal.io.paramfile`, the importers :mod:`inscal.io.importers`."""

from inscal.core.cancel import cancel, check_cancel
from inscal.io.files import (
    REMOVED_PARTS,
    atomic_path,
    file_hash,
    remove_live_parts,
    remove_part,
)
from inscal.io.records import (
    KIND,
    UNITS,
    DataFileError,
    LazyArray,
    Record,
    RecordInfo,
    Temperature,
    Truth,
    Window,
    check_datasets,
    compensated_with,
    iter_chunks,
    iter_window,
    open_record,
    read_record,
    read_temperature,
    record_attrs,
    record_info,
    record_window,
    truth_groups,
    validate_arrays,
    validate_temperature,
    write_record,
    write_stream,
)

__all__ = ['REMOVED_PARTS', 'cancel', 'check_cancel', 'atomic_path', 'remove_part', 'remove_live_parts', 'file_hash', 'KIND', 'UNITS', 'DataFileError', 'Truth', 'Temperature', 'validate_temperature', 'read_temperature', 'Record', 'write_stream', 'write_record', 'validate_arrays', 'truth_groups', 'read_record', 'RecordInfo', 'record_info', 'iter_chunks', 'check_datasets', 'Window', 'record_window', 'iter_window', 'LazyArray', 'open_record', 'record_attrs', 'compensated_with']
