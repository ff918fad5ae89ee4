"""External forces at the point masses (``f_ext``): ground contact, human-exoskeleton interaction, loads.

**Layout.** ``f_ext`` is batch-first, ``(samples, links, 3, dim)``, or ``(links, 3, dim)`` for one
sample: the force in newtons, in world axes (``x, y`` in 2D, ``x, y, z`` in 3D; gravity acts along
the last), at the start, middle and end point mass of every link (:data:`POINTS`, the order of
:func:`exo_bench.models.mechanism.kinematics.point_mass_positions`). A point need not carry mass: a force at a
middle point of zero mass acts at fraction ``n_i`` of the rod all the same. Build it by name with
:func:`forces_at`, never by position.

**Physics.** Point ``k`` of link ``i`` sits at ``P_k = sum_{a in anc(i)} r_a + f r_i``, ``f`` in
``{0, n_i, 1}``. A force ``f_k`` there does virtual work ``f_k . dP_k``, so its generalised force is
``Q = sum_k J_k^T f_k``: for each rod ``a``,

    Q_a = J_a(q_a)^T F_a,    F_a = sum_k c_ak f_k   (c = 1 beyond rod a, f on rod a itself),

``F_a`` summed leaves first as Newton-Euler's backward pass sums its ``D`` (:func:`rod_loads`), and
``J_a^T F`` the projection of :func:`exo_bench.models.mechanism.rod_elements.project_2d`/``_3d``, the rod
elements newton-euler's kernels inline too. One implementation serves every method:

* inverse dynamics: ``ID(q, qd, qdd) - Q(q, f_ext)``;
* forward dynamics: ``FD(q, qd, tau + Q(q, f_ext))``;
* derivatives: ``dtau/dq`` gains ``-dQ/dq`` (:func:`dQ_dq`; :func:`inverse_derivatives` and
  :func:`forward_derivatives` wrap ``model.derivatives``' calls), block-diagonal per rod since ``F_a`` is
  fixed in the world: ``d(J_a^T F_a)/dq_a``. Each term of the projection holds one of ``(cos x, sin x)``
  of an angle ``x`` or none, so its derivative is the projection at ``x + pi/2`` without the terms
  free of ``x`` (in ``phi``: those of ``F_z``); in ``l``, the projection at ``l = 1`` without ``u.F``.

The engines (Pinocchio ``fext``, MuJoCo ``xfrc_applied``, Drake's applied spatial forces) supply their
own ``Q`` (``PreparedModel._external_forces``), so the methods cross-validate (docs/external-forces.md).

**Speed.** Every other model's calls with ``f_ext`` run the compiled ``Q`` of
:mod:`exo_bench.models.runtime.external_forces`, bound once per model: one sample costs the call
without ``f_ext`` plus array checks and one compiled pass (bench/test_external_forces.py).

**Compiled.** The compiled generalised forces of ``f_ext``, ``Q(q, f_ext)``, and the calls' fast path.

One numba kernel, :func:`kernel` (models/runtime/external_forces_kernel.py), serves the generalised forces themselves
(:func:`generalized_forces_compiled`) and inverse and forward dynamics with ``f_ext``
(:mod:`exo_bench.models.runtime.external_forces`): ``dest = tau - Q``, ``tau + Q`` or ``Q``, over flat
C-ordered float64 arrays of any number of samples, with an optional finiteness check of the forces
in the same pass. It holds the arithmetic of :func:`exo_bench.models.runtime.external_forces.generalized_forces`
(the same leaves-first sums, the same rod projections as :mod:`exo_bench.models.mechanism.rod_elements`), so its
numbers are the numpy ones to the last bit.

A prepared model binds what is fixed once (:func:`bound`: the mechanism's parent indices, signs and
middle fractions as one parameter array, and whether the model's ``Q`` is this one: the engines
supply their own), so a call rebuilds nothing: one sample costs the call without ``f_ext``, a few
array checks and one compiled call (bench/test_external_forces.py times it).

**Memory safety.** The kernel reads and writes nothing outside its arrays whatever it is given: it
compares every array's size with what the parameters and the sample count imply and answers
:data:`BAD_SIZE` without touching anything when they differ. Its status is otherwise :data:`DONE`,
or the flat index of the first force that is not finite (``check``: nothing written), which the
caller names (:func:`exo_bench.models.runtime.external_forces.check_f_ext`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import cache
from typing import Any

import numpy as np
from exo_bench.models.machine.memory import check_batch
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.mechanism.rod_elements import project_2d, project_3d
from exo_bench.models.states.array_gate import as_out, converted, is_plain, real_numbers_problem
from exo_bench.models.states.array_gate import as_states as gate_states
from exo_bench.models.states.states import as_states, coordinate_names

#: The kernel's status: done, or the arrays' sizes disagree with the parameters (nothing touched).
DONE, BAD_SIZE = -1, -2
#: What the kernel writes into ``dest``: ``tau - Q`` (inverse dynamics), ``tau + Q`` (forward), ``Q``.
MINUS, PLUS, ONLY = -1, 1, 0

F8 = np.dtype(np.float64)


def parameters(mech: Mechanism) -> np.ndarray:
    """The kernel's parameter array: ``[dim, parent..., sign..., n...]`` (parents as floats, -1 for a root)."""
    return np.concatenate(([float(mech.dim)], np.asarray(mech.parent, float), mech.sign_array, mech.n))


