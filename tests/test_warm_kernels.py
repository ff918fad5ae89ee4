"""The controller's warm-up of the numba cache (tests/warm_kernels.py, tests/xdist_workers.py): it covers
every method with numba kernels, and a part that fails or hangs is named and the run goes on (its
kernels are then compiled by the tests, as without a warm-up)."""

from __future__ import annotations


import pytest
import warm_kernels
import xdist_workers

from exo_bench import method_names, prepare, presets


def test_every_method_with_numba_kernels_is_in_a_part():
    warmed = {m for part in warm_kernels.PARTS.values() for m in part}
    assert set(warm_kernels.PARTS) == set(xdist_workers.WARM_PARTS)
    for method in method_names():
        if method in ("lagrange", "mujoco", "drake", "pinocchio"):
            continue  # no numba kernel: a derivation, or an engine of its own
        model = prepare(presets.exo5(dim=2), method)
        if any(k.option == "numba" for k in model.kernels or ()):
            assert method in warmed, method


@pytest.mark.parametrize(
    ("script", "timeout", "expected"),
    [
        (
            "import sys; print('no such part'); sys.exit(3)",
            600,
            "exit 3: no such part; its kernels compile in the tests",
        ),
        ("import time; time.sleep(600)", 1, "stopped after 1 s; its kernels compile in the tests"),
    ],
)
def test_a_part_that_fails_or_hangs_is_named_and_the_run_goes_on(tmp_path, monkeypatch, script, timeout, expected):
    fake = tmp_path / "warm.py"
    fake.write_text(script)
    monkeypatch.setattr(xdist_workers, "WARM_KERNELS", fake)
    lines = xdist_workers.warm_numba_cache(tmp_path / "cache", timeout=timeout)
    assert lines == [f"warm_kernels {part}: {expected}" for part in xdist_workers.WARM_PARTS], lines
