"""Sympy symbols shared by every symbolic implementation, so their expressions compare directly.

Coordinates, rates and accelerations are plain symbols (not functions of time):
``phi1..phin``, ``psi1..psin``, ``l1..ln`` and ``dphi1``, ``ddphi1`` and so on. Parameters are
``m{i}_{beta}`` (beta = 0, 1, 2), ``n{i}`` and ``g``; links are numbered from 1 as in the paper.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import sympy as sp

from exo_bench.models.mechanism.mechanism import Mechanism


@dataclass(frozen=True)
class Symbols:
    phi: tuple[sp.Symbol, ...]
    psi: tuple[sp.Symbol, ...]  # empty in 2D
    l: tuple[sp.Symbol, ...]
    dphi: tuple[sp.Symbol, ...]
    dpsi: tuple[sp.Symbol, ...]
    dl: tuple[sp.Symbol, ...]
    ddphi: tuple[sp.Symbol, ...]
    ddpsi: tuple[sp.Symbol, ...]
    ddl: tuple[sp.Symbol, ...]
    m: tuple[tuple[sp.Symbol, sp.Symbol, sp.Symbol], ...]
    n: tuple[sp.Symbol, ...]
    g: sp.Symbol

    @property
    def q(self) -> tuple[sp.Symbol, ...]:
        """Coordinates in block order ``[phi..., psi..., l...]``."""
        return self.phi + self.psi + self.l

    @property
    def qd(self) -> tuple[sp.Symbol, ...]:
        return self.dphi + self.dpsi + self.dl

    @property
    def qdd(self) -> tuple[sp.Symbol, ...]:
        return self.ddphi + self.ddpsi + self.ddl

    def parameter_values(self, mech: Mechanism) -> dict[sp.Symbol, float]:
        """Numeric values of the mass, fraction and gravity symbols for a mechanism."""
        out: dict[sp.Symbol, float] = {self.g: mech.g}
        for i in range(mech.nlinks):
            out[self.n[i]] = mech.n[i]
            for b in range(3):
                out[self.m[i][b]] = mech.masses[i][b]
        return out


@lru_cache(maxsize=64)  # keyed on a user n: bounded (issue 34); equal names give equal sympy symbols
def symbols_for(nlinks: int, dim: int) -> Symbols:
    """The shared symbols of an ``nlinks``-link model in ``dim`` dimensions (real-valued)."""
    k = range(1, nlinks + 1)
    mk = lambda p: tuple(sp.Symbol(f"{p}{i}", real=True) for i in k)
    psi = lambda p: mk(p) if dim == 3 else ()
    return Symbols(
        phi=mk("phi"),
        psi=psi("psi"),
        l=mk("l"),
        dphi=mk("dphi"),
        dpsi=psi("dpsi"),
        dl=mk("dl"),
        ddphi=mk("ddphi"),
        ddpsi=psi("ddpsi"),
        ddl=mk("ddl"),
        m=tuple(tuple(sp.Symbol(f"m{i}_{b}", nonnegative=True) for b in range(3)) for i in k),
        n=tuple(sp.Symbol(f"n{i}", positive=True) for i in k),
        g=sp.Symbol("g", real=True),
    )