@cache
def kernel() -> Callable[..., int]:
    """The compiled kernel ``(params, q, f, tau, dest, mode, check) -> status`` (module text):
    :func:`exo_bench.models.runtime.external_forces_kernel.apply`'s compiled entry point for flat C-ordered
    float64 arrays, an int64 ``mode`` and a boolean ``check``, loaded from numba's on-disk cache or
    compiled on the first call in a process. ``q``, ``tau``, ``dest``: ``(samples * dof,)``; ``f``:
    ``(samples * links * 3 * dim,)``; ``mode``: :data:`MINUS`, :data:`PLUS` or :data:`ONLY` (``tau``
    unread). ``dest`` may be ``tau``; any other overlap with the inputs is the caller's to avoid.

    The entry point types nothing (no dispatch: a call costs the unboxing and the pass), so its
    callers pass exactly those types (:func:`flat`, ``np.empty``); under ``NUMBA_DISABLE_JIT`` it is
    the Python function."""
    from exo_bench.models.machine.numba_runtime import ensure, jit_disabled

    ensure()  # before the kernel is defined: numba's cache locators
    from exo_bench.models.runtime.external_forces_kernel import apply

    if jit_disabled():
        return apply
    from numba import types

    flat_f8 = types.Array(types.float64, 1, "C")
    return apply.compile((flat_f8, flat_f8, flat_f8, flat_f8, flat_f8, types.int64, types.boolean))


def flat(a: Any) -> np.ndarray:
    """``a`` as a flat plain float64 array (:func:`exo_bench.models.states.array_gate.is_plain`: a view where it
    is one already, else a fresh base-class copy)."""
    if not is_plain(a):
        a = np.array(a, dtype=F8, order="C", subok=False)
    return a.reshape(-1)


def generalized_forces_compiled(
    mech: Mechanism, q: np.ndarray, f: np.ndarray, params: np.ndarray | None = None
) -> np.ndarray:
    """:func:`exo_bench.models.runtime.external_forces.generalized_forces` by the compiled kernel (float64 ``q (S,
    dof)``, ``f (S, links, 3, dim)``): ``(S, dof)``."""
    q2 = np.ascontiguousarray(q, dtype=float)
    out = np.empty(q2.shape)
    p = parameters(mech) if params is None else params  # a prepared model passes its own (:func:`bound`)
    status = kernel()(p, q2.reshape(-1), flat(f), out.reshape(-1), out.reshape(-1), ONLY, False)
    if status != DONE or out.shape[-1:] != (mech.dof,):
        raise ValueError(
            f"f_ext: expected q of shape (samples, {mech.dof}) and forces of shape (samples, {mech.nlinks}, 3, "
            f"{mech.dim}), got {q2.shape} and {np.shape(f)}"
        )
    return out


@dataclass(frozen=True)
class Bound:
    """What a prepared model's calls with ``f_ext`` need, bound once (:func:`bound`)."""

    params: np.ndarray
    apply: Callable[..., int] | None  # the kernel; None: the model has its own Q (an engine)
    forces: tuple[int, int, int]  # one sample's f_ext shape, (links, 3, dim)
    dof: int


def bound(model: Any) -> Bound:
    """The :class:`Bound` of a prepared model, made on its first call with ``f_ext`` and kept on it."""
    b = model.__dict__.get("_f_ext_bound")
    if b is None:
        mech = model.mechanism
        # the model's Q is PreparedModel's default (the first class in its lineage to define one; not
        # imported here: prepared imports this module's callers), not an engine's override
        cls = type(model)
        first = next(c for c in reversed(cls.__mro__) if "_external_forces" in vars(c))
        native = cls._external_forces is vars(first)["_external_forces"]
        b = Bound(parameters(mech), kernel() if native else None, (mech.nlinks, 3, mech.dim), mech.dof)
        model.__dict__["_f_ext_bound"] = b
    return b


