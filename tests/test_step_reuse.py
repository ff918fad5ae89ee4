"""Which stored step a step scene walks (issue 34: W7, S5).

A stored step is found by a key, the mechanism's name through the one file-name encoder
(:func:`exo_bench.models.files.file_stem`), inside the package's data folder, never by a path built
from a name; and it is reused only for the mechanism it was solved for, compared field by field
(dim, g, tree, signs, masses, fractions, link names) by a digest stored with the step, or, for a
step stored before the digest, against the preset it was solved for.
"""

import dataclasses
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from exo_bench.bench.studies.scenes import load_scene
from exo_bench.bench.studies.step import data, identity
from exo_bench.bench.studies.step.scene import load_motion
from exo_bench.models.files import file_stem
from exo_bench.models.mechanism.presets import exo5

SCENE = Path("scene.toml")
MOTION = {"kind": "step", "steps": 2}
EXO3 = exo5(3)


def _scaled_masses(mech, factor, link=None):
    masses = [tuple(m * (factor if link in (None, i) else 1.0) for m in ms) for i, ms in enumerate(mech.masses)]
    return mech.replace(masses=tuple(masses))


#: Mechanisms named exo5-3d, with the stored step's link names, that are not exo5-3d.
IMPOSTORS = {
    "masses x3": _scaled_masses(EXO3, 3.0),
    "another tree (trunk on the knee)": EXO3.replace(parent=(-1, 0, 1, 2, 0)),
    "swing leg not reversed": EXO3.replace(sign=(1, 1, 1, 1, 1)),
    "g on the moon": EXO3.replace(g=1.62),
    "other fractions": EXO3.replace(n=(0.5,) * 5),
    "the 2D exoskeleton named exo5-3d": exo5(2).replace(name="exo5-3d"),
}


@pytest.mark.case("W7")
@pytest.mark.parametrize("mech", IMPOSTORS.values(), ids=IMPOSTORS.keys())
def test_a_step_scene_refuses_another_mechanism_of_the_same_name(mech, tmp_path):
    """A step scene whose mechanism only shares the name of a stored step (masses tripled, another
    tree, other signs, g or fractions, another dimension) is refused in one line saying the stored
    step was solved for another mechanism and how to solve one."""
    assert mech.name == "exo5-3d" and mech != EXO3
    (tmp_path / "m.json").write_text(mech.to_json())
    toml = tmp_path / "impostor.toml"
    toml.write_text('mechanism = "m.json"\nmethods = ["recurrence"]\n[motion]\nkind = "step"\n')
    with pytest.raises(ValueError) as e:
        load_scene(toml)
    msg = str(e.value)
    assert "\n" not in msg and str(toml) in msg and "field 'mechanism'" in msg, msg
    assert "solved for another mechanism" in msg and "exo-bench gait --solve" in msg, msg


@pytest.mark.case("W7")
@settings(max_examples=25, deadline=None)
@given(
    link=st.integers(0, 4),
    factor=st.floats(0.25, 4.0).filter(lambda f: f != 1.0),
)
def test_any_change_of_one_links_masses_is_another_mechanism(link, factor):
    """Any change of one link's masses, however small, makes another mechanism: the stored step is
    refused for it, naming the link whose masses differ."""
    mech = _scaled_masses(EXO3, factor, link)
    if mech.masses == EXO3.masses:  # a factor within rounding of 1
        return
    with pytest.raises(ValueError, match=r"solved for another mechanism.*link %d" % (link + 1)):
        load_motion(SCENE, MOTION, mech)


@pytest.mark.case("W7")
def test_an_equal_mechanism_reuses_the_stored_step(tmp_path):
    """The preset, and the same mechanism read back from its JSON, walk the stored step."""
    for mech in (EXO3, type(EXO3).from_json(EXO3.to_json())):
        motion = load_motion(SCENE, MOTION, mech)
        assert motion["stored"].q.shape[1] == mech.dof
    # a step stored with its digest: reused for an equal mechanism under that name, refused for another
    stored = data.load(EXO3)
    solution = _as_solution(stored)
    path = data.save(solution, EXO3, folder=tmp_path)
    assert path.parent == tmp_path and path.name == "exo5-3d-step.npz"
    again = data.load(EXO3, folder=tmp_path)
    assert again.meta["mechanism_digest"] == identity.digest(EXO3)
    assert np.array_equal(again.q, stored.q)
    with pytest.raises(ValueError, match="solved for another mechanism.*masses"):
        data.load(IMPOSTORS["masses x3"], folder=tmp_path)
    with pytest.raises(
        ValueError, match=r"solved for another mechanism.*link 5 \('trunk'\): parent link 2 stored, link 1 here"
    ):
        data.load(IMPOSTORS["another tree (trunk on the knee)"], folder=tmp_path)


def _as_solution(stored):
    from exo_bench.bench.studies.step.problem import Solution

    fields = {f.name for f in dataclasses.fields(Solution)}
    kw = {k: getattr(stored, k) for k in fields if k != "stats"}
    return Solution(**kw, stats=stored.meta["solver"])


