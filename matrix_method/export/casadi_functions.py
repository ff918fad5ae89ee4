"""Eq. (5) / (17) as CasADi functions: inverse and forward dynamics, M, h and their derivatives.

The functions are built from the factored closed forms that method ``matrix-factored`` runs
(:func:`exo_bench.matrix_method.numpy_kernels.matrix._factored_2d` / ``_factored_3d``, derivation in
:func:`exo_bench.matrix_method.numpy_kernels.matrix.inverse_dynamics`): the same kernel, called once on CasADi's SX
symbols instead of numpy arrays (:class:`CasadiOps` supplies ``cos``/``sin``, the product with the
signed coupling ``c`` and the stacking; everything else is the kernel's own elementwise
arithmetic). Nothing of the physics is written here. With ``parameters=True`` the masses,
fractions and g are one more input, ``params``, and ``c`` is :func:`exo_bench.matrix_method.closed_forms.coefficients.generic_coupling`
of them (the same function the symbolic export uses).

* ``inverse_dynamics(q, qd, qdd) -> tau``: the kernel on symbols;
* ``mass_matrix(q) -> M``: ``d tau / d qdd`` (exact: tau is linear in qdd);
* ``bias_forces(q, qd) -> h``: ``tau(q, qd, 0)``;
* ``forward_dynamics(q, qd, tau) -> qdd``: ``M^-1 (tau - h)`` by CasADi's ``solve`` with its sparse
  QR (an MX function; M is symmetric positive definite away from the singular configurations of
  :func:`exo_bench.models.mechanism.singularity.singular_reasons`, where the factorisation fails or the result is
  Inf/NaN, never hidden);
* ``inverse_dynamics_derivatives(q, qd, qdd) -> (dtau_dq, dtau_dqd, M)``: CasADi's algorithmic
  differentiation of the kernel;
* ``forward_dynamics_derivatives(q, qd, tau) -> (qdd, dqdd_dq, dqdd_dqd, Minv)``: from
  ``ID(q, qd, FD(q, qd, tau)) = tau``: ``dqdd/dq = -M^-1 dID/dq``, ``dqdd/dqd = -M^-1 dID/dqd``,
  ``dqdd/dtau = M^-1`` (one sparse QR of M for every right-hand side; MX).

Every function is a ``casadi.Function`` of column vectors in block order ``[phi..., psi..., l...]``
(no psi in 2D), so it takes numbers (one sample, or ``(dof, samples)`` columns: CasADi maps it),
SX or MX symbols (an optimal-control problem, with IPOPT from CasADi's wheel), and saves to a
``.casadi`` file (:meth:`CasadiEquations.save`, ``Function.load`` reads it back without exo-bench).

CasADi is an optional extra (``pip install 'exo-bench[casadi]'``); without it
:func:`casadi_functions` raises a ValueError that names the extra.
"""

from __future__ import annotations

from functools import cached_property, lru_cache
from pathlib import Path

import numpy as np

from exo_bench.matrix_method.numpy_kernels import matrix as numeric
from exo_bench.matrix_method.closed_forms.coefficients import generic_coupling, signed_coupling, signed_gravity
from exo_bench.models.files import markdown_code, python_string
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import coordinate_names, force_names
from exo_bench.models.files import file_stem

#: The optional extra that installs CasADi, named in every error about it.
EXTRA = "casadi"
#: The functions of :class:`CasadiEquations`, with their inputs and outputs (CasADi's names).
FUNCTIONS = {
    "inverse_dynamics": (("q", "qd", "qdd"), ("tau",)),
    "mass_matrix": (("q",), ("M",)),
    "bias_forces": (("q", "qd"), ("h",)),
    "forward_dynamics": (("q", "qd", "tau"), ("qdd",)),
    "inverse_dynamics_derivatives": (("q", "qd", "qdd"), ("dtau_dq", "dtau_dqd", "M")),
    "forward_dynamics_derivatives": (("q", "qd", "tau"), ("qdd", "dqdd_dq", "dqdd_dqd", "Minv")),
}


