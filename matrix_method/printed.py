"""The paper's formulas **exactly as printed**, each once, with its equation number.

Nothing here is trusted: the errata study (``exo-bench errata``, ``bench/studies/errata.py``) evaluates every entry against Lagrange's
equations (and Pinocchio) and writes the verdicts to ``reports/errata.md``; the method
``matrix-paper`` evaluates :data:`TRANSITIONS` literally. Where an entry carries a ``corrected``
form, that is a hypothesis the same report verifies.

Longer than the project's 400 lines on purpose: one table of the printed formulas, in the paper's
order, each once; split, a reader could no longer check it against the paper page by page.

Transcription conventions (the source is the Russian original's LaTeX,
``/work/shared/paper/borisov-chigarev-original-ru.md``):

* ``±`` is ``sigma`` (+1 upper signs, Fig. 2a; -1 lower signs, Fig. 2b) and ``∓`` is ``-sigma``;
* an operator repeated at a line break (``... + \\\\ + ...``, ``... ± \\\\ ± ...``) is the Russian
  typesetting convention of repeating a sign at a break and is read once;
* links are numbered from 1 as in the paper; ``C_ij = cos(phi_i - phi_j)``, ``S_ij = sin(...)``.

The state namespaces the formulas receive are built by :func:`transition_namespace` (eq. 18)
and :func:`equation_namespace` (everything else).
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace
from collections.abc import Callable

import numpy as np

from exo_bench.models.mechanism.aggregates import link_aggregates
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import split


@dataclass(frozen=True)
class Printed:
    """One printed formula.

    ``kind``: ``"transition"`` (a line of eq. 18: ``fn(t)`` gives the 3D element of ``block``/``name``
    for all i, j), ``"notation"`` (a line that names a right-hand side and has nothing to
    evaluate), ``"equation"`` (``fn(x)`` gives the left-hand sides of the listed ``rows`` of tau),
    ``"matrix"`` (``fn(x)`` gives a whole matrix of a model), ``"rule"`` (a reading of a rule in the
    text). ``label``: the left side as printed; ``divides_by``: the divisors that vanish somewhere.
    """

    key: str
    equation: str
    label: str
    latex: str
    kind: str
    fn: Callable | None = None
    block: str = ""
    name: str = ""
    reading: str = ""
    corrected_latex: str = ""
    corrected: Callable | None = None
    divides_by: tuple[str, ...] = ()
    printed_dim: int = 3


# ------------------------------------------------------------------ namespaces
_PLANAR_NAMES = {
    ("phi", "A"): "a_phi",
    ("phi", "Lambda"): "lam_phi",
    ("phi", "D"): "d_phi",
    ("phi", "H"): "h_phi",
    ("phi", "P"): "p_phi",
    ("l", "A"): "a_l",
    ("l", "Lambda"): "lam_l",
    ("l", "D"): "d_l",
    ("l", "H"): "h_l",
    ("l", "P"): "p_l",
}


def transition_namespace(
    mech: Mechanism, q: np.ndarray, planar: dict, three_d: dict | None = None, cos=np.cos, sin=np.sin
):
    """What the right-hand sides of (18) refer to, as numpy arrays over samples ``S``:
    ``a_phi_2d ... p_l_2d`` (the planar matrices ``(S, n, n)`` / vectors ``(S, n)`` of the model of
    the same structure), ``cos_psi_i, sin_psi_i`` ``(S, n, 1)``, ``cos_psi_j, sin_psi_j``
    ``(S, 1, n)``, ``cos_phi_ij = cos(phi_i - phi_j)``, ``l_i, l_j``, the vectors ``cos_psi, sin_psi,
    cos_phi, sin_phi`` ``(S, n)`` and, from ``three_d`` (``block -> name -> array``), the 3D
    matrices a line refers to as ``<name>_<block>_3d`` (e.g. ``A_l_3d``). ``cos, sin``: elementwise
    functions (numpy's, or sympy's vectorised for exact evaluation)."""
    phi, psi, l = split(mech, q)
    t = SimpleNamespace()
    for (block, name), attr in _PLANAR_NAMES.items():
        setattr(t, f"{attr}_2d", planar[block][name])
    t.cos_psi, t.sin_psi, t.cos_phi, t.sin_phi = cos(psi), sin(psi), cos(phi), sin(phi)
    t.cos_psi_i, t.sin_psi_i = t.cos_psi[:, :, None], t.sin_psi[:, :, None]
    t.cos_psi_j, t.sin_psi_j = t.cos_psi[:, None, :], t.sin_psi[:, None, :]
    t.cos_phi_ij = cos(phi[:, :, None] - phi[:, None, :])
    t.l_i, t.l_j = l[:, :, None], l[:, None, :]
    for block, mats in (three_d or {}).items():
        for name, m in mats.items():
            setattr(t, f"{name}_{block}_3d", m)
    return t


class _Link:
    """1-based access to per-link arrays, so formulas read like the print: ``x.l(1)``."""

    def __init__(self, arr):
        self.arr = arr

    def __call__(self, i: int):
        return self.arr[..., i - 1]


def equation_namespace(mech: Mechanism, q, qd, qdd):
    """The symbols of the printed equations as numpy arrays, links numbered from 1:
    ``x.phi(i), x.psi(i), x.l(i)``, rates ``x.dphi(i)`` (phi'), ``x.ddphi(i)`` (phi''), ...,
    ``x.C(i, j) = cos(phi_i - phi_j)``, ``x.S(i, j)``, ``x.C1(i) = cos phi_i``, ``x.S1(i) = sin phi_i``,
    the masses ``x.m(i, beta)``, fractions ``x.nf(i, beta)`` (``n_{i beta}``), the aggregates
    ``x.zeta(i), x.eta(i), x.theta(i)``, ``x.g`` and ``x.n`` (number of links)."""
    phi, psi, l = split(mech, q)
    dphi, dpsi, dl = split(mech, qd)
    ddphi, ddpsi, ddl = split(mech, qdd)
    x = SimpleNamespace(n=mech.nlinks, g=mech.g, samples=q.shape[0])
    for name, arr in dict(
        phi=phi, psi=psi, l=l, dphi=dphi, dpsi=dpsi, dl=dl, ddphi=ddphi, ddpsi=ddpsi, ddl=ddl
    ).items():
        setattr(x, name, _Link(arr) if arr is not None else None)
    x.C = lambda i, j: np.cos(phi[:, i - 1] - phi[:, j - 1])
    x.S = lambda i, j: np.sin(phi[:, i - 1] - phi[:, j - 1])
    x.C1 = lambda i: np.cos(phi[:, i - 1])
    x.S1 = lambda i: np.sin(phi[:, i - 1])
    x.m = lambda i, b: mech.masses[i - 1][b]
    x.nf = lambda i, b: mech.fractions[i - 1, b]
    zeta, eta, theta = link_aggregates(mech)
    x.zeta, x.eta, x.theta = (lambda i: zeta[i - 1]), (lambda i: eta[i - 1]), (lambda i: theta[i - 1])
    return x


def _matrix(x, element) -> np.ndarray:
    """``(S, n, n)`` from a printed element ``element(i, j)`` (1-based)."""
    n = x.n
    out = np.zeros((x.samples, n, n))
    for i in range(1, n + 1):
        for j in range(1, n + 1):
            out[:, i - 1, j - 1] = element(i, j)
    return out


def _swap(m):
    return np.swapaxes(m, -1, -2)


# ------------------------------------------------------------- eq. (18)
# The text gives the lines two to a row; they are listed here one by one, in printed order.
_ci, _si = (lambda t: t.cos_psi_i), (lambda t: t.sin_psi_i)


_COS_IJ = "cos(phi_i - phi_j)"


def _line(element: str, matrix: str, latex: str, fn: Callable, label: str = "", **more) -> Printed:
    """A line of eq. (18) that gives ``element`` (``"a^phi"``: the element a of the block phi) of the 3D
    ``matrix`` (key ``18:a^phi``, label ``3D a^phi_ij``, ``_i`` for the gravity vector ``P``, unless
    ``label`` says how it is printed otherwise); ``more``: the other fields of :class:`Printed`."""
    label = label or f"3D {element}_{'i' if matrix == 'P' else 'ij'}"
    block = element.split("^")[1]
    return Printed(f"18:{element}", "(18)", label, latex, "transition", fn, block, matrix, **more)


def _notation(element: str, latex: str, reading: str) -> Printed:
    """A line of eq. (18) that names a generalised force (``"mu^phi"``): nothing to evaluate, ``reading``
    says how it is read."""
    return Printed(f"18:{element}", "(18)", f"3D {element}_i", latex, "notation", reading=reading)


# One line of the paper a row (unformatted, so that the table reads like the page).
# fmt: off
TRANSITIONS: tuple[Printed, ...] = (
    _line("a^phi", "A", r"{}^{3D}a_{ij}^\phi = {}^{2D}a_{ij}^\phi \cos\psi_i \cos\psi_j", lambda t: t.a_phi_2d * t.cos_psi_i * t.cos_psi_j),
    _line("b^phi", "B", r"{}^{3D}b_{ij}^\phi = {}^{2D}a_{ij}^l l_i \cos\psi_i \sin\psi_j", lambda t: t.a_l_2d * t.l_i * t.cos_psi_i * t.sin_psi_j),
    _line("lambda^phi", "Lambda", r"{}^{3D}\lambda_{ij}^\phi = {}^{2D}\lambda_{ij}^\phi \cos\psi_i \cos\psi_j", lambda t: t.lam_phi_2d * t.cos_psi_i * t.cos_psi_j),
    _line("d^phi", "D", r"{}^{3D}d_{ij}^\phi = {}^{2D}d_{ij}^\phi \cos\psi_i \cos\psi_j", lambda t: t.d_phi_2d * t.cos_psi_i * t.cos_psi_j),
    _line("e^phi", "E", r"{}^{3D}e_{ij}^\phi = {}^{2D}d_{ij}^\phi \cos\psi_i \cos\psi_j", lambda t: t.d_phi_2d * t.cos_psi_i * t.cos_psi_j),
    _line("g^phi", "G", r"{}^{3D}g_{ij}^\phi = -{}^{2D}h_{ij}^\phi l_j \cos\psi_i \sin\psi_j", lambda t: -t.h_phi_2d * t.l_j * t.cos_psi_i * t.sin_psi_j),
    _line("h^phi", "H", r"{}^{3D}h_{ij}^\phi = {}^{2D}h_{ij}^\phi \cos\psi_i \cos\psi_j", lambda t: t.h_phi_2d * t.cos_psi_i * t.cos_psi_j),
    _line("k^phi", "K", r"{}^{3D}k_{ij}^\phi = -{}^{2D}\lambda_{ij}^\phi \cos\psi_i \sin\psi_j", lambda t: -t.lam_phi_2d * t.cos_psi_i * t.sin_psi_j),
    _line("p^phi", "P", r"{}^{3D}p_i^\phi = {}^{2D}p_i^\phi \cdot 0", lambda t: t.p_phi_2d * 0),
    _notation("mu^phi", r"{}^{3D}\mu_i^\phi = {}^{2D}\mu_i^\phi", "mu names the generalised force (right-hand side) of the row: the 3D azimuth row keeps the planar angle's force; it says nothing about a matrix, so there is nothing to compute."),
    _line("a^psi", "A", r"{}^{3D}a_{ij}^\psi = -{}^{2D}a_{ij}^l l_i \cos\psi_j \sin\psi_i", lambda t: -t.a_l_2d * t.l_i * t.cos_psi_j * t.sin_psi_i),
    _line("b^psi", "B", r"{}^{3D}b_{ij}^\psi = {}^{2D}a_{ij}^\phi (\sin\psi_i \sin\psi_j + \cos\psi_i \cos\psi_j / \cos(\phi_i - \phi_j))", lambda t: t.a_phi_2d * (t.sin_psi_i * t.sin_psi_j + t.cos_psi_i * t.cos_psi_j / t.cos_phi_ij), divides_by=(_COS_IJ,)),
    _line("lambda^psi", "Lambda", r"{}^{3D}\lambda_{ij}^\psi = {}^{2D}h_{ij}^\phi (\cos\psi_i \sin\psi_j / \cos(\phi_i - \phi_j) - \cos\psi_j \sin\psi_i)", lambda t: t.h_phi_2d * (t.cos_psi_i * t.sin_psi_j / t.cos_phi_ij - t.cos_psi_j * t.sin_psi_i), divides_by=(_COS_IJ,)),
    _line("d^psi", "D", r"{}^{3D}d_{ij}^\psi = {}^{2D}h_{ij}^\phi l_j \cos\psi_j \sin\psi_i", lambda t: t.h_phi_2d * t.l_j * t.cos_psi_j * t.sin_psi_i),
    _line("e^psi", "E", r"{}^{3D}e_{ij}^\psi = {}^{2D}h_{ij}^\phi l_j (\cos\psi_j \sin\psi_i - \cos\psi_i \sin\psi_j / \cos(\phi_i - \phi_j))", lambda t: t.h_phi_2d * t.l_j * (t.cos_psi_j * t.sin_psi_i - t.cos_psi_i * t.sin_psi_j / t.cos_phi_ij), divides_by=(_COS_IJ,)),
    _line("g^psi", "G", r"{}^{3D}g_{ij}^\psi = {}^{2D}d_{ij}^\phi \sin\psi_i \sin\psi_j", lambda t: t.d_phi_2d * t.sin_psi_i * t.sin_psi_j),
    _line("h^psi", "H", r"{}^{3D}h_{ij}^\psi = {}^{2D}\lambda_{ij}^\phi \sin\psi_i \cos\psi_j", lambda t: t.lam_phi_2d * t.sin_psi_i * t.cos_psi_j),
    _line("k^psi", "K", r"{}^{2D}k_{ij}^\psi = {}^{2D}h_{ij}^\phi (\sin\psi_j \sin\psi_i + \cos\psi_i \cos\psi_j / \cos(\phi_i - \phi_j))", lambda t: t.h_phi_2d * (t.sin_psi_j * t.sin_psi_i + t.cos_psi_i * t.cos_psi_j / t.cos_phi_ij), label="2D k^psi_ij", divides_by=(_COS_IJ,), printed_dim=2, reading="The left side is printed as a 2D element, but a planar model has no psi and no K matrix, and no other line defines 3D k^psi: the right side is read as 3D k^psi.", corrected_latex=r"{}^{3D}k_{ij}^\psi = {}^{2D}h_{ij}^\phi (\sin\psi_j \sin\psi_i + \cos\psi_i \cos\psi_j / \cos(\phi_i - \phi_j))", corrected=lambda t: t.h_phi_2d * (t.sin_psi_j * t.sin_psi_i + t.cos_psi_i * t.cos_psi_j / t.cos_phi_ij)),
    _line("p^psi", "P", r"{}^{3D}p_i^\psi = {}^{2D}p_i^\phi \cos\psi_i / \cos\phi_i", lambda t: t.p_phi_2d * t.cos_psi / t.cos_phi, divides_by=("cos phi_i",)),
    _notation("mu^psi", r"{}^{3D}\mu_i^\psi = {}^{2D}\mu_i^\phi \Big|_{\phi \rightarrow \psi}", "mu names the generalised force of the elevation row (the planar angle's force with phi renamed psi); nothing to compute."),
    _line("a^l", "A", r"{}^{3D}a_{ij}^l = {}^{2D}a_{ij}^l \cos\psi_i \cos\psi_j", lambda t: t.a_l_2d * t.cos_psi_i * t.cos_psi_j),
    _line("b^l", "B", r"{}^{3D}b_{ij}^l = {}^{2D}d_{ij}^l (\cos\psi_i \sin\psi_j - \sin\psi_i \cos\psi_j / \cos(\phi_i - \phi_j))", lambda t: t.d_l_2d * (t.cos_psi_i * t.sin_psi_j - t.sin_psi_i * t.cos_psi_j / t.cos_phi_ij), divides_by=(_COS_IJ,)),
    _line("lambda^l", "Lambda", r"{}^{3D}\lambda_{ij}^l = {}^{2D}\lambda_{ij}^l (\cos\psi_i \cos\psi_j + \sin\psi_i \sin\psi_j / \cos(\phi_i - \phi_j))", lambda t: t.lam_l_2d * (t.cos_psi_i * t.cos_psi_j + t.sin_psi_i * t.sin_psi_j / t.cos_phi_ij), divides_by=(_COS_IJ,)),
    Printed(
        "18:D_l",
        "(18)",
        "D_l",
        r"D_l(\phi, \psi, l) = - (H_\phi(\phi, \psi, l))^T",
        "transition",
        lambda t: -_swap(t.H_phi_3d),
        "l",
        "D",
        reading="Both sides are 3D matrices (the line sits among the 3D formulas and names "
        "phi, psi, l); H_phi is the 3D matrix.",
    ),
    _line("e^l", "E", r"{}^{3D}e_{ij}^l = {}^{2D}d_{ij}^l (\sin\psi_i \sin\psi_j / \cos(\phi_i - \phi_j) + \cos\psi_i \cos\psi_j)", lambda t: t.d_l_2d * (t.sin_psi_i * t.sin_psi_j / t.cos_phi_ij + t.cos_psi_i * t.cos_psi_j), divides_by=(_COS_IJ,)),
    _line("g^l", "G", r"{}^{3D}g_{ij}^l = -{}^{3D}a_{ij}^l \cos\psi_i \sin\psi_j", lambda t: -t.A_l_3d * t.cos_psi_i * t.sin_psi_j, corrected_latex=r"{}^{3D}g_{ij}^l = -{}^{2D}a_{ij}^l \cos\psi_i \sin\psi_j", corrected=lambda t: -t.a_l_2d * t.cos_psi_i * t.sin_psi_j),
    _line("h^l", "H", r"{}^{3D}h_{ij}^l = {}^{2D}h_{ij}^l \cos\psi_i \cos\psi_j", lambda t: t.h_l_2d * t.cos_psi_i * t.cos_psi_j),
    _line("k^l", "K", r"{}^{3D}k_{ij}^l = -{}^{2D}d_{ij}^l (\cos\psi_i \sin\psi_j - \sin\psi_i \cos\psi_j / \cos(\phi_i - \phi_j)) / l_j", lambda t: -t.d_l_2d * (t.cos_psi_i * t.sin_psi_j - t.sin_psi_i * t.cos_psi_j / t.cos_phi_ij) / t.l_j, divides_by=(_COS_IJ, "l_j"), corrected_latex=r"{}^{3D}k_{ij}^l = {}^{2D}d_{ij}^l (\cos\psi_i \sin\psi_j - \sin\psi_i \cos\psi_j / \cos(\phi_i - \phi_j)) / l_j", corrected=lambda t: t.d_l_2d * (t.cos_psi_i * t.sin_psi_j - t.sin_psi_i * t.cos_psi_j / t.cos_phi_ij) / t.l_j),
    _line("p^l", "P", r"{}^{3D}p_i^l = {}^{2D}p_i^l \sin\psi_i / \sin\phi_i", lambda t: t.p_l_2d * t.sin_psi / t.sin_phi, divides_by=("sin phi_i",)),
    _notation("mu^l", r"{}^{3D}\mu_i^l = {}^{2D}\mu_i^l", "mu names the generalised force of the length row; nothing to compute."),
)
# fmt: on


def corrected_table(keys) -> tuple[Printed, ...]:
    """:data:`TRANSITIONS` with the lines ``keys`` replaced by their corrected forms."""
    from dataclasses import replace

    keys = set(keys)
    return tuple(replace(f, fn=f.corrected) if f.key in keys else f for f in TRANSITIONS)


# ------------------------------------------------------- one link, eqs. (2), (13)-(15)
def _eq2(x):
    l1, phi1, dl1, dphi1, ddl1, ddphi1 = x.l(1), x.phi(1), x.dl(1), x.dphi(1), x.ddl(1), x.ddphi(1)
    zeta1, eta1, g = x.zeta(1), x.eta(1), x.g
    C1, S1 = np.cos(phi1), np.sin(phi1)
    M1 = l1**2 * zeta1 * ddphi1 + g * l1 * eta1 * C1 + 2 * l1 * zeta1 * dl1 * dphi1
    F1 = -l1 * zeta1 * dphi1**2 + g * eta1 * S1 + zeta1 * ddl1
    return np.stack([M1, F1], -1)


def _eq13(x):
    l1, dl1, dphi1, dpsi1, ddphi1 = x.l(1), x.dl(1), x.dphi(1), x.dpsi(1), x.ddphi(1)
    zeta1 = x.zeta(1)
    Cpsi1, Spsi1 = np.cos(x.psi(1)), np.sin(x.psi(1))
    return (
        zeta1 * l1**2 * Cpsi1**2 * ddphi1
        + 2 * zeta1 * l1 * Cpsi1**2 * dl1 * dphi1
        - 2 * zeta1 * l1**2 * Cpsi1 * Spsi1 * dphi1 * dpsi1
    )[:, None]


def _eq14(x, rate):
    l1, dl1, dphi1, ddpsi1 = x.l(1), x.dl(1), x.dphi(1), x.ddpsi(1)
    zeta1, eta1, g = x.zeta(1), x.eta(1), x.g
    Cpsi1, Spsi1 = np.cos(x.psi(1)), np.sin(x.psi(1))
    return (
        zeta1 * l1**2 * ddpsi1
        + zeta1 * l1**2 * Cpsi1 * Spsi1 * dphi1**2
        + 2 * zeta1 * l1 * dl1 * rate(x)
        + g * eta1 * l1 * Cpsi1
    )[:, None]


def _eq15(x):
    l1, dphi1, dpsi1, ddl1 = x.l(1), x.dphi(1), x.dpsi(1), x.ddl(1)
    zeta1, eta1, g = x.zeta(1), x.eta(1), x.g
    Cpsi1, Spsi1 = np.cos(x.psi(1)), np.sin(x.psi(1))
    return (zeta1 * ddl1 - zeta1 * l1 * Cpsi1**2 * dphi1**2 - zeta1 * l1 * dpsi1**2 + g * eta1 * Spsi1)[:, None]


# ------------------------------------------------------------------ eq. (4)
def _eq4(x, sigma):
    """Eq. (4) as printed: ``sigma = +1`` upper signs (Fig. 2a), ``-1`` lower signs (Fig. 2b)."""
    pm, mp = sigma, -sigma  # "±" and "∓"
    l1, l2, dl1, dl2, ddl1, ddl2 = x.l(1), x.l(2), x.dl(1), x.dl(2), x.ddl(1), x.ddl(2)
    dphi1, dphi2, ddphi1, ddphi2 = x.dphi(1), x.dphi(2), x.ddphi(1), x.ddphi(2)
    C1, S1, C2, S2 = x.C1(1), x.S1(1), x.C1(2), x.S1(2)
    C12, S12 = x.C(1, 2), x.S(1, 2)
    g = x.g
    zeta1 = x.m(1, 1) * x.nf(1, 1) ** 2 + x.m(1, 2)  # the aggregates as defined under (4)
    zeta2 = x.m(2, 1) * x.nf(2, 1) ** 2 + x.m(2, 2)
    eta1 = x.m(1, 1) * x.nf(1, 1) + x.m(1, 2)
    eta2 = x.m(2, 1) * x.nf(2, 1) + x.m(2, 2)
    theta2 = x.m(2, 0) + x.m(2, 1) + x.m(2, 2)
    r1 = (
        (zeta1 + theta2) * l1**2 * ddphi1
        + pm * l1 * l2 * eta2 * C12 * ddphi2
        + pm * l1 * l2 * eta2 * S12 * dphi2**2
        + (eta1 + theta2) * g * l1 * C1
        + 2 * (zeta1 + theta2) * l1 * dl1 * dphi1
        + pm * 2 * l1 * eta2 * C12 * dl2 * dphi2
        + mp * l1 * eta2 * S12 * ddl2
    )
    r2 = (
        pm * l1 * l2 * eta2 * C12 * ddphi1
        + zeta2 * l2**2 * ddphi2
        + mp * l1 * l2 * eta2 * S12 * dphi1**2
        + pm * eta2 * g * l2 * C2
        + pm * 2 * l2 * eta2 * C12 * dl1 * dphi1
        + 2 * zeta2 * l2 * dl2 * dphi2
        + pm * l2 * eta2 * S12 * ddl1
    )
    r3 = (
        pm * l2 * eta2 * S12 * ddphi2
        - (zeta1 + theta2) * l1 * dphi1**2
        + mp * l2 * eta2 * C12 * dphi2**2
        + (eta1 + theta2) * g * S1
        + pm * 2 * eta2 * S12 * dl2 * dphi2
        + (zeta1 + theta2) * ddl1
        + pm * eta2 * C12 * ddl2
    )
    r4 = (
        mp * l1 * eta2 * S12 * ddphi1
        + mp * l1 * eta2 * C12 * dphi1**2
        - zeta2 * l2 * dphi2**2
        + pm * eta2 * g * S2
        + mp * 2 * eta2 * S12 * dl1 * dphi1
        + pm * eta2 * C12 * ddl1
        + zeta2 * ddl2
    )
    return np.stack([r1, r2, r3, r4], -1)


_EQ4_LATEX = (
    r"(\zeta_1 + \theta_2)l_1^2\ddot{\varphi}_1 \pm l_1l_2\eta_2C_{12}\ddot{\varphi}_2 \pm l_1l_2\eta_2S_{12}"
    r"\dot{\varphi}_2^2 + (\eta_1 + \theta_2)gl_1C_1 + \\ + 2(\zeta_1 + \theta_2)l_1\dot{l}_1\dot{\varphi}_1 "
    r"\pm 2l_1\eta_2C_{12}\dot{l}_2\dot{\varphi}_2 \mp l_1\eta_2S_{12}\ddot{l}_2 = M_1 - M_2, \; "
    r"\pm l_1l_2\eta_2C_{12}\ddot{\varphi}_1 + \zeta_2l_2^2\ddot{\varphi}_2 \mp l_1l_2\eta_2S_{12}\dot{\varphi}_1^2 "
    r"\pm \eta_2gl_2C_2 + \\ \pm 2l_2\eta_2C_{12}\dot{l}_1\dot{\varphi}_1 + 2\zeta_2l_2\dot{l}_2\dot{\varphi}_2 "
    r"\pm l_2\eta_2S_{12}\ddot{l}_1 = M_2, \; \pm l_2\eta_2S_{12}\ddot{\varphi}_2 - (\zeta_1 + \theta_2)l_1"
    r"\dot{\varphi}_1^2 \mp l_2\eta_2C_{12}\dot{\varphi}_2^2 + (\eta_1 + \theta_2)gS_1 + \\ \pm 2\eta_2S_{12}"
    r"\dot{l}_2\dot{\varphi}_2 + (\zeta_1 + \theta_2)\ddot{l}_1 \pm \eta_2C_{12}\ddot{l}_2 = F_1, \; "
    r"\mp l_1\eta_2S_{12}\ddot{\varphi}_1 \mp l_1\eta_2C_{12}\dot{\varphi}_1^2 - \zeta_2l_2\dot{\varphi}_2^2 \pm "
    r"\\ \pm \eta_2gS_2 \mp 2\eta_2S_{12}\dot{l}_1\dot{\varphi}_1 \pm \eta_2C_{12}\ddot{l}_1 + \zeta_2\ddot{l}_2 = F_2"
)

_REPEAT = (
    "An operator repeated at a line break ('+ \\\\ +', '± \\\\ ±', '+ \\\\ ±') is read once "
    "(Russian typesetting repeats the sign at a break)."
)


# ------------------------------------------------------------- chains: (6), (22), (25)
def _sum_theta(x, lo, hi):
    """``sum_{k=lo..hi} theta_k`` (zero when lo > hi), theta as defined under (6)."""
    return sum((x.theta(k) for k in range(lo, hi + 1)), 0.0)


def _eq6(x):
    def a(i, j):
        if j < i:
            return a(j, i)  # a_ji = a_ij
        d = 1.0 if i == j else 0.0
        return (d * x.zeta(i) + (1 - d) * x.eta(j) + _sum_theta(x, j + 1, x.n)) * x.l(i) * x.l(j) * x.C(i, j)

    return _matrix(x, a)


def _eq22(x):
    n = x.n

    def a(i, j):
        if i == j:  # (zeta_i + sum_{k=j+1..n} theta_k) l_i l_j C_ij, (i = j)
            return (x.zeta(i) + _sum_theta(x, j + 1, n)) * x.l(i) * x.l(j) * x.C(i, j)
        k = max(i, j)  # first row: eta_j + ..., first column: eta_i + ..., last: eta_n
        return (x.eta(k) + _sum_theta(x, k + 1, n)) * x.l(i) * x.l(j) * x.C(i, j)

    return _matrix(x, a)


def _eq25(x):
    """delta A_n of (25) for the n+1 links of ``x`` (``x.n = n + 1``)."""
    N = x.n

    def da(i, j):
        if i < N and j < N:
            return x.theta(N) * x.l(i) * x.l(j) * x.C(i, j)
        if i == N and j == N:
            return x.zeta(N) * x.l(N) * x.l(N) * x.C(N, N)
        return x.eta(N) * x.l(i) * x.l(j) * x.C(i, j)

    return _matrix(x, da)


def _eq26(x):
    """(26): every element of the 2D delta A_{n+1} times cos psi_i cos psi_j."""
    cpsi = np.stack([np.cos(x.psi(i)) for i in range(1, x.n + 1)], -1)
    return _eq25(x) * cpsi[:, :, None] * cpsi[:, None, :]


# ------------------------------------------------------------------ Fig. 5: (19)-(21)
def _eq19_element(x, i, j):
    """The elements of (19) as printed (links 1..4 of Fig. 5), a_ij = a_ji."""
    m, nf, l, C = x.m, x.nf, x.l, x.C
    theta = lambda k: sum(m(k, b) for b in range(3))  # sum_{beta=0..2} m_{k beta}
    if i > j:
        i, j = j, i
    table = {
        (1, 1): lambda: l(1) ** 2 * (m(1, 1) * nf(1, 1) ** 2 + m(1, 2) + sum(theta(k) for k in range(2, 5))),
        (1, 2): lambda: l(1) * l(2) * (m(2, 1) * nf(2, 1) + m(2, 2) + sum(theta(k) for k in range(3, 5))) * C(1, 2),
        (2, 2): lambda: l(2) ** 2 * (m(2, 1) * nf(2, 1) ** 2 + m(2, 2) + sum(theta(k) for k in range(3, 5))),
        (3, 3): lambda: l(3) ** 2 * (m(3, 1) * nf(3, 1) ** 2 + m(3, 2) + theta(4)),
        (3, 4): lambda: l(3) * l(4) * (m(4, 1) * nf(4, 1) + m(4, 2)) * C(3, 4),
        (4, 4): lambda: l(4) ** 2 * (m(4, 1) * nf(4, 1) ** 2 + m(4, 2)),
    }
    if (i, j) in table:
        return table[(i, j)]()
    if j == 3:  # a_j3 = a_3j, j = 1, 2
        return l(i) * l(3) * (m(3, 1) * nf(3, 1) + m(3, 2) + theta(4)) * C(i, 3)
    return l(i) * l(4) * (m(4, 1) * nf(4, 1) + m(4, 2)) * C(i, 4)  # a_j4 = a_4j, j = 1, 2


#: The branch signs of Fig. 5 as (20) shows them: a13 and a14 enter row 1 with a minus.
def _fig5_signs():
    s = np.array([1, 1, -1, -1])
    return np.outer(s, s)


def _eq19(x):
    return _matrix(x, lambda i, j: _eq19_element(x, i, j)) * _fig5_signs()


def _eq20(x):
    a = lambda i, j: _eq19_element(x, i, j)
    return (a(1, 1) * x.ddphi(1) + a(1, 2) * x.ddphi(2) - a(1, 3) * x.ddphi(3) - a(1, 4) * x.ddphi(4))[:, None]


def _eq21(x):
    cpsi = lambda i: np.cos(x.psi(i))
    return _matrix(x, lambda i, j: _eq19_element(x, i, j) * cpsi(i) * cpsi(j)) * _fig5_signs()


_SIGN_READING = (
    "(19) and (21) print the elements without branch signs; (20) shows a13 and a14 entering "
    "row 1 with a minus. Read as A = s_i s_j a_ij with the signs of Fig. 5 "
    "(s = +1, +1, -1, -1: links 3, 4 after the branch point, reversed). The text builds (19) "
    "'by the formula (2.13)', a number the paper does not have; read as eq. (6)."
)

EQUATIONS: tuple[Printed, ...] = (
    Printed(
        "2",
        "(2)",
        "one planar link",
        r"l_1^2 \zeta_1 \ddot{\phi}_1 + g l_1 \eta_1 C_1 + 2 l_1 \zeta_1 \dot{l}_1 \dot{\phi}_1 = M_1, \quad "
        r"-l_1 \zeta_1 \dot{\phi}_1^2 + g \eta_1 S_1 + \zeta_1 \ddot{l}_1 = F_1",
        "equation",
        _eq2,
    ),
    Printed(
        "4+",
        "(4)",
        "two planar links, upper signs (Fig. 2a)",
        _EQ4_LATEX,
        "equation",
        lambda x: _eq4(x, +1),
        reading=_REPEAT,
    ),
    Printed(
        "4-",
        "(4)",
        "two planar links, lower signs (Fig. 2b)",
        _EQ4_LATEX,
        "equation",
        lambda x: _eq4(x, -1),
        reading=_REPEAT,
    ),
    Printed(
        "6",
        "(6)",
        "a^phi_ij of a chain",
        r"a_{ij}^\phi = (\delta_{ij}\zeta_i + (1 - \delta_{ij})\eta_j + \sum_{k=j+1}^n \theta_k) l_i l_j "
        r"\cos(\phi_i - \phi_j), \; j \geq i, \; a_{ji}^\phi = a_{ij}^\phi",
        "matrix",
        _eq6,
        "phi",
        "A",
    ),
    Printed(
        "13",
        "(13)",
        "one spatial link, M_phi",
        r"\zeta_1 l_1^2 (C_1^\psi)^2 \ddot{\varphi}_1 + 2\zeta_1 l_1 (C_1^\psi)^2 \dot{l}_1 \dot{\varphi}_1 "
        r"- 2\zeta_1 l_1^2 C_1^\psi S_1^\psi \dot{\varphi}_1 \dot{\psi}_1 = M_{1\varphi}",
        "equation",
        _eq13,
    ),
    Printed(
        "14",
        "(14)",
        "one spatial link, M_psi",
        r"\zeta_1 l_1^2 \ddot{\psi}_1 + \zeta_1 l_1^2 C_1^\psi S_1^\psi \dot{\varphi}_1^2 + 2\zeta_1 l_1 \dot{l}_1 "
        r"\dot{\varphi}_1 + g \eta_1 l_1 C_1^\psi = M_{1\psi}",
        "equation",
        lambda x: _eq14(x, lambda x: x.dphi(1)),
        corrected_latex=r"\zeta_1 l_1^2 \ddot{\psi}_1 + \zeta_1 l_1^2 C_1^\psi S_1^\psi \dot{\varphi}_1^2 + 2\zeta_1 l_1 "
        r"\dot{l}_1 \dot{\psi}_1 + g \eta_1 l_1 C_1^\psi = M_{1\psi}",
        corrected=lambda x: _eq14(x, lambda x: x.dpsi(1)),
    ),
    Printed(
        "15",
        "(15)",
        "one spatial link, F",
        r"\zeta_1 \ddot{l}_1 - \zeta_1 l_1 (C_1^\psi)^2 \dot{\varphi}_1^2 - \zeta_1 l_1 \dot{\psi}_1^2 "
        r"+ g \eta_1 S_1^\psi = F_1",
        "equation",
        _eq15,
    ),
    Printed(
        "19",
        "(19)",
        "A of Fig. 5 (2D)",
        r"a_{11} = l_1^2(m_{11}n_{11}^2 + m_{12} + \sum_{\beta=0}^2 \sum_{k=2}^4 m_{k\beta}), \ldots, "
        r"a_{44} = l_4^2 (m_{41}n_{41}^2 + m_{42})",
        "matrix",
        _eq19,
        "phi",
        "A",
        reading=_SIGN_READING,
    ),
    Printed(
        "20",
        "(20)",
        "row 1 of A phi'' of Fig. 5",
        r"a_{11} \ddot{\varphi}_1 + a_{12} \ddot{\varphi}_2 - a_{13} \ddot{\varphi}_3 - a_{14} \ddot{\varphi}_4 + \dots",
        "equation",
        _eq20,
        reading="Compared with the A-part of the first planar equation of Fig. 5, sum_j A_1j phi_j''.",
    ),
    Printed(
        "21",
        "(21)",
        "3D A_phi of Fig. 5",
        r"{}^{3D}a_{11}^\varphi = l_1^2(m_{11}n_{11}^2 + m_{12} + \sum_{\beta=0}^2 \sum_{k=2}^4 m_{k\beta}) "
        r"\cos^2 \psi_1, \ldots, {}^{3D}a_{44}^\varphi = l_4^2 (m_{41}n_{41}^2 + m_{42}) \cos^2 \psi_4",
        "matrix",
        _eq21,
        "phi",
        "A",
        reading=_SIGN_READING,
    ),
    Printed(
        "22",
        "(22)",
        "A_n of an n-link chain",
        r"A_n = \begin{pmatrix} (\zeta_1 + \sum_{k=2}^n \theta_k) l_1 l_1 C_{11} & \dots & (\eta_j + "
        r"\sum_{k=j+1}^n \theta_k) l_1 l_j C_{1j} & \dots & \eta_n l_1 l_n C_{1n} \\ \dots \end{pmatrix}",
        "matrix",
        _eq22,
        "phi",
        "A",
        reading="(22) shows the first row and column, the diagonal and the last row and column; the "
        "elements in between are read with the same pattern, eta_k + sum_{m>k} theta_m for "
        "k = max(i, j).",
    ),
    Printed(
        "25",
        "(25)",
        "delta A_n: the chain grows by link n+1",
        r"\delta A_n = \begin{pmatrix} \theta_{n+1} l_i l_j C_{ij} & \eta_{n+1} l_i l_{n+1} C_{i,n+1} \\ "
        r"\eta_{n+1} l_{n+1} l_j C_{n+1,j} & \zeta_{n+1} l_{n+1} l_{n+1} C_{n+1,n+1} \end{pmatrix}, \; "
        r"\theta_{n+1} = \sum_{\beta=0}^{\alpha-1} m_{n+1,\beta}, \ldots",
        "matrix",
        _eq25,
        "phi",
        "A",
        reading="Checked as A_{n+1} = A_n (padded with a zero row and column, eqs. 23-24) + delta A_n "
        "with A_n, A_{n+1} from Lagrange for chains of n and n+1 links sharing links 1..n. The "
        "upper limit alpha - 1 of the sums under (25) is undefined in the text; it is read as 2 "
        "(three masses per link, beta = 0, 1, 2, as under (6)).",
    ),
    Printed(
        "26",
        "(26)",
        "delta 3D A_{n+1} = delta 2D A_{n+1} cos psi_i cos psi_j",
        r"{}^{2D}A_n \rightarrow {}^{2D}A_{n+1} \rightarrow {}^{3D}A_{n+1}; \; \text{в матрице } "
        r"\delta {}^{3D}A_{n+1} \text{ каждый ее элемент умножается на } \cos\psi_i \cos\psi_j",
        "matrix",
        _eq26,
        "phi",
        "A",
        reading="Checked as 3D A_{n+1} - 3D A_n (padded) = (25) times cos psi_i cos psi_j on spatial chains.",
    ),
)


# ------------------------------------------------------------- the branch-sign rule of section 5
def branch_sign_readings(first_after_branch: int, n: int) -> dict[str, np.ndarray]:
    """The rule of section 5, "after the branch point, elements whose indices are greater than or
    equal to the indices of the links after the branch point change sign", read three ways for a
    chain whose links ``first_after_branch..n`` (1-based) follow the branch point: ``(n, n)`` sign
    matrices."""
    after = np.arange(1, n + 1) >= first_after_branch
    return {
        "either index after the branch point": np.where(after[:, None] | after[None, :], -1, 1),
        "both indices after the branch point": np.where(after[:, None] & after[None, :], -1, 1),
        "exactly one index after the branch point": np.where(after[:, None] ^ after[None, :], -1, 1),
    }


BRANCH_RULE = Printed(
    "branch",
    "section 5",
    "branch-point sign rule",
    r"\text{В случае ветвления звеньев ... у соответствующих элементов матриц, индексы которых больше или "
    r"равны индексам звеньев после разветвления, следует сменить знак на противоположный.}",
    "rule",
    reading="Applied to the planar matrices (A, Lambda, D, H of both blocks) of Fig. 5's links as a "
    "chain without reversal; compared with Fig. 5 (links 3, 4 after the branch point).",
)

ALL: tuple[Printed, ...] = EQUATIONS + TRANSITIONS + (BRANCH_RULE,)
