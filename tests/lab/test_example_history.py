"""``lab.example_history``: the database its docstring describes (dates a month apart, the record hashes,
the newest current), and no database at all for a bad count of biases."""

import datetime as dt

import pytest

from inscal import lab


def test_the_documented_history(tmp_path):
    db, ids = lab.example_history(tmp_path / "calib.sqlite", (0.010, 0.012))
    try:
        cals = lab.calibrations(db, "IMU-1")
        assert [c.id for c in cals] == list(ids)
        assert [c.session.record_sha256 for c in cals] == ["sha256:" + "1" * 64, "sha256:" + "2" * 64]
        assert [c.session.date.replace(tzinfo=None) for c in cals] == [dt.datetime(2025, 1, 31), dt.datetime(2025, 3, 2)]
        assert [c.parameters["gyro_bias"].sigma.tolist() for c in cals] == [[0.001] * 3] * 2
        assert lab.current_calibration(db, "IMU-1").id == ids[-1]
    finally:
        db.close()


@pytest.mark.parametrize("biases", [(), tuple(0.01 for _ in range(10))])
def test_a_bad_count_leaves_nothing(tmp_path, biases):
    with pytest.raises(ValueError, match="1 to 9"):
        lab.example_history(tmp_path / "calib.sqlite", biases)
    assert not (tmp_path / "calib.sqlite").exists()