def require_casadi():
    """The ``casadi`` module, or a ValueError naming the optional extra that installs it."""
    try:
        import casadi
    except ImportError:
        raise ValueError(
            f"CasADi is not installed: it is the optional extra '{EXTRA}' (pip install 'exo-bench[{EXTRA}]')"
        ) from None
    return casadi


class CasadiOps:
    """The namespace of :func:`exo_bench.matrix_method.numpy_kernels.matrix._factored_2d` for CasADi column vectors ``(n, 1)``:
    ``cos``/``sin`` (not numpy's half-angle tangent, whose derivative is singular at pi), the
    product with the constant coupling (``mtimes``) and the blocks stacked (``vertcat``)."""

    def __init__(self, ca):
        self.ca = ca

    def cos_sin(self, x):
        return self.ca.cos(x), self.ca.sin(x)

    def couple(self, c, parts):
        return [self.ca.mtimes(c, p) for p in parts]

    def rows(self, parts):
        return self.ca.vertcat(*parts)


def symbolic_inverse_dynamics(mech: Mechanism, q, qd, qdd, ca=None, params=None):
    """``tau`` of ``mech`` as a CasADi expression of the column vectors ``q, qd, qdd`` ``(dof, 1)``
    (SX or MX): the factored kernel of method ``matrix-factored`` run on them. ``params``: a symbol
    ``(4 n + 1, 1)`` of the masses, fractions and g (:func:`parameter_names`) instead of the
    mechanism's numbers; the coupling is then :func:`exo_bench.matrix_method.closed_forms.coefficients.generic_coupling` of them."""
    ca = ca or require_casadi()
    kernel = numeric._factored_2d if mech.dim == 2 else numeric._factored_3d
    if params is None:
        c = ca.sparsify(ca.DM(np.asarray(signed_coupling(mech))))  # links on different branches: no term
        nu_s, g = ca.DM(np.asarray(signed_gravity(mech))), float(mech.g)
    else:
        n = mech.nlinks
        per_link = [(params[3 * i], params[3 * i + 1], params[3 * i + 2], params[3 * n + i]) for i in range(n)]
        cc, nn = generic_coupling(mech, per_link, zero=ca.SX(0) if isinstance(params, ca.SX) else ca.MX(0))
        c = ca.vertcat(*[ca.horzcat(*row) for row in cc])
        nu_s, g = ca.vertcat(*nn), params[4 * n]
    return kernel(mech.nlinks, g, c, nu_s, q, qd, qdd, CasadiOps(ca))


def parameter_names(mech: Mechanism) -> list[str]:
    """The entries of ``params`` (``parameters=True``): ``m1_0, m1_1, m1_2, m2_0, ..., n1, ..., nN, g``,
    the order of ``exo-bench equations --symbolic-parameters`` (:func:`exo_bench.matrix_method.export.code.parameter_symbols`)."""
    n = mech.nlinks
    return [f"m{i + 1}_{b}" for i in range(n) for b in range(3)] + [f"n{i + 1}" for i in range(n)] + ["g"]


def parameter_values(mech: Mechanism) -> np.ndarray:
    """The mechanism's values in the order of :func:`parameter_names`."""
    return np.array([x for ms in mech.masses for x in ms] + list(mech.n) + [mech.g], dtype=float)


