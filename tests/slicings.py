"""Ways to slice a kernel's steps, for the tests that prove the slicing changes no bit
(``tests/plan/test_slices.py``, ``tests/calibrate/test_kernel_slices.py``)."""


def one_call(total, kernel, **_):
    """The unsliced computation: every step in one kernel call."""
    kernel(0, total)
    return 1


def fixed(n):
    def run(total, kernel, **_):
        for k0 in range(0, total, n):
            kernel(k0, min(total, k0 + n))
        return -(-total // n)

    return run


def slicings(run_in_slices) -> dict:
    """Fixed slices of 1 and 7 steps, the real driver ``run_in_slices`` with a tiny target (slices of
    varying length: 1, 4, 16 ... shrinking again) and with its defaults."""

    def adaptive_tiny(total, kernel, **_):
        return run_in_slices(total, kernel, first=1, target_s=1e-4)

    return {"one step": fixed(1), "7 steps": fixed(7), "adaptive": adaptive_tiny, "default": run_in_slices}