#: The points of every link, in the order of ``f_ext``'s third axis.
POINTS = ("start", "middle", "end")


# ----------------------------------------------------------------------------- building and checking
def forces_at(mech: Mechanism, loads: Mapping[tuple[str, str], Any], samples: int | None = None) -> np.ndarray:
    """``f_ext`` from named points: ``loads[(link name, point)]`` is a force ``(dim,)`` or, for a batch,
    ``(samples, dim)``; ``point`` is one of :data:`POINTS`. Returns ``(links, 3, dim)`` with
    ``samples=None``, else ``(samples, links, 3, dim)``; points not named get zero. A name that is not
    the mechanism's is a ValueError listing the names."""
    d = mech.dim
    if samples is not None and not (
        isinstance(samples, int | np.integer) and not isinstance(samples, bool) and samples >= 0
    ):
        raise ValueError(f"f_ext: field 'samples': expected None or a count >= 0, got {samples!r}")
    out = np.zeros((mech.nlinks, 3, d) if samples is None else (samples, mech.nlinks, 3, d))
    for key, value in loads.items():
        if not (isinstance(key, tuple) and len(key) == 2):
            raise ValueError(f"f_ext: expected keys (link name, point), got {key!r}")
        link, point = key
        if link not in mech.names:
            raise ValueError(f"f_ext: link {link!r}: expected one of {', '.join(map(repr, mech.names))}")
        if point not in POINTS:
            raise ValueError(f"f_ext: link {link!r}: point {point!r}: expected one of {', '.join(POINTS)}")
        i, b = mech.names.index(link), POINTS.index(point)
        why = real_numbers_problem(value)
        if why:
            raise ValueError(f"f_ext: link {link!r}, point {point!r}: expected a force of real numbers, got {why}")
        v = np.asarray(value, dtype=float)
        want = (d,) if samples is None else (samples, d)
        if v.shape != want and not (samples is not None and v.shape == (d,)):
            raise ValueError(f"f_ext: link {link!r}, point {point!r}: expected a force of shape {want}, got {v.shape}")
        out[..., i, b, :] = v
    return out


def check_f_ext(mech: Mechanism, f_ext: Any, q_shape: tuple, check: bool = True, method: str = "") -> np.ndarray:
    """``f_ext`` as a C-ordered float64 ``(samples, links, 3, dim)`` array for states of shape
    ``q_shape``, ``(dof,)`` or ``(samples, dof)``. Its shape is always checked (``check=False``
    included: a wrong shape would broadcast silently); with ``check`` every value must be finite
    (a ValueError naming the sample, the link, the point, the expected and the actual value)."""
    who = f"{method}: " if method else ""
    want = (mech.nlinks, 3, mech.dim)
    full = (*q_shape[:-1], *want)
    try:
        shape = getattr(f_ext, "shape", None) if check is False else np.shape(f_ext)
    except ValueError:  # ragged nested lists
        shape = None
    if shape is None or tuple(shape) != full:
        raise ValueError(
            f"{who}field 'f_ext': expected forces of shape {full} (samples, links, 3 points: start, middle, "
            f"end, dim; one sample: {want}) in newtons, world axes, got {shape}"
        )
    why = real_numbers_problem(f_ext)
    if why:
        raise ValueError(f"{who}field 'f_ext': expected forces in newtons (numbers), got {why}")
    try:
        f = np.ascontiguousarray(f_ext, dtype=float).reshape(-1, *want)
    except (ValueError, TypeError, OverflowError) as e:  # entries that are not numbers
        raise ValueError(f"{who}field 'f_ext': expected forces in newtons (numbers), got {e}") from None
    if check and not np.isfinite(f).all():
        s, i, b, c = (int(x) for x in np.argwhere(~np.isfinite(f))[0])
        raise ValueError(
            f"{who}field 'f_ext': sample {s}, link {i + 1} ({mech.names[i]!r}), point {POINTS[b]!r}, component "
            f"{'xyz'[c]}: expected a finite force in newtons, got {f[s, i, b, c]}"
        )
    return f


