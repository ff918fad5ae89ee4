"""Every family of writers the package has goes through the one writer (exo_bench/models/files.py):
"Nothing half-written is left behind" and "Writes do not follow links planted in output folders".

The families: the library's ``save_mechanism``, the CasADi functions' ``save`` (one ``.casadi`` file
each), the stored step and the stored stride (numpy's savez), a figure (``save_figure``), a rerun
recording and the checkpoint of a sweep's row (``atomic_write``). The command line's ``-o`` and
``--reports``: tests/test_safe_writes.py.

* A symlink planted where a writer's file goes is refused (a ValueError naming it): the file it
  points to is kept, and no temporary is left.
* A crash in the middle of the write (the file size limit, ``RLIMIT_FSIZE``, set to 64 bytes in a
  child process once everything to write is built, so the write fails with EFBIG part-way) leaves the
  file there before as it was, and no temporary (all but the recording: :data:`NOT_CRASHED`). CasADi's
  ``Function.save`` reported no error and left a truncated file: each file is now read back. One child runs every family (about 5 s: importing
  and building what is written, the writes are small).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

OLD = "old content, kept\n"


def _mechanism():
    from exo_bench.models.mechanism.presets import fig2a

    return fig2a(2)


def _save_mechanism(folder: Path) -> None:
    from exo_bench.models.mechanism.presets import save_mechanism

    save_mechanism(_mechanism(), folder / "m.json")


def _casadi(folder: Path) -> None:
    from exo_bench.matrix_method.export.casadi_functions import casadi_functions

    casadi_functions(_mechanism()).save(folder)


def _step(folder: Path) -> None:
    from types import SimpleNamespace

    from exo_bench.bench.studies.step import data
    from exo_bench.models.mechanism.presets import exo5

    s = data.load("exo5-3d")
    arrays = {k: getattr(s, k) for k in ("t", "q", "qd", "qdd", "tau", "moments", "forces")}
    data.save(SimpleNamespace(settings=s.settings, stats=s.meta["solver"], **arrays), exo5(3), folder)


def _stride(folder: Path) -> None:
    from exo_bench.bench.studies.stride import data
    from exo_bench.models.mechanism.presets import human

    data.save(data.load("human", 1.41, human(2)), human(2), folder)


def _figure(folder: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from exo_bench.bench.output.provenance import save_figure

    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    save_figure(fig, folder / "f.png")


def _recording(folder: Path) -> None:
    import numpy as np

    from exo_bench.bench.output.recording import write_recording
    from exo_bench.bench.studies.study import run_methods
    from exo_bench.models.gait.motion import smooth_random_motion

    motion = smooth_random_motion(_mechanism(), np.linspace(0.0, 1.0, 5), seed=1)
    write_recording(run_methods("r", _mechanism(), motion, "a reach", ["matrix-factored"]), folder / "r.rrd")


def _checkpoint(folder: Path) -> None:
    from exo_bench.models.files import atomic_write

    atomic_write(folder / "row.json", json.dumps({"key": "x" * 200}))


#: family -> (the file it writes in its folder, the writer, the module it needs)
FAMILIES = {
    "save_mechanism": ("m.json", _save_mechanism, None),
    "casadi": ("inverse_dynamics.casadi", _casadi, "casadi"),
    "step": ("exo5_3d-step.npz", _step, None),
    "stride": ("human_2d_human_v141.npz", _stride, None),
    "figure": ("f.png", _figure, None),
    "recording": ("r.rrd", _recording, "rerun"),
    "checkpoint": ("row.json", _checkpoint, None),
}


#: Families the crash test leaves out, with the reason.
NOT_CRASHED = {
    "recording": "rerun's file sink blocks forever (RecordingStream.save) when its write fails with EFBIG "
    "under pytest; it raised 'File-writer thread shut down prematurely' when run alone",
}


def _target(family: str, folder: Path) -> Path:
    """The file ``family`` writes in ``folder`` (the stored step's and stride's names from their data modules)."""
    if family == "step":
        from exo_bench.bench.studies.step import data

        return data.path_of("exo5-3d", folder)
    if family == "stride":
        from exo_bench.bench.studies.stride import data

        return data.path_of("human-2d", "human", 1.41, folder)
    return folder / FAMILIES[family][0]


def _needs(family: str) -> None:
    module = FAMILIES[family][2]
    if module:
        pytest.importorskip(module)


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_a_link_planted_where_a_writer_writes_is_refused_and_its_target_kept(family, tmp_path):
    """A symlink where the family's file goes is refused naming it; the file it points to is kept
    and no temporary is left (``save_mechanism`` and the CasADi ``save`` wrote through it)."""
    _needs(family)
    folder, victim = tmp_path / "out", tmp_path / "victim.txt"
    folder.mkdir()
    victim.write_text(OLD)
    link = _target(family, folder)
    os.symlink(victim, link)
    with pytest.raises(ValueError, match="symlink"):
        FAMILIES[family][1](folder)
    assert victim.read_text() == OLD and link.is_symlink()
    assert [p.name for p in folder.iterdir() if p.name.endswith(".tmp")] == []


def _crash_all(folder: str) -> None:
    """In the child: build, then write every family with a 64-byte file size limit; print what each raised."""
    import resource
    import signal

    import faulthandler

    faulthandler.dump_traceback_later(240, exit=True)  # a hang shows where
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG
    out = {}
    for family, (_, write, module) in FAMILIES.items():
        if family in NOT_CRASHED:
            continue
        if module:
            try:
                __import__(module)
            except ImportError:
                continue
        write(Path(folder) / "warm" / family)  # imports, numba and CasADi builds, before the limit
        resource.setrlimit(resource.RLIMIT_FSIZE, (64, resource.RLIM_INFINITY))
        try:
            write(Path(folder) / family)
            out[family] = "no error"
        except BaseException as e:  # noqa: BLE001 - reported to the parent
            out[family] = f"{type(e).__name__}: {e}"
        resource.setrlimit(resource.RLIMIT_FSIZE, (resource.RLIM_INFINITY, resource.RLIM_INFINITY))
    print(json.dumps(out))


def test_a_crash_mid_write_leaves_the_old_file_and_no_temporary(tmp_path):
    """With the file size limit hit part-way through, every family raises, the file there before
    is unchanged (never half-written) and no temporary is left (``save_mechanism`` left 64 bytes)."""
    for family in set(FAMILIES) - set(NOT_CRASHED):
        (tmp_path / family).mkdir()
        (tmp_path / "warm" / family).mkdir(parents=True)
        _target(family, tmp_path / family).write_text(OLD)
    code = f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); import test_writer_families as t; t._crash_all({str(tmp_path)!r})"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-6000:]
    raised = json.loads(r.stdout.strip().splitlines()[-1])
    assert "save_mechanism" in raised and "step" in raised, raised
    for family, what in raised.items():
        folder = tmp_path / family
        assert what != "no error", family
        assert _target(family, folder).read_text() == OLD, (family, what)
        assert sorted(p.name for p in folder.iterdir()) == [_target(family, folder).name], (family, what)
