"""The two engines as peers, ``mujoco`` and ``drake``, and the MJCF export, against every other method.

Agreement is within the error model of tests/conftest.py (MuJoCo with its com-based term,
:func:`conftest.com_frame_scale`) on seeded random trees in 2D and 3D (random signs, several roots),
with every rod vertical and with every length zero; the exported MJCF's bodies sit where eq. (7)
puts the point masses. Without the extra ``[peers]`` every test here is skipped with the reason.
"""

import importlib.util
import subprocess
import sys

import numpy as np
import pytest
from cli_runs import cli_process
from conftest import assert_forces_agree, assert_mass_matrices_agree

from exo_bench.api import prepare
from exo_bench.models.mechanism.kinematics import point_mass_positions
from exo_bench.models.engines.mjcf import joint_map, to_mjcf
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5, fig2b, random_tree

ENGINES = {"mujoco": "mujoco", "drake": "pydrake"}


def _need(method: str) -> None:
    if importlib.util.find_spec(ENGINES[method]) is None:
        reason = f"{method}: not installed: pip install 'exo-bench[peers]' to run the {method} peer's tests"
        print(f"skipped: {reason}")
        pytest.skip(reason)


TREES = [(n, d, seed) for d in (2, 3) for n, seed in [(1, 40), (2, 41), (3, 42), (5, 43), (8, 44), (12, 45)]]
#: lagrange (sympy) derives only the small trees in reasonable time
LAGRANGE_N = 3


def _peers(method, mech):
    others = ["pinocchio", "matrix-factored", "matrix", "recurrence"] + (
        ["lagrange"] if mech.nlinks <= LAGRANGE_N else []
    )
    return others + [m for m in ENGINES if m != method and importlib.util.find_spec(ENGINES[m]) is not None]


def _special(mech, q, case):
    n = mech.nlinks
    q = q.copy()
    if case == "vertical":  # every rod vertical: psi = +-pi/2 in 3D, phi = +-pi/2 in 2D
        block = slice(n, 2 * n) if mech.dim == 3 else slice(0, n)
        q[:, block] = np.where(np.arange(q.shape[0])[:, None] % 2 == 0, np.pi / 2, -np.pi / 2)
    elif case == "zero-length":
        q[:, -n:] = 0.0
    return q


@pytest.mark.parametrize("method", list(ENGINES))
@pytest.mark.parametrize("case", ["random", "vertical", "zero-length"])
@pytest.mark.parametrize("n,dim,seed", TREES)
def test_forces_agree_with_every_other_method(method, case, n, dim, seed):
    _need(method)
    mech = random_tree(n, dim, seed)
    q, qd, qdd = random_states(mech, 6, seed)
    q = _special(mech, q, case)
    tau = prepare(mech, method).inverse_dynamics(q, qd, qdd)
    for other in _peers(method, mech):
        ref = prepare(mech, other).inverse_dynamics(q, qd, qdd)
        assert_forces_agree(
            tau, ref, mech, q, qd, qdd, what=f"{method} vs {other} ({case})", com_frame="mujoco" in (method, other)
        )


@pytest.mark.parametrize("method", list(ENGINES))
@pytest.mark.parametrize("n,dim,seed", TREES[1::2])
def test_mass_matrix_and_bias_agree(method, n, dim, seed):
    """``M`` (MuJoCo's CRB by mj_fullM, Drake's CalcMassMatrix) against Pinocchio's CRBA and
    lagrange's; ``h`` against Pinocchio's nonLinearEffects; and ``M qdd + h`` is the method's RNE."""
    _need(method)
    mech = random_tree(n, dim, seed)
    q, qd, qdd = random_states(mech, 5, seed)
    model = prepare(mech, method)
    M, h = model.mass_matrix(q), model.bias_forces(q, qd)
    com = method == "mujoco"
    pin = prepare(mech, "pinocchio")
    assert_mass_matrices_agree(M, pin.mass_matrix(q), mech, q, what=f"{method} M vs pinocchio", com_frame=com)
    if n <= LAGRANGE_N:
        assert_mass_matrices_agree(M, prepare(mech, "lagrange").mass_matrix(q), mech, q, com_frame=com)
    assert_forces_agree(h, pin.bias_forces(q, qd), mech, q, qd, None, what=f"{method} h", com_frame=com)
    assert_forces_agree(
        np.einsum("sij,sj->si", M, qdd) + h,
        model.inverse_dynamics(q, qd, qdd),
        mech,
        q,
        qd,
        qdd,
        k=16,
        what=f"{method} M qdd + h",
        com_frame=com,
    )  # both sides rounded: twice K


