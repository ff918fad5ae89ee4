"""Eq. (5) / (17) as code to take away: a standalone numpy module and C99 source, with CSE.

The equations are the matrix method's own (:func:`exo_bench.matrix_method.symbolic.compose_equations` and
:func:`exo_bench.matrix_method.symbolic.matrices`): ``tau`` (inverse dynamics), the mass matrix ``M`` (row
block ``k``, column block ``c`` is the matrix multiplying the second derivatives of block ``c``,
:data:`exo_bench.models.states.states.ACCELERATION`) and the bias forces ``h = tau(qdd = 0)``. Each function
is one common-subexpression elimination (``sympy.cse``) of its outputs, printed

* :func:`python_module`: one module importing numpy only (its file: :func:`module_name`), ``inverse_dynamics(q, qd, qdd)``,
  ``mass_matrix(q)``, ``bias_forces(q, qd)`` on ``(samples, dof)`` (or ``(dof,)``) arrays;
* :func:`c_sources`: a C99 header and source, the same three functions for one sample on plain
  arrays, inputs then output, no allocation and no global state (sympy's C99 code printer).

Numbers: with numeric parameters every coefficient is an exact Rational (the mechanism's floats
composed exactly); it is printed as the nearest double (17 significant digits), so each
coefficient carries at most half an ulp of rounding before the evaluation's own. With
``symbolic_parameters=True`` the masses ``m{i}_{b}``, fractions ``n{i}`` and ``g`` stay symbols
and every function takes them as one more input, ``params`` (order: :func:`parameter_symbols`),
whose default in Python is the mechanism's values.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import sympy as sp
from sympy.printing.c import C99CodePrinter
from sympy.printing.numpy import NumPyPrinter

from exo_bench.matrix_method.symbolic import compose_equations, matrices
from exo_bench.models.files import c_comment, c_identifier, python_docstring, python_module_name, python_string
from exo_bench.models.states.states import ACCELERATION, blocks
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import coordinate_names, force_names
from exo_bench.models.mechanism.symbols import Symbols, symbols_for

FUNCTIONS = ("inverse_dynamics", "mass_matrix", "bias_forces")
#: The inputs of each function (before ``params`` with symbolic parameters).
INPUTS = {"inverse_dynamics": ("q", "qd", "qdd"), "mass_matrix": ("q",), "bias_forces": ("q", "qd")}


@dataclass
class EquationSet:
    """The equations of one mechanism as sympy expressions in the shared symbols."""

    mechanism: Mechanism
    symbols: Symbols
    symbolic_parameters: bool
    tau: list  # (dof,) in block order
    mass_matrix: list  # (dof, dof), row-major nested lists
    bias: list  # (dof,)
    seconds: dict = field(default_factory=dict)

    def outputs(self, function: str) -> list:
        """The flat list of outputs of ``function`` (M row-major)."""
        if function == "inverse_dynamics":
            return list(self.tau)
        if function == "mass_matrix":
            return [x for row in self.mass_matrix for x in row]
        if function == "bias_forces":
            return list(self.bias)
        raise ValueError(f"function: expected one of {', '.join(FUNCTIONS)}, got {function!r}")


def parameter_symbols(S: Symbols) -> list[sp.Symbol]:
    """The order of ``params``: ``m1_0, m1_1, m1_2, m2_0, ..., n1, ..., nN, g``."""
    return [x for ms in S.m for x in ms] + list(S.n) + [S.g]


def parameter_values(mech: Mechanism) -> list[float]:
    """The mechanism's values in the order of :func:`parameter_symbols`."""
    return [float(x) for ms in mech.masses for x in ms] + [float(x) for x in mech.n] + [float(mech.g)]


def equation_set(mech: Mechanism, symbolic_parameters: bool = False) -> EquationSet:
    """Eq. (5) / (17): ``tau``, ``M`` and ``h`` of ``mech`` composed by the matrix method."""
    S = symbols_for(mech.nlinks, mech.dim)
    t0 = time.perf_counter()
    tau = list(compose_equations(mech, symbolic_parameters))
    mats = matrices(mech, symbolic_parameters)
    bl = blocks(mech.dim)
    M = []
    for k in bl:
        for i in range(mech.nlinks):
            M.append([mats[k][ACCELERATION[c]][i, j] for c in bl for j in range(mech.nlinks)])
    zero = {s: sp.S.Zero for s in S.qdd}
    h = [e.xreplace(zero) for e in tau]
    return EquationSet(mech, S, symbolic_parameters, tau, M, h, {"compose": time.perf_counter() - t0})


def eliminate(outputs: list) -> tuple[list[tuple[sp.Symbol, sp.Expr]], list[sp.Expr]]:
    """``sympy.cse`` of ``outputs`` (temporaries ``x0, x1, ...``), no re-ordering of the outputs."""
    return sp.cse(outputs, symbols=sp.numbered_symbols("x"), order="none")


