"""Hostile names through every exporter: a name is data, never code (issue 34: S1, S2, W10, T2, U2).

A hypothesis strategy draws names from the metacharacters of XML, LaTeX, C, Python and Markdown,
``--``, comment and string ends, surrogates, control and bidi characters. What
:mod:`exo_bench.models.files` refuses is refused at the edge (a ValueError naming the field; the CLI
one line, exit 2). Every other name goes into the MJCF and URDF (they parse, with exactly the
bodies and joints of the mechanism, and Pinocchio's forces agree with matrix-factored's), the
LaTeX (no control sequence comes from it), the C (compiles) and the Python module (imports and
runs); the encoders of :mod:`exo_bench.models.files` give each name back exactly.
MuJoCo's forces on hostile names: tests/test_mujoco_drake.py (CI's engine step).
"""

from __future__ import annotations

import ast
import dataclasses
import functools
import importlib.util
import json
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest
from conftest import assert_forces_agree
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from exo_bench.api import prepare
from exo_bench.bench.cli import equations as beq
from exo_bench.matrix_method.export import code as export_code
from exo_bench.models import files as enc
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.engines.mjcf import to_mjcf
from exo_bench.models.gait.motion import random_states
from exo_bench.models.files import name_problem
from exo_bench.models.mechanism.presets import fig2a
from exo_bench.models.engines.urdf import to_urdf

PIECES = [
    *'<>&"\'-\\{}$%#^_~|*/?`[]()!;:=@.,+',
    "--", "-->", "<!--", "*/", "/*", "??/", "???/", "*/*", '"""', "'''", "]]>", "&amp;", "&#x41;", "$$", "```", "\\\\",
    "\\input{/etc/hostname}", "\\immediate\\write18{id}", '--><include file="/etc/passwd"/><!--',
    '<body name="X"><inertial pos="0 0 0" mass="50" diaginertia="1 1 1"/></body>', "</robot>",
    "numpy", "math", "os", "sys", "stdio", "import", "int", "#include <stdlib.h>", "__init__", "x",
    "é", "中", "😀", "\u202e", "\u2066", "\u200b", "\ud800", "\udfff", "\x00", "\x1b", "\x85", "\u2028", " ", "\t",
]  # fmt: skip
NAMES = st.lists(st.sampled_from(PIECES), min_size=1, max_size=6).map("".join)
ACCEPTED = NAMES.filter(lambda s: name_problem(s) is None)
REFUSED = NAMES.filter(lambda s: name_problem(s) is not None)
FEW = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])


def _named(name: str, link: str) -> Mechanism:
    return fig2a(2).replace(name=name, names=(link, name))


# ------------------------------------------------------------------------------ refused at the edge
@pytest.mark.case("U2", "T2")
@given(bad=REFUSED | st.sampled_from([0, 1.5, None, {"a": 1}, ["x"], b"x", True]))
@FEW
def test_names_the_name_check_refuses_are_refused_naming_the_field(bad):
    """A mechanism or link name with a NUL, surrogate, bidi or control character, or one that is no
    string, is refused with a ValueError naming the field (mechanism: 'name'; link: its number)."""
    for make, where in [
        (lambda: fig2a(2).replace(name=bad), "field 'name'"),
        (lambda: fig2a(2).replace(names=("hip", bad)), "link 2"),
        (lambda: Mechanism.from_dict({**fig2a(2).to_dict(), "name": bad}, "m.json"), "m.json: field 'name'"),
    ]:
        with pytest.raises(ValueError, match=re.escape(where)) as e:
            make()
        assert "field 'name'" in str(e.value) and "expected" in str(e.value)


@pytest.mark.case("U2", "T2")
@pytest.mark.parametrize("bad", ["\ud800", "a\x00b", "x\u202ey", 7, {"a": 1}, " pad"])
@pytest.mark.parametrize("command", [["urdf"], ["mjcf", "--no-check"], ["equations", "--format", "c"]])
def test_the_cli_refuses_a_bad_mechanism_name_in_one_line(bad, command, tmp_path):
    """The CLI refuses a mechanism name that the name check refuses in one line, exit 2, naming the
    file and the field (a surrogate gave 'internal error: TypeError' in mjcf)."""
    from cli_runs import run_cli

    path = tmp_path / "m.json"
    path.write_text(json.dumps({**fig2a(2).to_dict(), "name": bad}))  # ensure_ascii: a lone surrogate as \ud800
    rc, out, err = run_cli([command[0], path, *command[1:], "-o", tmp_path / "out"])
    assert rc == 2 and out == "" and err.count("\n") == 1 and "Traceback" not in err, err
    assert f"{path}: field 'name': expected" in err and "internal error" not in err
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