@pytest.mark.parametrize("method", list(ENGINES))
def test_one_sample_in_one_sample_out_and_batches_in_chunks(method):
    _need(method)
    mech = exo5(3)
    q, qd, qdd = random_states(mech, 7, 3)
    model = prepare(mech, method)
    tau = model.inverse_dynamics(q, qd, qdd)
    assert np.array_equal(model.inverse_dynamics(q[2], qd[2], qdd[2]), tau[2])
    model.chunk_samples = 3
    assert np.array_equal(model.inverse_dynamics(q, qd, qdd), tau)
    out = np.empty(mech.dof)
    assert model.inverse_dynamics(q[0], qd[0], qdd[0], check=False, out=out) is out and np.array_equal(out, tau[0])


def test_mujoco_rne_stages_equal_mj_inverse_with_constraints_off():
    """The staged RNE of the backend (kinematics, com, rne) is what MuJoCo's own mj_inverse returns
    once every constraint, passive force and armature is off (mj_inverse adds ``M qacc`` by mj_mulM to
    the bias of its RNE: other roundings of the same com-based terms). mj_inverse also factorises
    ``M``, singular where an undo hinge and an elevation hinge align: its warning is silenced here."""
    _need("mujoco")
    import mujoco

    from exo_bench.models.engines.mujoco_backend import load_model

    mech = random_tree(6, 3, 7)
    q, qd, qdd = random_states(mech, 4, 7)
    mm = load_model(mech)
    data = mujoco.MjData(mm.model)
    tau = prepare(mech, "mujoco").inverse_dynamics(q, qd, qdd)
    inv = np.empty_like(tau)
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda msg: None)
    try:
        for s in range(q.shape[0]):
            data.qpos[:], data.qvel[:], data.qacc[:] = mm.G @ q[s], mm.G @ qd[s], mm.G @ qdd[s]
            mujoco.mj_inverse(mm.model, data)
            inv[s] = data.qfrc_inverse @ mm.G
    finally:
        mujoco.set_mju_user_warning(previous)
    assert_forces_agree(inv, tau, mech, q, qd, qdd, com_frame=True)


@pytest.mark.parametrize(
    "mech", [exo5(3), exo5(2), fig2b(3), random_tree(9, 3, 8), random_tree(9, 2, 9)], ids=lambda m: m.name
)
def test_exported_mjcf_bodies_are_the_point_masses(mech, tmp_path):
    """The file written by ``exo-bench mjcf``, loaded by ``MjModel.from_xml_path`` as a user would,
    puts every point-mass body where eq. (7) does, to 1e-12 m, at q_mj = G q; its joints are those of
    joint_map in MuJoCo's order, and its masses (after the compiler's floors) are the mechanism's."""
    _need("mujoco")
    import mujoco

    from exo_bench.bench.cli import main

    path = tmp_path / "m.xml"
    assert (
        main(
            [
                "mjcf",
                mech.name if mech.name in ("exo5-3d", "exo5-2d", "fig2b-3d") else _json(mech, tmp_path),
                "-o",
                str(path),
            ]
        )
        == 0
    )
    model = mujoco.MjModel.from_xml_path(str(path))
    jm = joint_map(mech)
    assert [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(model.njnt)] == list(jm.joints)
    assert model.nv == jm.G.shape[0] and model.nq == model.nv
    body = lambda name: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    named = {x for names in jm.bodies for x in names if x is not None}
    assert named == {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in range(1, model.nbody)}
    for i, names in enumerate(jm.bodies):
        for name, m in zip(names, mech.masses[i]):
            if name is not None:
                assert model.body_mass[body(name)] == max(m, 1e-12)
    q, _, _ = random_states(mech, 20, 5)
    expect = point_mass_positions(mech, q)
    data = mujoco.MjData(model)
    for s in range(q.shape[0]):
        data.qpos[:] = jm.G @ q[s]
        mujoco.mj_kinematics(model, data)
        for i, names in enumerate(jm.bodies):
            for beta, name in enumerate(names):
                if name is not None:
                    assert np.abs(data.xpos[body(name)][: mech.dim] - expect[s, i, beta]).max() <= 1e-12
                    if mech.dim == 2:
                        assert data.xpos[body(name)][2] == 0.0


