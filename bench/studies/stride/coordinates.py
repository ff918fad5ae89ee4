"""The stride's coordinates: which of the 2D human's are free, the left/right mirror, and the full stride.

**Free coordinates.** Of the 20 coordinates of :func:`exo_bench.models.mechanism.presets.human` (10 angles, 10
lengths), 13 are the optimiser's: the root's angle and length (where the hips are), HAT's angle, the
thigh, leg and foot angles of both legs, and the four telescopic rods' lengths (thighs and legs). The
rest are fixed: HAT's, the feet's and the heels' lengths at the anthropometric ones, and each heel's
angle at its foot's plus the standing arch (the foot is one rigid segment; its arch moment is what holds
it). So ``q = E z + c``, ``qd = E zd``, ``qdd = E zdd`` (:func:`free_map`).

**Mirror.** The half stride runs from the right heel's touchdown to the left's; its end is its start with
right and left exchanged (:func:`mirror_matrix`, a permutation of the free coordinates that keeps the
root's and HAT's) and the hips one half stride further on. The root's angle and length are polar
coordinates of the hips about O, so that move is not a permutation: :func:`shift_root` moves the hips by
``dx`` at unchanged velocity and acceleration. :func:`full_stride` builds the stored full stride from the
solved half.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exo_bench.models.mechanism.mechanism import Mechanism

SIDES = ("right", "left")
LEG_PARTS = ("thigh", "leg", "foot", "heel")
#: The telescopic actuators: the thigh and leg rods of both legs.
TELESCOPIC = tuple(f"{s}_{p}" for s in SIDES for p in ("thigh", "leg"))


@dataclass(frozen=True)
class FreeMap:
    """``q = E z + c`` (rates ``E zd``): ``E (dof, nz)``, ``c (dof,)``; ``free`` the coordinate index of
    each free one, ``names`` a readable name of each."""

    E: np.ndarray
    c: np.ndarray
    free: np.ndarray
    names: tuple[str, ...]

    @property
    def nz(self) -> int:
        return len(self.free)

    def full(self, z: np.ndarray, rates: bool = False) -> np.ndarray:
        """``q (K, dof)`` of free coordinates ``z (K, nz)`` (``rates``: without the constant)."""
        return z @ self.E.T + (0.0 if rates else self.c)

    def index(self, name: str) -> int:
        return self.names.index(name)


def _ix(mech: Mechanism) -> dict[str, int]:
    if mech.dim != 2 or mech.names != ("root", "hat", *(f"{s}_{p}" for s in SIDES for p in LEG_PARTS)):
        raise ValueError(f"stride: mechanism {mech.name!r}: expected the 2D human preset (presets.human(2))")
    return {name: i for i, name in enumerate(mech.names)}


def free_map(mech: Mechanism, standing: np.ndarray) -> FreeMap:
    """The free coordinates of the stride, with the fixed ones taken from the posture ``standing (1, dof)``."""
    ix, n = _ix(mech), mech.nlinks
    q0 = np.asarray(standing, dtype=float).reshape(-1)
    free, names = [ix["root"], ix["hat"]], ["root angle", "hat angle"]
    for s in SIDES:
        free += [ix[f"{s}_{p}"] for p in ("thigh", "leg", "foot")]
        names += [f"{s}_{p} angle" for p in ("thigh", "leg", "foot")]
    free += [n + ix["root"]]
    names += ["root length"]
    for r in TELESCOPIC:
        free.append(n + ix[r])
        names.append(f"{r} length")
    E = np.zeros((mech.dof, len(free)))
    E[free, np.arange(len(free))] = 1.0
    c = q0.copy()
    c[free] = 0.0
    for s in SIDES:  # the heel turns with the foot: q_heel = q_foot + (standing arch)
        heel, foot = ix[f"{s}_heel"], ix[f"{s}_foot"]
        E[heel, free.index(foot)] = 1.0
        c[heel] = q0[heel] - q0[foot]
    return FreeMap(E, c, np.array(free), tuple(names))


def mirror_matrix(fm: FreeMap) -> np.ndarray:
    """``P (nz, nz)``: the free coordinates with right and left exchanged (root and HAT kept)."""
    nz = fm.nz
    P = np.zeros((nz, nz))
    for i, name in enumerate(fm.names):
        other = name.replace("right_", "@").replace("left_", "right_").replace("@", "left_")
        P[i, fm.index(other)] = 1.0
    return P


def shift_root(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, root: int, n: int, dx: float):
    """Copies of ``q, qd, qdd (K, dof)`` with the hips (the root rod's end, polar ``(phi, l)`` about O)
    moved by ``dx`` along x at unchanged velocity and acceleration."""
    q, qd, qdd = q.copy(), qd.copy(), qdd.copy()
    phi, l = q[:, root], q[:, n + root]
    u = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    w = np.stack([-np.sin(phi), np.cos(phi)], axis=1)
    p = l[:, None] * u + np.array([dx, 0.0])
    v = qd[:, n + root, None] * u + (l * qd[:, root])[:, None] * w
    a = (qdd[:, n + root] - l * qd[:, root] ** 2)[:, None] * u
    a = a + (l * qdd[:, root] + 2 * qd[:, n + root] * qd[:, root])[:, None] * w
    phi2, l2 = np.arctan2(p[:, 1], p[:, 0]), np.hypot(p[:, 0], p[:, 1])
    u2 = np.stack([np.cos(phi2), np.sin(phi2)], axis=1)
    w2 = np.stack([-np.sin(phi2), np.cos(phi2)], axis=1)
    ld, phid = np.sum(v * u2, axis=1), np.sum(v * w2, axis=1) / l2
    ldd = np.sum(a * u2, axis=1) + l2 * phid**2
    phidd = (np.sum(a * w2, axis=1) - 2 * ld * phid) / l2
    q[:, root], q[:, n + root], qd[:, root], qd[:, n + root] = phi2, l2, phid, ld
    qdd[:, root], qdd[:, n + root] = phidd, ldd
    return q, qd, qdd


def full_stride(mech: Mechanism, fm: FreeMap, t: np.ndarray, z: np.ndarray, zd: np.ndarray, zdd: np.ndarray, dx: float):
    """``(t, q, qd, qdd)`` of the full stride (``2N + 1`` nodes) from the solved half (``N + 1`` nodes of
    free coordinates): the second half is the first mirrored with the hips ``dx`` (a half stride) on."""
    P = mirror_matrix(fm)
    ix = _ix(mech)
    q, qd, qdd = fm.full(z), fm.full(zd, rates=True), fm.full(zdd, rates=True)
    mq, mqd, mqdd = fm.full(z @ P.T), fm.full(zd @ P.T, rates=True), fm.full(zdd @ P.T, rates=True)
    mq, mqd, mqdd = shift_root(mq, mqd, mqdd, ix["root"], mech.nlinks, dx)
    T = t[-1]
    return (
        np.concatenate([t, T + t[1:]]),
        np.concatenate([q, mq[1:]]),
        np.concatenate([qd, mqd[1:]]),
        np.concatenate([qdd, mqdd[1:]]),
    )


__all__ = ["TELESCOPIC", "FreeMap", "free_map", "full_stride", "mirror_matrix", "shift_root"]