# ------------------------------------------------------------------------------ the encoders
@given(name=ACCEPTED)
@FEW
def test_each_encoder_gives_the_name_back_exactly(name):
    """Every encoder's output reads back as the name in its own language (XML, LaTeX, Markdown,
    C comment, Python), so escaping loses nothing."""
    assert ET.fromstring(f"<a b={enc.xml_attr(name)}/>").get("b") == name
    parser = ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))
    parser.feed(f"<a><!-- {enc.xml_comment(name)} --></a>")
    assert json.loads(parser.close()[0].text.strip()) == name
    back = {v: k for k, v in enc.LATEX_ESCAPES.items()}
    pattern = "|".join(re.escape(v) for v in sorted(back, key=len, reverse=True))
    assert re.sub(pattern, lambda m: back[m.group(0)], enc.latex_text(name)) == name
    assert re.sub(r"\\(.)", r"\1", enc.markdown_text(name)) == name
    code = enc.markdown_code(name)
    fence = re.match("`+", code).group(0)
    inner = code[len(fence) : -len(fence)]
    assert (inner[1:-1] if inner.startswith(" ") and inner.endswith(" ") else inner) == name
    assert "*/" not in enc.c_comment(name) and "/*" not in enc.c_comment(name) and "??" not in enc.c_comment(name)
    assert ast.literal_eval(enc.python_string(name)) == name
    assert ast.literal_eval('"""' + enc.python_docstring(name) + '"""') == name


@pytest.mark.case("W10")
@given(name=ACCEPTED | st.sampled_from(["numpy", "math", "os", "stdio", "string", "int", "if", "_MATH_H", "3d", "sys"]))
@FEW
def test_generated_module_and_header_names_never_shadow_what_they_import(name):
    """A mechanism named numpy gets module m_numpy.py and one named math gets m_math.h: a generated
    module or header never takes the name of a standard module or header, or of numpy."""
    module, prefix = enc.python_module_name(name), enc.c_identifier(name)
    assert module.isidentifier() and module.isascii() and not module.startswith("_")
    assert module not in sys.stdlib_module_names and module not in sys.builtin_module_names and module != "numpy"
    assert re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", prefix) and prefix.lower() not in enc.C_STANDARD_HEADERS
    files = beq.render(fig2a(2).replace(name=name), "python") | beq.render(fig2a(2).replace(name=name), "c")
    assert set(files) == {f"{module}.py", f"{prefix}.h", f"{prefix}.c"}


# ------------------------------------------------------------------------------ XML: URDF and MJCF
def _xml_names(text: str) -> tuple[ET.Element, list[str]]:
    """The root and the texts of every comment."""
    parser = ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))
    parser.feed(text)
    root = parser.close()
    return root, [c.text for c in root.iter() if c.tag is ET.Comment]


def _shape(root: ET.Element) -> list[tuple]:
    """Every element's tag and attributes but the model's own name: what the file builds."""
    return [
        (e.tag, sorted((k, v) for k, v in e.attrib.items() if e is not root))
        for e in root.iter()
        if e.tag is not ET.Comment
    ]


@pytest.mark.case("S1", "T2")
@given(name=ACCEPTED, link=ACCEPTED)
@FEW
def test_urdf_and_mjcf_parse_with_exactly_the_mechanisms_bodies(name, link):
    """A hostile mechanism or link name stays data in the MJCF and URDF: both parse, hold exactly
    the bodies and joints of the same mechanism with a plain name, and give the names back."""
    mech, plain = _named(name, link), _named("plain", "plain")
    for write, attr in [(to_urdf, "name"), (to_mjcf, "model")]:
        root, comments = _xml_names(write(mech))
        ref, _ = _xml_names(write(plain))
        assert _shape(root) == _shape(ref) and root.get(attr) == name
        assert not root.findall(".//include")
        named = [c for c in comments if c.strip().startswith("link ") or c.strip().startswith('"')]
        decoded = [json.loads(m.group(0)) for c in named for m in re.finditer(r'"(?:[^"\\]|\\.)*"', c)]
        assert link in decoded and name in decoded