def operation_count(outputs: list) -> int:
    """``sympy.count_ops`` of the equations after CSE: the temporaries and the outputs."""
    subs, reduced = eliminate(outputs)
    return int(sp.count_ops([e for _, e in subs] + list(reduced)))


def _double(r) -> str:
    """The nearest double of a rational, 17 significant digits (round-trips exactly)."""
    x = float(r)
    text = repr(x)
    return text if ("e" in text or "." in text) else text + ".0"


class _NumpyPrinter(NumPyPrinter):
    def _print_Rational(self, expr):
        return _double(expr)

    def _print_Integer(self, expr):
        return _double(expr)

    def _print_Pow(self, expr, rational=False):
        base, e = expr.as_base_exp()
        if e.is_Integer and 2 <= int(e) <= 4:
            b = self.parenthesize(base, sp.printing.precedence.PRECEDENCE["Mul"])
            return "*".join([b] * int(e))
        return super()._print_Pow(expr, rational)


class _CPrinter(C99CodePrinter):
    def _print_Rational(self, expr):
        return _double(expr)

    def _print_Integer(self, expr):
        return _double(expr)

    def _print_Pow(self, expr):
        base, e = expr.as_base_exp()
        if e.is_Integer and 2 <= int(e) <= 4:
            b = self.parenthesize(base, sp.printing.precedence.PRECEDENCE["Mul"])
            return "*".join([b] * int(e))
        return super()._print_Pow(expr)


def _inputs(S: Symbols, symbolic_parameters: bool) -> dict[str, list[sp.Symbol]]:
    out = {"q": list(S.q), "qd": list(S.qd), "qdd": list(S.qdd)}
    if symbolic_parameters:
        out["params"] = parameter_symbols(S)
    return out


def _used(subs, reduced) -> set:
    used = set()
    for _, e in subs:
        used |= e.free_symbols
    for e in reduced:
        used |= sp.sympify(e).free_symbols
    return used


def header_lines(es: EquationSet, version: str) -> list[str]:
    """What the generated code says about itself (mechanism, version, coordinate order): plain text,
    the mechanism's name as a Python literal; each language puts every line through its encoder
    (:func:`exo_bench.models.files.c_comment`, :func:`exo_bench.models.files.python_docstring`)."""
    m = es.mechanism
    lines = [
        f"Equations of motion of mechanism {python_string(m.name)} ({m.dim}D, {m.nlinks} link(s), parents "
        f"{list(m.parent)}, signs {list(m.sign)}), eq. (5)/(17) of Borisov & Chigarev composed by the matrix",
        f"method and generated by exo-bench {version} (`exo-bench equations --format ...`). Do not edit.",
        f"Coordinates q, qd, qdd in block order: {', '.join(coordinate_names(m))}.",
        f"Generalised forces tau (absolute angles): {', '.join(force_names(m))}.",
        "M is (dof, dof) row-major; tau = M qdd + h.",
    ]
    if es.symbolic_parameters:
        lines.append(
            "params: "
            + ", ".join(str(s) for s in parameter_symbols(es.symbols))
            + " (masses in kg, fractions, g in m/s^2)."
        )
    else:
        lines.append(
            f"Parameters are this mechanism's (masses {[list(x) for x in m.masses]}, fractions {list(m.n)}, g = {m.g})."
        )
    return lines


# ------------------------------------------------------------------------------ Python
def module_name(es: EquationSet) -> str:
    """The generated module's name and file stem: never a standard module's or numpy's
    (:func:`exo_bench.models.files.python_module_name`)."""
    return python_module_name(es.mechanism.name)