class CasadiEquations:
    """The equations of motion of one mechanism as ``casadi.Function`` objects.

    Built once in the constructor (like sympy's ``LagrangesMethod``); each function is a property
    (:data:`FUNCTIONS` lists inputs and outputs). Column vectors in block order; ``q, qd, qdd`` and
    ``tau`` are also available as the SX symbols the functions were built on. With
    ``parameters=True`` every function takes one more input, ``params`` (masses, fractions and g,
    :func:`parameter_names`; the mechanism's values: :attr:`parameter_values`), for design
    optimisation; the tree, its signs and dimension stay fixed.
    """

    def __init__(self, mechanism: Mechanism, parameters: bool = False):
        if not isinstance(mechanism, Mechanism):
            raise ValueError(
                f"casadi functions: expected a Mechanism (exo_bench.Mechanism or "
                f"exo_bench.load_mechanism), got {type(mechanism).__name__}"
            )
        ca = require_casadi()
        self._ca = ca
        self.mechanism = mechanism
        d = mechanism.dof
        self.dof = d
        self.q, self.qd, self.qdd = ca.SX.sym("q", d), ca.SX.sym("qd", d), ca.SX.sym("qdd", d)
        self.parameters = bool(parameters)
        #: the symbol of the parameters (None without ``parameters``) and the mechanism's values of them
        self.params = ca.SX.sym("params", 4 * mechanism.nlinks + 1) if parameters else None
        self.parameter_values = parameter_values(mechanism)
        self._p = [self.params] if parameters else []
        #: tau(q, qd, qdd) as an SX expression
        self.tau = symbolic_inverse_dynamics(mechanism, self.q, self.qd, self.qdd, ca, self.params)
        self.M = ca.jacobian(self.tau, self.qdd)
        self.h = ca.substitute(self.tau, self.qdd, ca.SX.zeros(d))

    def _function(self, name: str, inputs: list, outputs: list):
        ins, outs = FUNCTIONS[name]
        names = list(ins) + (["params"] if self.parameters else [])
        return self._ca.Function(name, inputs + self._p_of(inputs[0]), outputs, names, list(outs))

    def _p_of(self, x) -> list:
        """``[params]`` as the symbol type of ``x`` (the SX symbol, or the MX one of an MX function)."""
        if not self.parameters:
            return []
        if isinstance(x, self._ca.SX):
            return [self.params]
        return [self._mx_params]

    @cached_property
    def _mx_params(self):
        return self._ca.MX.sym("params", self.params.numel())

    # ------------------------------------------------------------------ the functions
    @cached_property
    def inverse_dynamics(self):
        """``(q, qd, qdd) -> tau``."""
        return self._function("inverse_dynamics", [self.q, self.qd, self.qdd], [self.tau])

    @cached_property
    def mass_matrix(self):
        """``q -> M = d tau / d qdd`` ``(dof, dof)``."""
        return self._function("mass_matrix", [self.q], [self.M])

    @cached_property
    def bias_forces(self):
        """``(q, qd) -> h = tau(q, qd, 0)``."""
        return self._function("bias_forces", [self.q, self.qd], [self.h])

    @cached_property
    def forward_dynamics(self):
        """``(q, qd, tau) -> qdd = M^-1 (tau - h)``: an MX function over :attr:`mass_matrix` and
        :attr:`bias_forces` with CasADi's sparse QR (``Linsol`` plugin ``qr``) at run time. (A
        symbolic QR on SX grows as ``dof^3`` and lost two digits more: 8e-12 against 1e-13 relative
        on exo5-3d's random states.) In an optimal-control problem, ``inverse_dynamics(q, qd, qdd) ==
        tau`` as a constraint needs no solve at all."""
        ca = self._ca
        q, qd, tau = (ca.MX.sym(x, self.dof) for x in ("q", "qd", "tau"))
        p = self._p_of(q)
        qdd = ca.solve(self.mass_matrix(q, *p), tau - self.bias_forces(q, qd, *p), "qr")
        return self._function("forward_dynamics", [q, qd, tau], [qdd])

    @cached_property
    def inverse_dynamics_derivatives(self):
        """``(q, qd, qdd) -> (d tau/d q, d tau/d qd, M)``, each ``(dof, dof)``."""
        ca = self._ca
        return self._function(
            "inverse_dynamics_derivatives",
            [self.q, self.qd, self.qdd],
            [ca.jacobian(self.tau, self.q), ca.jacobian(self.tau, self.qd), self.M],
        )

    @cached_property
    def forward_dynamics_derivatives(self):
        """``(q, qd, tau) -> (qdd, d qdd/d q, d qdd/d qd, M^-1)``: the implicit-function theorem on
        ``ID(q, qd, qdd) = tau``. An MX function over the SX ones, with CasADi's sparse QR
        (``Linsol`` plugin ``qr``) factorising M at run time: a symbolic QR with ``3 dof``
        right-hand sides would grow as ``dof^3`` (266 MB saved for a 3D chain of 20 links)."""
        ca = self._ca
        d = self.dof
        q, qd, tau = ca.MX.sym("q", d), ca.MX.sym("qd", d), ca.MX.sym("tau", d)
        p = self._p_of(q)
        M = self.mass_matrix(q, *p)
        a = ca.solve(M, tau - self.bias_forces(q, qd, *p), "qr")
        jq, jqd, _ = self.inverse_dynamics_derivatives(q, qd, a, *p)
        sol = ca.solve(M, ca.horzcat(jq, jqd, ca.MX.eye(d)), "qr")
        return self._function(
            "forward_dynamics_derivatives", [q, qd, tau], [a, -sol[:, :d], -sol[:, d : 2 * d], sol[:, 2 * d :]]
        )

    def functions(self) -> dict:
        """``name -> casadi.Function`` for every function of :data:`FUNCTIONS`."""
        return {name: getattr(self, name) for name in FUNCTIONS}

    # ------------------------------------------------------------------ files
    def serialized(self) -> dict[str, str]:
        """``file name -> text`` of every function's ``.casadi`` file, exactly as ``Function.save``
        writes it (ASCII; ``casadi.Function.load(path)`` reads it back). ``Function.serialize``
        gives another header, which ``load`` refuses, so each is saved to a scratch folder and read."""
        import tempfile

        with tempfile.TemporaryDirectory(prefix="exo-bench-casadi-") as tmp:
            return {p.name: p.read_text(encoding="ascii") for p in self.save(tmp)}

    def save(self, folder) -> list[Path]:
        """Every function into ``folder/<name>.casadi`` (``Function.save``); returns the paths. Each
        is written whole or not at all, never through a symlink planted there
        (:func:`exo_bench.models.files.atomic_path`)."""
        from exo_bench.models.files import atomic_path

        folder = Path(folder)
        paths = []
        for name, f in self.functions().items():
            p = folder / f"{name}.casadi"
            with atomic_path(p) as tmp:
                f.save(str(tmp))
                _check_saved(tmp, p)
            paths.append(p)
        return paths

    # ------------------------------------------------------------------ numbers, batch-first
    def evaluate(self, name: str, *arrays, params=None) -> tuple[np.ndarray, ...]:
        """Function ``name`` on batch-first float arrays ``(samples, dof)`` (or one ``(dof,)``):
        vectors come back ``(samples, dof)``, matrices ``(samples, dof, dof)`` (or without the
        sample axis for one sample). One mapped CasADi call, no Python loop over samples.
        ``params`` (with ``parameters=True``): one vector for every sample, default the mechanism's."""
        f = getattr(self, name)
        single = np.ndim(arrays[0]) == 1
        cols = [np.atleast_2d(np.asarray(a, dtype=float)).T for a in arrays]
        S = cols[0].shape[1]
        if self.parameters:
            cols.append(np.asarray(self.parameter_values if params is None else params, dtype=float).reshape(-1, 1))
        elif params is not None:
            raise ValueError("casadi functions: params given, but the functions were built without parameters")
        res = f(*cols)
        res = res if isinstance(res, (list, tuple)) else [res]
        d = self.dof
        out = []
        for k, r in enumerate(res):
            r = np.asarray(r)
            x = r.T if f.size2_out(k) == 1 else r.reshape(d, S, d).transpose(1, 0, 2)  # columns -> samples
            out.append(x[0] if single else x)
        return tuple(out)

    def __repr__(self) -> str:
        return f"<CasadiEquations of {self.mechanism.name!r} ({self.dof} dof, {self.mechanism.dim}D)>"