def _tau(mech: Mechanism, tau: Any, shape: tuple, source: str) -> np.ndarray | None:
    """``tau`` beside ``f_ext`` read as without it, by the states' converter (models/states/array_gate.py:
    real numbers only, a ValueError naming 'tau'); one sample stays 1-D; None stays None."""
    if tau is None:
        return None
    t = converted(tau, "tau", source, coordinate_names(mech))
    return t[0] if len(shape) == 1 and np.ndim(tau) == 1 else t


def refuse_overflow(mech: Mechanism, who: str, f: np.ndarray, result: np.ndarray, what: str) -> None:
    """With finite forces ``f`` (flat or ``(samples, links, 3, dim)``), a ValueError naming ``f_ext`` and
    the first sample where ``result`` (``what``: Q added to tau, dQ/dq) is not finite: forces too large
    for float64, never returned as inf or NaN nor blamed on another field. One isfinite pass when all
    is finite."""
    if np.isfinite(result).all():  # no np.errstate on this path: entering one costs ~5 us
        return
    forces = np.asarray(f).reshape(-1, mech.nlinks * 3 * mech.dim)  # one row per sample, as result's
    bad = ~np.isfinite(result.reshape(forces.shape[0], -1)).all(axis=1)
    if not bad.any():
        return
    s = int(np.argmax(bad))
    big = float(np.abs(forces[s]).max())
    raise ValueError(
        f"{who}: field 'f_ext': sample {s}: expected forces whose {what} is finite in float64, got "
        f"{what} not finite (largest |force| {big:.3g} N); express the forces in other units"
    )


# ----------------------------------------------------------------------------- Q and its derivative
def rod_loads(mech: Mechanism, f: np.ndarray) -> np.ndarray:
    """``F_a = sum_k c_ak f_k``, ``(samples, links, dim)``, summed leaves first (children have larger
    indices than their parents): a link's own points weighted by their fractions, its subtree's whole."""
    own = np.einsum("ib,sibd->sid", mech.fractions, f)
    through = f.sum(axis=2)  # what a link and its subtree pass to the parent
    F = own.copy()
    for k in range(mech.nlinks - 1, -1, -1):
        p = mech.parent[k]
        if p >= 0:
            through[:, p] += through[:, k]
            F[:, p] += through[:, k]
    return F


def _trig(mech: Mechanism, q):
    n = mech.nlinks
    cf, sf = np.cos(q[:, :n]), np.sin(q[:, :n])
    if mech.dim == 2:
        return cf, sf, None, None
    return cf, sf, np.cos(q[:, n : 2 * n]), np.sin(q[:, n : 2 * n])


def _project(mech: Mechanism, trig, l, F) -> list:
    """Signed ``J_a^T F_a`` of every rod: one ``(samples, links)`` array per coordinate block."""
    cf, sf, cp, sp = trig
    s = mech.sign_array[None, :]
    if mech.dim == 2:
        parts = project_2d(cf, sf, l, F[..., 0], F[..., 1])
    else:
        parts = project_3d(cf, sf, cp, sp, l, F[..., 0], F[..., 1], F[..., 2])
    return [s * x for x in parts]


def generalized_forces(mech: Mechanism, q, f) -> np.ndarray:
    """``Q(q, f_ext) = sum_k J_k^T f_k``, ``(samples, dof)`` in block order, for ``q`` ``(samples, dof)``
    and ``f`` ``(samples, links, 3, dim)`` (real or complex: complex-step derivatives)."""
    n = mech.nlinks
    return np.concatenate(_project(mech, _trig(mech, q), q[:, -n:], rod_loads(mech, f)), axis=1)


def dQ_dq(mech: Mechanism, q, f) -> np.ndarray:
    """``dQ/dq``, ``(samples, dof, dof)``: rod ``a``'s block ``d(J_a^T F_a)/dq_a`` (zero elsewhere: the
    forces are fixed in the world). Inverse dynamics with ``f_ext`` adds ``-dQ/dq`` to ``dtau/dq``;
    forward dynamics adds ``M^-1 dQ/dq`` to ``dqdd/dq``."""
    n, d = mech.nlinks, mech.dim
    cf, sf, cp, sp = _trig(mech, q)
    l, F = q[:, -n:], rod_loads(mech, f)
    one = np.ones_like(l)
    # columns: Q at phi + pi/2 (its terms free of phi, F_z's in 3D, dropped), psi + pi/2, and l = 1
    horizontal = F.copy()
    horizontal[..., 2:] = 0.0
    columns = (
        [(-sf, cf, cp, sp, l, horizontal)] + ([(cf, sf, -sp, cp, l, F)] if d == 3 else []) + [(cf, sf, cp, sp, one, F)]
    )
    out = np.zeros((q.shape[0], d * n, d * n), dtype=np.result_type(q, f))
    idx = np.arange(n)
    for c, (a, b, e, g, length, load) in enumerate(columns):
        parts = _project(mech, (a, b, e, g), length, load)
        if c == d - 1:  # d/dl: J^T F is linear in l except its last component, u.F
            parts[-1] = np.zeros_like(parts[-1])
        for r, part in enumerate(parts):
            out[:, r * n + idx, c * n + idx] = part
    return out