@pytest.mark.case("S1")
@given(name=ACCEPTED, link=ACCEPTED)
@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
def test_pinocchio_reads_the_urdf_of_hostile_names_and_its_forces_agree(name, link):
    """Pinocchio builds the URDF of a hostile name and its forces agree with matrix-factored's
    within the error model (a name cannot add a body or a mass)."""
    pin = pytest.importorskip("pinocchio")
    mech = _named(name, link)
    model = pin.buildModelFromXML(to_urdf(mech), mimic=True)
    assert model.nv == mech.dof and abs(sum(i.mass for i in model.inertias) - mech.total_mass) < 1e-12
    q, qd, qdd = random_states(mech, 8, 3)
    tau = prepare(mech, "pinocchio").inverse_dynamics(q, qd, qdd)
    assert_forces_agree(tau, prepare(mech, "matrix-factored").inverse_dynamics(q, qd, qdd), mech, q, qd, qdd)


# ------------------------------------------------------------------------------ LaTeX and Markdown
_CS = re.compile(r"\\(?:[A-Za-z]+|.)")


@functools.cache
def _plain_latex() -> dict[str, str]:
    return beq.render(fig2a(2).replace(name="plain"), "latex")


@pytest.mark.case("S2")
@given(name=ACCEPTED)
@FEW
def test_the_latex_holds_no_control_sequence_from_a_name(name):
    """The .tex of a hostile mechanism name holds the control sequences of a plain name's and the
    escapes of text mode only (no \\input, \\write18, math shift or group from the name), and
    its braces balance."""
    files = beq.render(fig2a(2).replace(name=name), "latex")
    tex = next(v for k, v in files.items() if k.endswith(".tex"))
    plain = next(v for k, v in _plain_latex().items() if k.endswith(".tex"))
    allowed = set(_CS.findall(plain)) | {_CS.match(v).group(0) for v in enc.LATEX_ESCAPES.values() if "\\" in v}
    assert set(_CS.findall(tex)) <= allowed
    unescaped = re.sub(r"\\[{}]", "", re.sub(r"\\\\", "", tex))
    assert unescaped.count("{") == unescaped.count("}") and enc.latex_text(name) in tex
    assert tex.count("$") - tex.count(r"\$") == plain.count("$") - plain.count(r"\$")
    md = next(v for k, v in files.items() if k.endswith(".md"))
    assert enc.markdown_text(name) in md or enc.markdown_code(name) in md


# ------------------------------------------------------------------------------ C and Python
@functools.cache
def _equations():
    return export_code.equation_set(fig2a(2))


@pytest.mark.case("W10", "S1")
@given(name=ACCEPTED)
@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
def test_generated_c_compiles_and_python_imports_and_runs(name, tmp_path_factory):
    """The C of a hostile name compiles warning-free and its Python module imports, runs and keeps
    the name exactly (MECHANISM), under a module name that shadows nothing."""
    mech = fig2a(2).replace(name=name)
    es = dataclasses.replace(_equations(), mechanism=mech)  # the equations do not depend on the name
    d = tmp_path_factory.mktemp("gen")
    module = enc.python_module_name(name)
    (d / f"{module}.py").write_text(export_code.python_module(es, "0"), encoding="utf-8")
    spec = importlib.util.spec_from_file_location(module, d / f"{module}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.MECHANISM == name
    q, qd, qdd = random_states(mech, 4, 5)
    ref = prepare(fig2a(2), "matrix-factored").inverse_dynamics(q, qd, qdd)
    assert_forces_agree(mod.inverse_dynamics(q, qd, qdd), ref, mech, q, qd, qdd)
    cc = shutil.which("gcc") or shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler")
    prefix, h, c = export_code.c_sources(es, "0")
    (d / f"{prefix}.h").write_text(h, encoding="utf-8")
    (d / f"{prefix}.c").write_text(c, encoding="utf-8")
    flags = export_code.C_FLAGS.split()
    r = subprocess.run([cc, *flags, "-fsyntax-only", f"{prefix}.c"], cwd=d, capture_output=True, text=True)
    assert r.returncode == 0 and r.stderr == "", r.stderr
