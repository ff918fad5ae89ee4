"""``exo-bench mjcf`` predicts its memory before any work (issue 34, U7).

The MJCF text is built in O(n) memory (the dense joint map ``G``, ``nv x dof``, is never formed for
it: 447 GiB for a flat tree of 100,000 links); what MuJoCo allocates to compile the file grows as
``nv^2`` and is predicted by :func:`exo_bench.models.engines.mjcf.compile_bytes` (checked against MuJoCo's
own figure in tests/test_mujoco_drake.py), and refused in one line beyond ``--max-memory``; a tree
deeper than MuJoCo's parser reads is refused with the depth.
"""

from __future__ import annotations

import tracemalloc

import pytest
from cli_runs import run_cli

from exo_bench.models.engines import mjcf
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.mechanism.presets import chain


def _flat(n: int, dim: int = 2) -> Mechanism:
    """``n`` links all hanging from the support, each with a middle mass."""
    return Mechanism(dim=dim, g=9.81, parent=(-1,) * n, sign=(1,) * n, masses=((1.0, 1.0, 1.0),) * n, n=(0.5,) * n)


@pytest.mark.case("U7")
def test_the_mjcf_command_refuses_a_flat_tree_too_large_to_compile_before_any_work(tmp_path, monkeypatch):
    """`mjcf` of a 100,000-link flat tree is refused in one line, exit 2, with the predicted memory
    and the limit, before the MJCF is built (it tried to allocate 447 GiB)."""
    path = tmp_path / "flat.json"
    path.write_text(_flat(100_000).to_json(indent=None))

    def never(mech):
        raise AssertionError("the MJCF was built before the memory check")

    monkeypatch.setattr(mjcf, "to_mjcf", never)
    rc, out, err = run_cli(["mjcf", path, "--max-memory", "1T", "-o", tmp_path / "flat.xml"])
    assert rc == 2 and out == "" and err.count("\n") == 1 and "Traceback" not in err, err
    assert "100000 links, 300000 MuJoCo coordinates, 100000 ties" in err and "over the limit of 1,024.0 GiB" in err
    need = mjcf.compile_bytes(_flat(100_000))
    assert f"needs about {need / 2**30:,.1f} GiB" in err and not (tmp_path / "flat.xml").exists()


@pytest.mark.case("U7")
def test_the_mjcf_text_of_a_wide_tree_takes_memory_linear_in_its_links():
    """The MJCF of a 3,000-link flat tree is built with less than 40 MB allocated at the peak
    (the dense joint map it formed took 432 MB: 9,000 x 6,000 doubles)."""
    mech = _flat(3000)
    tracemalloc.start()
    try:
        text = mjcf.to_mjcf(mech)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 40e6, peak
    assert text.count("<body ") == 3 * 3000
    nv, neq = mjcf.mujoco_sizes(mech)
    qpos = text.split('qpos="')[1].split('"')[0].split()
    assert (nv, neq) == (9000, 3000) and len(qpos) == nv  # the keyframe: one value per MuJoCo coordinate


@pytest.mark.case("U7")
def test_the_mjcf_command_refuses_a_chain_deeper_than_mujocos_parser_naming_the_depth(tmp_path):
    """A chain of 249 3D links (its MJCF nests 501 elements; MuJoCo's parser reads 500) is refused
    up front in one line naming the depth and the limit."""
    path = tmp_path / "deep.json"
    path.write_text(chain(249, 3).to_json())
    rc, out, err = run_cli(["mjcf", path, "-o", tmp_path / "deep.xml"])
    assert rc == 2 and err.count("\n") == 1 and "nests 501 elements deep" in err and "at most 500" in err, err
    assert not (tmp_path / "deep.xml").exists()