def point_forces(mech: Mechanism, f: np.ndarray):
    """``(link, point, force (3,))`` of one sample's forces ``(links, 3, dim)`` at the engines' bodies (Pinocchio, MuJoCo, Drake):
    a middle point of zero mass has none, so its force goes ``(1 - n) : n`` to the start and the end
    (``P_mid = (1 - n) P_start + n P_end``: the same virtual work)."""
    for i in range(mech.nlinks):
        for b in range(3):
            force = np.zeros(3)
            force[: mech.dim] = f[i, b]
            if b == 1 and mech.masses[i][1] <= 0.0:
                yield i, 0, (1.0 - mech.n[i]) * force
                yield i, 2, mech.n[i] * force
            elif force.any():
                yield i, b, force


# ----------------------------------------------------------------------------- the calls
def inverse_dynamics(model: Any, q, qd, qdd, f_ext, check: bool, out) -> np.ndarray:
    """``model.inverse_dynamics(q, qd, qdd) - Q(q, f_ext)`` (``PreparedModel.inverse_dynamics`` with
    ``f_ext``): the states checked by the call itself, ``f_ext``'s shape always and its values with
    ``check`` (:func:`check_f_ext`'s messages), ``out`` as there. ``Q`` by the model's bound compiled
    kernel (:mod:`exo_bench.models.runtime.external_forces`; an engine's own ``Q`` otherwise)."""
    b = model.__dict__.get("_f_ext_bound") or bound(model)
    check_batch("inverse dynamics with f_ext", q, b.dof, 6 * b.dof + int(np.prod(b.forces)))  # before any copy
    tau = model.inverse_dynamics(q, qd, qdd, check=check)
    f = _forces(model, b, f_ext, tau.shape, check)
    if b.apply is None:
        q2 = np.ascontiguousarray(q, dtype=float).reshape(-1, b.dof)
        tau = tau - model._external_forces(q2, f.reshape(-1, *b.forces)).reshape(tau.shape)
    else:
        dest = np.empty(tau.shape)
        status = b.apply(b.params, flat(q), f, flat(tau), dest.reshape(-1), MINUS, bool(check))
        if status != DONE:
            _refuse(model, f, tau.shape, status)
        tau = dest
    if check:
        refuse_overflow(model.mechanism, model.method, f, tau, "tau - Q")
    if out is None:
        return tau
    as_out(out, tau.shape, model.method)
    out[...] = tau
    return out


def _forces(model: Any, b: Bound, f_ext: Any, shape: tuple, check: bool) -> np.ndarray:
    """``f_ext`` flat and C-ordered float64 for states of ``shape``: its shape checked (always); its
    values by :func:`check_f_ext` unless it is such an array already (then the kernel checks them)."""
    if is_plain(f_ext) and f_ext.shape == (b.forces if len(shape) == 1 else (*shape[:-1], *b.forces)):
        return f_ext.reshape(-1)
    return check_f_ext(model.mechanism, f_ext, shape, check, model.method).reshape(-1)


def _refuse(model: Any, f: np.ndarray, shape: tuple, status: int) -> None:
    """The ValueError of a kernel's status other than done: the force that is not finite, named by
    :func:`check_f_ext`, or sizes that disagree."""
    mech = model.mechanism
    if status >= 0:
        check_f_ext(mech, f.reshape(*shape[:-1], mech.nlinks, 3, mech.dim), shape, True, model.method)
    raise ValueError(
        f"{model.method}: field 'f_ext': expected forces of shape {(*shape[:-1], mech.nlinks, 3, mech.dim)} for "
        f"states of shape {shape}, got {f.size} numbers"
    )


