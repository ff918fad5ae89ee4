"""A mechanism sent to another process (a Dask worker, a pool) is rebuilt from its fields there: it
carries none of its cached values, so its hash is the receiving process's own (string hashes differ
between processes) and it is validated again."""

from __future__ import annotations

import pickle
import subprocess
import sys

from exo_bench.models.mechanism.presets import exo5

_CHILD = """
import pickle, sys
from exo_bench.models.mechanism.presets import exo5
received = pickle.loads(sys.stdin.buffer.read())
rebuilt = exo5(3)
print(hash(received) == hash(rebuilt), received == rebuilt, len({received, rebuilt}))
"""


def test_a_pickled_mechanism_hashes_as_the_receiving_process_does():
    """An exo5-3d hashed (and its views cached) here, unpickled in a process with another hash seed,
    hashes as that process's own exo5-3d and is one element of a set with it."""
    mech = exo5(3)
    hash(mech), mech.mass_array  # fill the caches the pickle must not carry
    data = pickle.dumps(mech)
    out = subprocess.run(
        [sys.executable, "-c", _CHILD],
        input=data,
        capture_output=True,
        env={**__import__("os").environ, "PYTHONHASHSEED": "12345"},
        timeout=600,
        check=True,
    )
    assert out.stdout.decode().split() == ["True", "True", "1"]


def test_a_pickled_mechanism_is_validated_when_rebuilt():
    """Unpickling runs the mechanism's validation: a pickle whose fields were edited to a negative
    mass is refused with the ValueError naming the link and field."""
    import pytest

    mech = exo5(3)
    cls, args = mech.__reduce__()[:2]
    args = list(args)
    masses = [list(m) for m in args[4]]
    masses[2][1] = -1.0
    args[4] = masses
    with pytest.raises(ValueError, match="link 3"):
        cls(*args)