#: Names a step's key must never turn into a path: traversal, absolute paths, separators, NUL.
HOSTILE = ["../x", "../../x", "/abs/x.npz", "a/b", "..", ".", "x\0y", "..\\x", "/etc/passwd", "./exo5-3d", "~/x.npz"]


@pytest.mark.case("S5")
@settings(max_examples=60, deadline=None)
@given(name=st.one_of(st.sampled_from(HOSTILE), st.text(alphabet="./\\\0~abc-", min_size=1, max_size=12)))
def test_a_stored_steps_key_stays_in_the_data_folder(name):
    """A mechanism name becomes the stored step's file name through file_stem, inside the package's
    data folder (or is refused as a name): never a path of its own."""
    try:
        path = data.path_of(name)
    except ValueError as e:
        assert "name" in str(e)
        return
    assert path.parent == data.DATA and path.resolve().parent == data.DATA.resolve(), path
    assert path.name == file_stem(name) + "-step.npz" and not path.name.startswith(".")


@pytest.fixture
def planted(monkeypatch):
    """A data folder ``base/pkg/data`` holding the real exo5-3d step, and copies of it planted at
    ``base/pkg/x-step.npz``, ``base/x-step.npz``, ``base/x.npz`` and ``base/y-step.npz`` (a short
    ``base``, so that its absolute names are acceptable names)."""
    base = Path(tempfile.mkdtemp(prefix="s5", dir="/tmp"))
    folder = base / "pkg" / "data"
    folder.mkdir(parents=True)
    real = data.DATA / "exo5-3d-step.npz"
    for p in (folder / "exo5-3d-step.npz", base / "pkg" / "x-step.npz", base / "x-step.npz", base / "x.npz"):
        shutil.copy(real, p)
    shutil.copy(real, base / "y-step.npz")
    monkeypatch.setattr(data, "DATA", folder)
    yield base
    shutil.rmtree(base)


@pytest.mark.case("S5")
@pytest.mark.parametrize("name", ["../x", "../../x", "{base}/x.npz", "{base}/y", "{base}/../{base_name}/y"])
def test_a_planted_step_is_never_opened(name, planted, monkeypatch):
    """A mechanism named after a planted file (``../x``, ``../../x``, an absolute ``*.npz`` path or
    stem) does not load it: the name is looked up in the data folder, where no such step is stored."""
    name = name.format(base=planted, base_name=planted.name)
    try:
        mech = EXO3.replace(name=name)
    except ValueError as e:  # refused as a mechanism name: it never reaches a step scene
        assert "'name'" in str(e)
        return
    opened = []
    real_load = np.load
    monkeypatch.setattr(np, "load", lambda f, *a, **k: opened.append(Path(f)) or real_load(f, *a, **k))
    with pytest.raises(ValueError) as e:
        load_motion(SCENE, MOTION, mech)
    assert "no stored step" in str(e.value) and "\n" not in str(e.value)
    assert all(p.resolve().parent == data.DATA.resolve() for p in opened), opened
    assert load_motion(SCENE, MOTION, EXO3)["stored"].q.shape[1] == EXO3.dof  # the data folder's own step


def _rewrite_meta(path: Path, change) -> None:
    """Rewrite a stored step's meta through ``change(meta)`` (arrays kept)."""
    import json

    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files if k != "meta"}
        meta = json.loads(str(z["meta"]))
    change(meta)
    with open(path, "wb") as f:
        np.savez_compressed(f, meta=np.array(json.dumps(meta)), **arrays)


@pytest.mark.case("W7")
def test_a_stored_definition_must_match_its_digest_and_an_undigested_step_a_preset(tmp_path):
    """A stored step whose definition was edited (masses tripled, digest kept) is refused as not
    matching its digest, and one stored without a digest for a mechanism that is no exo5 preset
    is refused: nothing says what it was solved for."""
    path = data.save(_as_solution(data.load(EXO3)), EXO3, folder=tmp_path)

    def triple(meta):
        for link in meta["mechanism_definition"]["links"]:
            link["masses"] = [3 * m for m in link["masses"]]

    _rewrite_meta(path, triple)
    with pytest.raises(ValueError, match="mechanism_definition'.*does not match"):
        data.load(EXO3, folder=tmp_path)
    with pytest.raises(ValueError, match="mechanism_definition'.*does not match"):
        data.load(IMPOSTORS["masses x3"], folder=tmp_path)
    mine = EXO3.replace(name="my-exo")
    path = data.save(_as_solution(data.load(EXO3)), mine, folder=tmp_path)
    _rewrite_meta(path, lambda meta: [meta.pop(k) for k in ("mechanism_digest", "mechanism_definition")])
    with pytest.raises(ValueError, match="field 'meta.mechanism': expected the preset .* got 'my-exo'"):
        data.load(mine, folder=tmp_path)