def forward_dynamics(model: Any, q, qd, tau, f_ext, check: bool, out) -> np.ndarray:
    """``model.forward_dynamics(q, qd, tau + Q(q, f_ext))`` (``PreparedModel.forward_dynamics`` with
    ``f_ext``): ``q`` and the shapes checked here first (``Q`` needs them), the rest by the call. Arrays
    ``q`` and ``tau`` of one shape ``(dof,)`` or ``(samples, dof)`` go straight to the compiled ``Q``
    (a bad value in ``q`` is then named by the call, as without ``f_ext``)."""
    b = model.__dict__.get("_f_ext_bound") or bound(model)
    check_batch("forward dynamics with f_ext", q, b.dof, 6 * b.dof + int(np.prod(b.forces)))  # before any copy
    if (
        b.apply is not None
        and type(q) is np.ndarray
        and type(tau) is np.ndarray
        and q.shape == tau.shape
        and tau.dtype.kind in "iuf"
        and 0 < q.ndim <= 2
        and q.shape[-1] == b.dof
    ):
        f = _forces(model, b, f_ext, q.shape, check)
        total = np.empty(q.shape)
        status = b.apply(b.params, flat(q), f, flat(tau), total.reshape(-1), PLUS, bool(check))
        if status != DONE:
            _refuse(model, f, q.shape, status)
        if check:
            refuse_overflow(model.mechanism, model.method, f, total, "tau + Q")
        return model.forward_dynamics(q, qd, total, check=check, out=out)
    mech = model.mechanism
    if check:
        shape = np.shape(q)
        q2, _, _ = as_states(mech, q, source="forward dynamics")
        t = _tau(mech, tau, shape, "forward dynamics")
        if t is None or t.shape != shape:
            raise ValueError(
                f"{model.method}: forward dynamics: field 'tau': expected an array of the shape of q, {shape}, "
                f"got {None if t is None else t.shape}"
            )
    else:
        q, qd, tau = gate_states((q, qd, tau), ("q", "qd", "tau"), model.dof, model.method, False)
        if out is not None:
            as_out(out, q.shape, model.method, (q, qd, tau), ("q", "qd", "tau"))
        shape, q2, t = q.shape, q.reshape(-1, model.dof), tau
    f = check_f_ext(mech, f_ext, shape, check, model.method)
    total = t + model._external_forces(q2, f).reshape(shape)
    if check:
        refuse_overflow(model.mechanism, model.method, f, total, "tau + Q")
    return model.forward_dynamics(q, qd, total, check=check, out=out)


def inverse_derivatives(model: Any, q, qd, qdd, f_ext, check: bool = True):
    """``model.derivatives.inverse_dynamics`` with ``f_ext``: ``(dtau_dq - dQ/dq, dtau_dqd, M)``, shapes as
    there (``Q`` does not depend on the rates nor on ``qdd``)."""
    dq, dqd, M = model.derivatives.inverse_dynamics(q, qd, qdd, check=check)
    q2 = np.ascontiguousarray(q, dtype=float).reshape(-1, model.dof)
    f = check_f_ext(model.mechanism, f_ext, q2.shape if dq.ndim == 3 else (model.dof,), check, model.method)
    dQ = dQ_dq(model.mechanism, q2, f)
    if check:
        refuse_overflow(model.mechanism, model.method, f, dQ, "dQ/dq")
    return dq - dQ.reshape(dq.shape), dqd, M


def forward_derivatives(model: Any, q, qd, tau, f_ext, check: bool = True):
    """``model.derivatives.forward_dynamics`` with ``f_ext``: at ``tau + Q``, ``(qdd, dqdd_dq + M^-1 dQ/dq,
    dqdd_dqd, M^-1)``, shapes as there."""
    q2 = np.ascontiguousarray(q, dtype=float).reshape(-1, model.dof)
    t = _tau(model.mechanism, tau, np.shape(q), "forward-dynamics derivatives") if check else np.asarray(tau, float)
    f = check_f_ext(model.mechanism, f_ext, np.shape(q), check, model.method)
    if t is None or t.shape != np.shape(q):
        raise ValueError(
            f"{model.method}: field 'tau': expected an array of the shape of q, {np.shape(q)}, "
            f"got {None if t is None else t.shape}"
        )
    total = t + model._external_forces(q2, f).reshape(t.shape)
    if check:
        refuse_overflow(model.mechanism, model.method, f, total, "tau + Q")
    qdd, aq, aqd, minv = model.derivatives.forward_dynamics(q, qd, total, check=check)
    return qdd, aq + minv @ dQ_dq(model.mechanism, q2, f).reshape(aq.shape), aqd, minv