def python_module(es: EquationSet, version: str) -> str:
    """One module importing numpy only: the three functions on ``(samples, dof)`` arrays."""
    S, m = es.symbols, es.mechanism
    dof = len(es.tau)
    p = _NumpyPrinter({"fully_qualified_modules": True, "inline": True, "allow_unknown_functions": False})
    inputs = _inputs(S, es.symbolic_parameters)
    doc = "\n".join(python_docstring(ln) for ln in header_lines(es, version))
    out = [
        '"""' + doc,
        "",
        "Each function takes arrays of shape (samples, dof) or (dof,) and returns the same leading shape.",
        '"""',
        "",
        "import numpy",
        "",
        f"DOF = {dof}",
        f"COORDINATES = {tuple(coordinate_names(m))!r}",
        f"FORCES = {tuple(force_names(m))!r}",
        f"MECHANISM = {python_string(m.name)}",
        f"EXO_BENCH_VERSION = {version!r}",
    ]
    if es.symbolic_parameters:
        out += [
            f"PARAMETERS = {tuple(str(s) for s in inputs['params'])!r}",
            f"DEFAULT_PARAMS = {tuple(parameter_values(m))!r}",
        ]
    out += [
        "",
        "",
        "def _batch(x):",
        "    x = numpy.asarray(x, dtype=float)",
        "    if x.ndim not in (1, 2) or x.shape[-1] != DOF:",
        "        raise ValueError(f'expected shape (samples, {DOF}) or ({DOF},), got {x.shape}')",
        "    return x.reshape(-1, DOF), x.ndim == 1",
    ]
    for fn in FUNCTIONS:
        subs, reduced = eliminate(es.outputs(fn))
        used = _used(subs, reduced)
        args = list(INPUTS[fn])
        sig = ", ".join(args) + (", params=DEFAULT_PARAMS" if es.symbolic_parameters else "")
        doc = {
            "inverse_dynamics": "tau = M(q) qdd + h(q, qd), (samples, dof).",
            "mass_matrix": "M(q), (samples, dof, dof).",
            "bias_forces": "h(q, qd) = tau(q, qd, 0), (samples, dof).",
        }[fn]
        out += ["", "", f"def {fn}({sig}):", f'    """{doc}"""']
        out.append(f"    {args[0]}, single = _batch({args[0]})")
        for a in args[1:]:
            out.append(f"    {a}, _ = _batch({a})")
        out.append(f"    samples = {args[0]}.shape[0]")
        for a in args:
            for k, s in enumerate(inputs[a]):
                if s in used:
                    out.append(f"    {s} = {a}[:, {k}]")
        if es.symbolic_parameters:
            out.append("    params = numpy.asarray(params, dtype=float)")
            for k, s in enumerate(inputs["params"]):
                if s in used:
                    out.append(f"    {s} = params[{k}]")
        for s, e in subs:
            out.append(f"    {s} = {p.doprint(e)}")
        shape = "(samples, DOF, DOF)" if fn == "mass_matrix" else "(samples, DOF)"
        out.append(f"    out = numpy.zeros({shape})")
        for k, e in enumerate(reduced):
            if e == 0:
                continue
            idx = f"{k // dof}, {k % dof}" if fn == "mass_matrix" else f"{k}"
            out.append(f"    out[:, {idx}] = {p.doprint(e)}")
        out.append("    return out[0] if single else out")
    return "\n".join(out) + "\n"


# ------------------------------------------------------------------------------ C
C_FLAGS = "-O2 -Wall -Wextra -Werror -std=c99"


def c_signature(prefix: str, fn: str, symbolic_parameters: bool) -> str:
    args = [f"const double *{a}" for a in INPUTS[fn]]
    if symbolic_parameters:
        args.append("const double *params")
    args.append("double *" + {"inverse_dynamics": "tau", "mass_matrix": "M", "bias_forces": "h"}[fn])
    return f"void {prefix}_{fn}({', '.join(args)})"


def c_sources(es: EquationSet, version: str, prefix: str | None = None) -> tuple[str, str, str]:
    """``(prefix, header, source)``: C99, one sample per call on plain arrays, inputs then output."""
    S, m = es.symbols, es.mechanism
    prefix = c_identifier(prefix or m.name)
    dof = len(es.tau)
    guard = prefix.upper() + "_H"
    info = [c_comment(ln) for ln in header_lines(es, version)]  # a user's name cannot end the comment
    head = (
        ["/*"]
        + [" * " + ln for ln in info]
        + [
            " *",
            f" * One sample per call: q, qd, qdd hold {dof} doubles; tau and h {dof}; M {dof * dof} (row-major).",
            " * No allocation, no global state: safe to call from any thread.",
            f" * Compile: cc {C_FLAGS} -c {prefix}.c   (link with -lm)",
            " */",
            f"#ifndef {guard}",
            f"#define {guard}",
            "",
            f"#define {prefix.upper()}_DOF {dof}",
            "",
        ]
    )
    for fn in FUNCTIONS:
        head.append(c_signature(prefix, fn, es.symbolic_parameters) + ";")
    head += ["", f"#endif /* {guard} */", ""]
    p = _CPrinter()
    inputs = _inputs(S, es.symbolic_parameters)
    src = [
        "/* " + info[0],
        " * Generated by exo-bench " + version + "; see " + prefix + ".h. Do not edit. */",
        "#include <math.h>",
        f'#include "{prefix}.h"',
    ]
    for fn in FUNCTIONS:
        subs, reduced = eliminate(es.outputs(fn))
        used = _used(subs, reduced)
        names = list(INPUTS[fn]) + (["params"] if es.symbolic_parameters else [])
        outname = {"inverse_dynamics": "tau", "mass_matrix": "M", "bias_forces": "h"}[fn]
        src += ["", c_signature(prefix, fn, es.symbolic_parameters), "{"]
        for a in names:
            syms = [s for s in inputs[a] if s in used]
            if not syms:
                src.append(f"    (void){a};")
            for k, s in enumerate(inputs[a]):
                if s in used:
                    src.append(f"    const double {s} = {a}[{k}];")
        for s, e in subs:
            src.append(f"    const double {s} = {p.doprint(e)};")
        for k, e in enumerate(reduced):
            src.append(f"    {outname}[{k}] = {p.doprint(e)};")
        src.append("}")
    return prefix, "\n".join(head), "\n".join(src) + "\n"
