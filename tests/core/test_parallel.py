"""The one Dask starter: a scheduler that cannot be reached is one line of the caller's error."""

import pytest

from inscal.core.parallel import start_client


class _Err(ValueError):
    pass


def test_unreachable_scheduler_is_the_callers_one_line_error():
    with pytest.raises(_Err, match=r"^cannot reach the Dask scheduler at tcp://127\.0\.0\.1:9") as e:
        start_client("tcp://127.0.0.1:9", 1, "1s", _Err)
    assert "\n" not in str(e.value)