def _json(mech, tmp_path):
    p = tmp_path / "mech.json"
    p.write_text(mech.to_json())
    return str(p)


@pytest.mark.parametrize("n,dim,seed", [(7, 3, 50), (7, 2, 51)])
def test_drake_bodies_are_the_point_masses(n, dim, seed):
    _need("drake")
    from exo_bench.models.engines.drake_backend import body_positions

    mech = random_tree(n, dim, seed)
    q, _, _ = random_states(mech, 10, seed)
    assert np.abs(body_positions(mech, q) - point_mass_positions(mech, q)).max() <= 1e-12


def test_mjcf_ties_and_map_are_what_the_paper_coordinates_say():
    """Without MuJoCo: G's rows are 1, -1 and n exactly where the module docstring says, and the
    file's equality ties carry the same coefficients."""
    mech = random_tree(6, 3, 60)
    jm = joint_map(mech)
    text = to_mjcf(mech)
    n = mech.nlinks
    for r, name in enumerate(jm.joints):
        k = int(name[1 : name.index("_")]) - 1
        kind = name.split("_")[1]
        row = np.zeros(mech.dof)
        p = mech.parent[k]
        if kind == "undo":
            row[n + p] = -1.0
            assert f'joint1="{name}" joint2="L{p + 1}_psi" polycoef="0 -1 0 0 0"' in text
        elif kind == "phi":
            row[k] = 1.0
            if p >= 0:
                row[p] = -1.0
        elif kind == "psi":
            row[n + k] = 1.0
        elif kind == "len":
            row[2 * n + k] = 1.0
        else:
            row[2 * n + k] = mech.n[k]
            assert f'joint1="{name}" joint2="L{k + 1}_len" polycoef="0 {mech.n[k]!r} 0 0 0"' in text
        assert np.array_equal(jm.G[r], row), name


# ------------------------------------------------------------------ bad input, missing extras
def _cli(*args, hide=()):
    code = (
        "import sys\n"
        + "".join(f"sys.modules[{m!r}] = None\n" for m in hide)
        + "from exo_bench.bench.cli import main\nsys.exit(main(sys.argv[1:]))"
    )
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=1800)


def test_mjcf_bad_input_is_one_line_and_exit_2(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    cases = [
        (["mjcf", "no-such-mechanism", "-o", str(tmp_path / "a.xml")], (), "not a preset"),
        (["mjcf", "exo5-3d", "-o", str(blocker / "a.xml")], (), ""),
        (["mjcf", "exo5-3d", "-o", str(tmp_path)], (), "folder"),
        (["mjcf", "exo5-3d", "-o", str(tmp_path / "b.xml")], ("mujoco",), "exo-bench[peers]"),
    ]
    for args, hide, words in cases:
        r = _cli(*args, hide=hide)
        assert r.returncode == 2, (args, r.stderr)
        assert len(r.stderr.strip().splitlines()) == 1 and r.stderr.startswith("exo-bench: error:"), r.stderr
        assert words in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "a.xml").exists() and not (tmp_path / "b.xml").exists()
    r = _cli("mjcf", "exo5-2d", "--no-check", "-o", str(tmp_path / "c.xml"), hide=("mujoco",))
    assert r.returncode == 0 and (tmp_path / "c.xml").read_text() == to_mjcf(exo5(2))