def _check_saved(tmp: Path, path: Path) -> None:
    """An OSError naming ``path`` unless ``tmp`` reads back as a CasADi function: ``Function.save``
    reports no write error (a full disk or a file size limit left a truncated file, no exception)."""
    import casadi as ca

    try:
        ca.Function.load(str(tmp))
    except Exception:  # noqa: BLE001 - CasADi's parse errors come as RuntimeError or UnicodeDecodeError
        import errno

        raise OSError(
            errno.EIO, "CasADi wrote an incomplete file (the disk full or a file size limit?)", str(path)
        ) from None


@lru_cache(maxsize=32)
def casadi_functions(mechanism: Mechanism, parameters: bool = False) -> CasadiEquations:
    """The CasADi functions of ``mechanism``'s equations of motion (built once per mechanism):
    :class:`CasadiEquations`; ``parameters=True``: masses, fractions and g as one more input.
    A ValueError names the optional extra when CasADi is missing."""
    return CasadiEquations(mechanism, parameters)


def export_files(
    mech: Mechanism, stem: str, version: str, header: str = "", parameters: bool = False
) -> dict[str, str]:
    """``file name -> text`` of ``exo-bench equations MECH --format casadi [--symbolic-parameters]``:
    every function as ``<stem>_<function>.casadi`` and the loader note ``<stem>_casadi.md``
    (nothing written)."""
    stem = file_stem(stem)  # the one file-name encoder (idempotent on a stem)
    files = {f"{stem}_{name}": text for name, text in casadi_functions(mech, parameters).serialized().items()}
    files[f"{stem}_casadi.md"] = loader_note(mech, stem, version, header, parameters)
    return files


