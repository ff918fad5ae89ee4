"""Errata study, the cases: which models and seeded states each printed formula is checked on.

The evaluation reads the settings through this module (``cases.SAMPLES``, ``cases.spatial_models()``),
so that a test can shrink the study by patching them here.
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from exo_bench.models.mechanism.mechanism import Mechanism, split
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import chain, exo5, fig1, fig2a, fig2b, fig5, random_tree

SAMPLES = 12
SEED = 20240
#: (links, seed) of the random 3D trees eq. (18) is checked on, besides the paper's own models
TREES = ((2, 1), (3, 2), (3, 5), (4, 3), (4, 8), (4, 11))
CHAIN_LENGTHS = (1, 2, 3, 4, 5)


def states(mech: Mechanism, seed: int):
    """``SAMPLES`` seeded random states ``(q, qd, qdd)`` of ``mech``."""
    return random_states(mech, SAMPLES, seed)


def prefix(mech: Mechanism, n: int) -> Mechanism:
    """The model of the first n links."""
    return mech.replace(
        parent=mech.parent[:n],
        sign=mech.sign[:n],
        masses=mech.masses[:n],
        n=mech.n[:n],
        names=mech.names[:n],
        name=f"{mech.name}[:{n}]",
    )


def prefix_states(mech: Mechanism, q: np.ndarray, n: int) -> np.ndarray:
    N = mech.nlinks
    return np.concatenate([q[:, b * N : b * N + n] for b in range(mech.dim)], axis=1)


def planar_states(mech: Mechanism, q: np.ndarray) -> np.ndarray:
    phi, _, l = split(mech, q)
    return np.concatenate([phi, l], axis=1)


def spatial_models() -> list[Mechanism]:
    return [fig2a(3), fig2b(3), fig5(3), exo5(3)] + [random_tree(n, 3, s) for n, s in TREES]


def equation_models(key: str):
    """The models and reference rows of a printed equation."""
    if key == "2":
        return [fig1(2)], None
    if key == "4+":
        return [fig2a(2)], None
    if key == "4-":
        return [fig2b(2)], None
    if key in ("13", "14", "15"):
        return [fig1(3)], [int(key) - 13]
    if key == "20":
        return [fig5(2)], "A phi'' row 1"
    raise KeyError(key)


def chains(dim: int = 2) -> list[Mechanism]:
    """Seeded random chains of 1..5 links; each is the prefix of the next (eq. 25 needs that)."""
    longest = chain(max(CHAIN_LENGTHS) + 1, dim, seed=SEED)
    return [prefix(longest, n) for n in CHAIN_LENGTHS + (max(CHAIN_LENGTHS) + 1,)]


def matrix_cases(key: str) -> list[tuple[Mechanism, Mechanism | None]]:
    """The models of a printed matrix formula, each with the smaller model whose matrix a
    recurrence (eqs. 25, 26) adds to (None for a direct formula)."""
    if key in ("6", "22"):
        return [(m, None) for m in chains(2)[:-1]]
    if key == "19":
        return [(fig5(2), None)]
    if key == "21":
        return [(fig5(3), None)]
    if key in ("25", "26"):
        cs = chains(2 if key == "25" else 3)
        return [(cs[k + 1], cs[k]) for k in range(len(cs) - 1)]
    raise KeyError(key)


def singular_configuration() -> tuple[Mechanism, np.ndarray]:
    """A 3-link chain at an exactly singular state: ``phi = (pi/2, 0, pi/4)`` makes
    ``cos phi_1 = 0``, ``sin phi_2 = 0`` and ``cos(phi_1 - phi_2) = 0``, and ``l_3 = 0`` (a rod
    retracted to zero length, the divisor of the printed ``k^l``); exact sympy numbers."""
    mech = chain(3, 3, seed=SEED)
    q = np.array(
        [
            sp.pi / 2,
            sp.S.Zero,
            sp.pi / 4,
            sp.Rational(1, 3),
            sp.Rational(-1, 5),
            sp.Rational(2, 7),
            sp.Rational(1, 2),
            sp.Rational(3, 4),
            sp.S.Zero,
        ],
        dtype=object,
    )
    return mech, q