@pytest.mark.parametrize("method,module", [("mujoco", "mujoco"), ("drake", "pydrake")])
def test_missing_engine_is_a_value_error_naming_the_extra(method, module):
    code = (
        f"import sys; sys.modules[{module!r}] = None\n"
        "from exo_bench import prepare, presets\n"
        f"try:\n    prepare(presets.exo5(dim=3), {method!r})\n"
        "except ValueError as e:\n    print(e)\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=1800)
    assert "pip install 'exo-bench[peers]'" in r.stdout and method in r.stdout, r.stdout + r.stderr
    r = _cli("inverse", "exo5-3d", "nothing.json", "--method", method, hide=(module,))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("n,dim,seed,sample_seed", [(5, 2, 124, 24), (10, 3, 149, 49)])
def test_mujocos_com_frame_term_is_needed_and_enough(n, dim, seed, sample_seed):
    """MuJoCo's mass matrix exceeds the joint-frame error model (K eps * scale) on these seeded trees,
    found among 60; with :func:`conftest.com_frame_scale` (the rounding of its com-based frame) it is
    within it. Drake, which works at the joints, needs no such term there."""
    _need("mujoco")
    from conftest import K, assert_close, com_frame_scale, mass_matrix_scale

    mech = random_tree(n, dim, seed)
    q, _, _ = random_states(mech, 8, sample_seed)
    M, ref = prepare(mech, "mujoco").mass_matrix(q), prepare(mech, "pinocchio").mass_matrix(q)
    with pytest.raises(AssertionError, match="disagreement"):
        assert_close(M, ref, mass_matrix_scale(mech, q), K)
    assert_close(M, ref, mass_matrix_scale(mech, q) + com_frame_scale(mech, q, matrix=True), K)
    if importlib.util.find_spec("pydrake") is not None:
        assert_close(prepare(mech, "drake").mass_matrix(q), ref, mass_matrix_scale(mech, q), K)


def _with_zero_masses(mech):
    """Zero start, middle and end masses on some links (links 1, 3, 4, 5, and link 6 a leaf with its
    start mass alone): MuJoCo's compiler floors them at 1e-12 (models/engines/mjcf.py), the backend puts the
    zeros back; a zero middle mass has no body or joint."""
    masses = [list(m) for m in mech.masses]
    masses[0][0] = 0.0
    masses[2][1] = 0.0
    masses[3][2] = 0.0
    masses[4][1] = 0.0
    masses[5][1] = masses[5][2] = 0.0  # a leaf rod with its start mass only: its length force is exactly 0
    return mech.replace(masses=tuple(tuple(m) for m in masses), name=mech.name + "-zeros")


@pytest.mark.parametrize("method", list(ENGINES))
@pytest.mark.parametrize("dim", [2, 3])
def test_zero_point_masses_are_exactly_zero(method, dim):
    """A 1e-12 kg floor left in place would move the forces by about 1e-12 relative, thousands of
    eps * scale: agreement within K shows the zeros are exact, and the joint map has no middle slide
    where the middle mass is zero."""
    _need(method)
    mech = _with_zero_masses(random_tree(6, dim, 70 + dim))
    q, qd, qdd = random_states(mech, 6, 3)
    tau = prepare(mech, method).inverse_dynamics(q, qd, qdd)
    for other in ("pinocchio", "matrix-factored"):
        assert_forces_agree(
            tau,
            prepare(mech, other).inverse_dynamics(q, qd, qdd),
            mech,
            q,
            qd,
            qdd,
            com_frame=method == "mujoco",
            what=f"{method} vs {other}",
        )
    assert np.array_equal(tau[:, -1], np.zeros(len(q)))  # the massless leaf rod: no force along it, exactly
    if method == "drake":  # its bodies: each point mass where eq. (7) puts it, each with its mass
        from exo_bench.models.engines.drake_backend import body_positions, build_plant

        assert np.abs(body_positions(mech, q) - point_mass_positions(mech, q)).max() <= 1e-12
        dp = build_plant(mech)
        for i, names in enumerate(dp.bodies):
            assert names == (f"L{i + 1}_frame", f"L{i + 1}_mid" if mech.masses[i][1] > 0 else None, f"L{i + 1}_end")
            for name, m in zip(names, mech.masses[i]):
                if name is not None:
                    assert dp.plant.GetBodyByName(name).default_mass() == m
    jm = joint_map(mech)
    assert "L3_mid" not in jm.joints and "L5_mid" not in jm.joints and "L2_mid" in jm.joints
    assert jm.bodies[2][1] is None and jm.bodies[1][1] == "L2_mid"


def test_exported_mjcf_with_zero_masses_loads_and_places_its_bodies(tmp_path):
    _need("mujoco")
    test_exported_mjcf_bodies_are_the_point_masses(_with_zero_masses(random_tree(6, 3, 73)), tmp_path)


def test_the_mjcf_nesting_depth_is_the_one_mujocos_parser_refuses_beyond_its_limit():
    """A chain nests two bodies per link: MuJoCo's XML parser (tinyxml2) reads 248 links and refuses
    249 ("Element nesting is too deep"). The suite predicts that depth (models.mjcf.nesting_depth),
    the `mujoco` method refuses deeper trees with the reason before any work (the benchmark row
    skips with it), and the export itself builds any depth without recursion (a 1000-link chain
    raised RecursionError in the full sweep)."""
    from exo_bench.models.engines.mjcf import MJCF_MAX_DEPTH, MjcfTooDeep, nesting_depth
    from exo_bench.models.mechanism.presets import chain

    assert nesting_depth(chain(248, 3)) <= MJCF_MAX_DEPTH < nesting_depth(chain(249, 3))
    assert to_mjcf(chain(1000, 2)).count("<body ") == 3000  # start, end and middle: no RecursionError
    with pytest.raises(MjcfTooDeep, match=r"'chain249-3d' nests 501 elements deep; .* at most 500") as e:
        prepare(chain(249, 3), "mujoco")
    assert e.value.skip_reason == str(e.value)
    _need("mujoco")
    import mujoco

    mujoco.MjModel.from_xml_string(to_mjcf(chain(248, 3)))  # the deepest MuJoCo reads
    with pytest.raises(ValueError, match="nesting is too deep"):
        mujoco.MjModel.from_xml_string(to_mjcf(chain(249, 3)))


def test_the_mjcf_command_refuses_a_tree_too_deep_for_mujoco_in_one_line(tmp_path):
    from exo_bench.models.mechanism.presets import chain

    path = tmp_path / "deep.json"
    path.write_text(chain(249, 3).to_json())
    r = cli_process("mjcf", path, "-o", tmp_path / "deep.xml")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr
    assert "nests 501 elements deep" in r.stderr and not (tmp_path / "deep.xml").exists()


@pytest.mark.case("S1")
def test_mujoco_forces_agree_on_hostile_names():
    """MuJoCo compiles the MJCF of hostile mechanism and link names (XML, LaTeX, C and Python
    metacharacters, `--`, comment ends, an injected body or include) with exactly the bodies of a
    plain name, and its forces agree with matrix-factored's (a name once added a 50 kg body)."""
    from hypothesis import HealthCheck, given, settings
    from test_hostile_names import ACCEPTED

    _need("mujoco")
    from exo_bench.models.engines.mujoco_backend import load_model

    plain = fig2b(2).replace(name="plain", names=("a", "b"))

    @given(name=ACCEPTED, link=ACCEPTED)
    @settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
    def check(name, link):
        mech = plain.replace(name=name, names=(link, name))
        model, ref = load_model(mech).model, load_model(plain).model
        assert (model.nbody, model.njnt, model.nv) == (ref.nbody, ref.njnt, ref.nv)
        assert abs(model.body_mass.sum() - mech.total_mass) < 1e-12
        q, qd, qdd = random_states(mech, 6, 7)
        tau = prepare(mech, "mujoco").inverse_dynamics(q, qd, qdd)
        ref_tau = prepare(mech, "matrix-factored").inverse_dynamics(q, qd, qdd)
        assert_forces_agree(tau, ref_tau, mech, q, qd, qdd, com_frame=True, what="mujoco vs matrix-factored")

    check()


@pytest.mark.case("U7")
def test_mujoco_compile_memory_is_predicted_from_above():
    """The memory predicted for compiling an MJCF (models.mjcf.compile_bytes) bounds MuJoCo's own
    arena (mjModel.narena) from above, within 1.6 times, on chains, flat and random trees."""
    _need("mujoco")
    from exo_bench.models.mechanism.mechanism import Mechanism
    from exo_bench.models.engines.mjcf import compile_bytes, mujoco_sizes
    from exo_bench.models.engines.mujoco_backend import compile_mjcf
    from exo_bench.models.mechanism.presets import chain

    flat = lambda n, d, m1: Mechanism(d, 9.81, (-1,) * n, (1,) * n, ((1.0, m1, 1.0),) * n, (0.5,) * n)  # noqa: E731
    mechs = [chain(n, d) for n in (1, 20, 120) for d in (2, 3)] + [random_tree(60, d, 3) for d in (2, 3)]
    mechs += [flat(n, d, m1) for n in (10, 200) for d in (2, 3) for m1 in (0.0, 1.0)]
    for mech in mechs:
        model = compile_mjcf(to_mjcf(mech))
        assert mujoco_sizes(mech) == (model.nv, model.neq), mech.name
        assert model.narena <= compile_bytes(mech) <= 1.6 * model.narena, (mech.name, model.narena)