def loader_note(mech: Mechanism, stem: str, version: str, header: str = "", parameters: bool = False) -> str:
    """The Markdown note written beside the ``.casadi`` files: what each holds and how to load it."""
    names = coordinate_names(mech)
    forces = force_names(mech)
    lines = [f"# CasADi functions of {markdown_code(mech.name)}", ""]  # a name is text, never Markdown
    if header:
        lines += [header, ""]
    lines += [
        f"Eq. (5)/(17) of the matrix method for {markdown_code(mech.name)} ({mech.dim}D, {mech.nlinks} links, {mech.dof} "
        f"coordinates), written by exo-bench {version} from the factored closed forms that its method "
        "`matrix-factored` runs (`matrix_method/export/casadi_functions.py`). Each file is one `casadi.Function` "
        "(`Function.save`); CasADi alone reads it back, exo-bench is not needed:",
        "",
        "```python",
        "import casadi as ca",
        "",
        f"ID = ca.Function.load({python_string(stem + '_inverse_dynamics.casadi')})   # (q, qd, qdd) -> tau",
        "tau = ID(q, qd, qdd)            # numbers, or SX/MX symbols in an optimal-control problem",
        "tau_batch = ID(Q, QD, QDD)      # (dof, samples) columns: CasADi maps the function",
        "```",
        "",
        "| file | inputs | outputs |",
        "|---|---|---|",
    ]
    extra = ", params" if parameters else ""
    for name, (ins, outs) in FUNCTIONS.items():
        lines.append(f"| `{stem}_{name}.casadi` | {', '.join(ins)}{extra} | {', '.join(outs)} |")
    lines += [
        "",
        f"Vectors are columns of {mech.dof} in block order: q = [{', '.join(names)}] "
        "(rad and m; the paper's absolute angles), qd and qdd their rates, "
        f"tau = [{', '.join(forces)}] (N m and N). Matrices are (dof, dof): `dtau_dq[i, j] = d tau_i / d q_j`.",
        *(
            [
                "",
                f"`params` ({4 * mech.nlinks + 1}): [{', '.join(parameter_names(mech))}] (kg, fractions of the "
                f"length, m/s^2); this mechanism's values: [{', '.join(f'{x:.17g}' for x in parameter_values(mech))}]. "
                "The tree, its signs and the dimension are fixed.",
            ]
            if parameters
            else []
        ),
        "",
        "`inverse_dynamics`, `mass_matrix`, `bias_forces` and `inverse_dynamics_derivatives` are SX "
        "functions (`Function.expand`-able, e.g. for IPOPT); `forward_dynamics` and "
        "`forward_dynamics_derivatives` are MX functions that factorise M at run time (CasADi's sparse QR). "
        "At a singular configuration (a rod of length zero; in 3D a vertical rod, cos psi = 0) M is singular "
        "and forward dynamics is not defined. In an optimal-control problem, the constraint "
        "`inverse_dynamics(q, qd, qdd) == tau` needs no solve.",
        "",
    ]
    return "\n".join(lines)
