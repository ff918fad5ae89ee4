"""Errata study, the evaluation: each printed formula against the witnesses, the verdicts, the
singular points of eq. (18) and the effect of the misprints on the gait.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from exo_bench.bench.studies.errata import cases
from exo_bench.bench.studies.errata.witnesses import (
    LagrangeWitness,
    PinocchioWitness,
    form_residual,
    pinocchio_matrices,
)
from exo_bench.matrix_method.numpy_kernels import matrix as numeric
from exo_bench.matrix_method import printed
from exo_bench.matrix_method.printed import Printed
from exo_bench.models.engines import pinocchio_backend as pb
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.gait.motion import gait, random_states
from exo_bench.models.mechanism.presets import exo5, fig5, random_tree

#: A formula holds when its largest error relative to the witness's largest magnitude is at most
#: this, for both witnesses on every model.
TOLERANCE = 1e-9


@dataclass
class Check:
    """One formula on one model against one witness."""

    model: str
    witness: str
    error: float = math.nan  # largest |printed - witness|
    scale: float = math.nan  # largest |witness| (the error is relative to it)
    corrected: float = math.nan  # relative error of the corrected form, if any
    method: float = math.nan  # relative error of the matrix method's element (eq. 18 lines)
    nan: int = 0  # NaN entries of the printed form
    skipped: str = ""

    @property
    def relative(self) -> float:
        return self.error / self.scale if self.scale > 0 else self.error


@dataclass
class Verdict:
    formula: Printed
    checks: list[Check] = field(default_factory=list)
    note: str = ""
    label_exists: bool = True

    def _done(self):
        return [c for c in self.checks if not c.skipped]

    @property
    def largest(self) -> float:
        done = self._done()
        return max((c.relative for c in done), default=math.nan)

    @property
    def largest_corrected(self) -> float:
        vals = [c.corrected for c in self._done() if not math.isnan(c.corrected)]
        return max(vals, default=math.nan)

    @property
    def largest_method(self) -> float:
        vals = [c.method for c in self._done() if not math.isnan(c.method)]
        return max(vals, default=math.nan)

    @property
    def status(self) -> str:
        if self.formula.kind == "notation":
            return "not checkable"
        done = self._done()
        if not done:
            return "not checked"
        values_hold = all(c.relative <= TOLERANCE and c.nan == 0 for c in done)
        if not self.label_exists:
            return "fails (left side)" if values_hold else "fails"
        return "holds" if values_hold else "fails"


# ------------------------------------------------------------------ helpers
def _rel(value, ref, scale=None):
    value, ref = np.asarray(value, float), np.asarray(ref, float)
    err = float(np.nanmax(np.abs(value - ref))) if np.isfinite(value).any() else math.nan
    s = float(np.abs(ref).max()) if scale is None else scale
    return err, s


def _model_scale(mats) -> float:
    return max(float(np.abs(m).max()) for ms in mats.values() for m in ms.values())


def _scale(ref, mats) -> float:
    """What an error is relative to: the largest ``|ref|``, or, for a reference that vanishes
    identically (``P_phi`` in 3D, ``G_l`` of two unrelated links; up to rounding), the largest
    element of the model's matrices."""
    model = _model_scale(mats)
    s = float(np.abs(ref).max())
    return s if s > 1e-12 * model else model


def _run(witnesses, mech: Mechanism, fn, verdict: Verdict):
    """Append one :class:`Check` per witness; ``fn(witness) -> Check fields``."""
    for w in witnesses:
        try:
            verdict.checks.append(Check(mech.name, w.name, **fn(w)))
        except Exception as e:  # noqa: BLE001 - a witness over its time budget is reported, not fatal
            reason = getattr(e, "skip_reason", None)
            if not reason:
                raise
            verdict.checks.append(Check(mech.name, w.name, skipped=str(reason)))


def check_transition(f: Printed, witnesses, models=None) -> Verdict:
    """A line of eq. (18): the printed right side from the witness's planar matrices of the same
    structure (and the 3D matrices a line names) against the witness's 3D matrix."""
    v = Verdict(f)
    if f.kind == "notation":
        v.note = f.reading
        return v
    for k, mech in enumerate(models or cases.spatial_models()):
        q, _, _ = cases.states(mech, cases.SEED + k)
        mech2 = mech.replace(dim=2, name=mech.name.replace("3d", "2d"))
        q2 = cases.planar_states(mech, q)

        def fn(w):
            planar, spatial = w.matrices(mech2, q2), w.matrices(mech, q)
            if f.printed_dim == 2:
                v.label_exists = v.label_exists and f.block in planar
            t = printed.transition_namespace(mech, q, planar, three_d=spatial)
            ref = spatial[f.block][f.name]
            scale = _scale(ref, spatial)
            with np.errstate(invalid="ignore", divide="ignore"):
                value = np.broadcast_to(f.fn(t), ref.shape)
                corr = np.broadcast_to(f.corrected(t), ref.shape) if f.corrected else None
            err, _ = _rel(value, ref)
            out = dict(
                error=err,
                scale=scale,
                nan=int(np.isnan(value).sum()),
                method=_rel(numeric.matrices(mech, q)[f.block][f.name], ref)[0] / scale,
            )
            if corr is not None:
                out["corrected"] = _rel(corr, ref)[0] / scale
            return out

        _run(witnesses, mech, fn, v)
    if f.printed_dim == 2:
        v.note = (
            "The printed left side is a 2D element; the witnesses' planar models have no psi block "
            f"(the left side {'exists' if v.label_exists else 'does not exist'}). " + f.reading
        )
    elif f.reading:
        v.note = f.reading
    return v


def check_equation(f: Printed, witnesses) -> Verdict:
    v = Verdict(f, note=f.reading)
    models, rows = cases.equation_models(f.key)
    for k, mech in enumerate(models):
        q, qd, qdd = cases.states(mech, cases.SEED + 100 + k)
        x = printed.equation_namespace(mech, q, qd, qdd)

        def fn(w):
            if rows == "A phi'' row 1":
                A = w.matrices(mech, q)["phi"]["A"]
                ref = np.einsum("sj,sj->s", A[:, 0, :], qdd[:, : mech.nlinks])[:, None]
            else:
                ref = w.equations(mech, q, qd, qdd)
                ref = ref if rows is None else ref[:, rows]
            value = f.fn(x)
            err, scale = _rel(value, ref)
            out = dict(error=err, scale=scale, nan=int(np.isnan(value).sum()))
            if f.corrected:
                out["corrected"] = _rel(f.corrected(x), ref)[0] / scale
            return out

        _run(witnesses, mech, fn, v)
    return v


def check_matrix(f: Printed, witnesses) -> Verdict:
    v = Verdict(f, note=f.reading)
    for k, (mech, smaller) in enumerate(cases.matrix_cases(f.key)):
        q, qd, qdd = cases.states(mech, cases.SEED + 200 + k)
        x = printed.equation_namespace(mech, q, qd, qdd)

        def fn(w):
            ref = w.matrices(mech, q)["phi"]["A"]
            if smaller is not None:  # A_{n+1} - (A_n padded), eqs. (23)-(24)
                n = smaller.nlinks
                pad = np.zeros_like(ref)
                pad[:, :n, :n] = w.matrices(smaller, cases.prefix_states(mech, q, n))["phi"]["A"]
                ref = ref - pad
            value = f.fn(x)
            err, scale = _rel(value, ref)
            return dict(error=err, scale=scale, nan=int(np.isnan(value).sum()))

        _run(witnesses, mech, fn, v)
    return v


def check_branch_rule(witnesses) -> dict[str, Verdict]:
    """The sign rule of section 5, three readings, on Fig. 5 (links 3, 4 after the branch point)."""
    branched = fig5(2)
    straight = branched.replace(sign=(1,) * branched.nlinks, name="fig5-2d as a chain")
    q, _, _ = cases.states(branched, cases.SEED + 300)
    out = {}
    for reading, sigma in printed.branch_sign_readings(3, branched.nlinks).items():
        v = Verdict(printed.BRANCH_RULE, note=f"Reading: {reading}.")

        def fn(w, sigma=sigma):
            a, b = w.matrices(straight, q), w.matrices(branched, q)
            err, scale = 0.0, _model_scale(b)
            for blk in b:
                for name in b[blk]:
                    s = np.where(np.arange(1, branched.nlinks + 1) >= 3, -1.0, 1.0) if name == "P" else sigma
                    err = max(err, float(np.abs(s * a[blk][name] - b[blk][name]).max()))
            return dict(error=err, scale=scale)

        _run(witnesses, branched, fn, v)
        out[reading] = v
    return out


def check_all(witnesses=None) -> list[Verdict]:
    witnesses = witnesses or [LagrangeWitness(), PinocchioWitness()]
    out = []
    for f in printed.EQUATIONS:
        out.append(check_equation(f, witnesses) if f.kind == "equation" else check_matrix(f, witnesses))
    models = cases.spatial_models()
    out.extend(check_transition(f, witnesses, models) for f in printed.TRANSITIONS)
    return out


@dataclass
class Singular:
    key: str
    divides_by: tuple[str, ...]
    exact_nan: int  # NaN entries of the printed form, exact arithmetic
    float_nan: int  # NaN entries at the nearest doubles
    float_error: float  # relative error of the finite printed entries at the nearest doubles
    matrix_error: float  # relative error of the matrix method (division-free) there


def check_singular() -> list[Singular]:
    """The lines of (18) that divide, at :func:`singular_configuration`. Misprinted lines are taken
    in their corrected form (still with the division), so that only the divisions are measured."""
    mech, q_exact = cases.singular_configuration()
    q = np.array([float(x) for x in q_exact])[None, :]
    table = printed.corrected_table([f.key for f in printed.TRANSITIONS if f.corrected is not None])
    exact = numeric.paper_matrices(mech, q_exact, table, exact=True)
    floating = numeric.paper_matrices(mech, q, table)
    ours = numeric.matrices(mech, q)
    ref = pinocchio_matrices(mech, q)
    out = []
    for f in printed.TRANSITIONS:
        if not f.divides_by:
            continue
        e = exact[f.block][f.name].ravel()
        fl = floating[f.block][f.name]
        r = ref[f.block][f.name]
        scale = _scale(r, ref)
        finite = np.isfinite(fl)
        out.append(
            Singular(
                f.key,
                f.divides_by,
                sum(1 for x in e if x is sp.nan or x in (sp.zoo, sp.oo, -sp.oo)),
                int((~finite).sum()),
                float(np.abs(fl - r)[finite].max()) / scale,
                float(np.abs(ours[f.block][f.name] - r).max()) / scale,
            )
        )
    return out


def gait_effect(samples: int = 111) -> dict:
    """``matrix-paper`` along the gait of Fig. 6 (eq. 26): NaN samples and errors vs Pinocchio."""
    import warnings

    mech = exo5(3)
    T = 1.1
    mo = gait(mech, np.linspace(0.0, T, samples))
    ref = pb.inverse_dynamics(mech, mo.q, mo.qd, mo.qdd)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # the NaNs are counted below
        paper = numeric.inverse_dynamics_paper(mech, mo.q, mo.qd, mo.qdd)
    ours = numeric.inverse_dynamics(mech, mo.q, mo.qd, mo.qdd)
    n = mech.nlinks
    out: dict[str, int | float | tuple[float, int]] = {
        "samples": samples,
        "nan_samples": int(np.isnan(paper).any(axis=1).sum()),
    }
    for k, block in enumerate(("phi", "psi", "l")):
        cols = slice(k * n, (k + 1) * n)
        r, p = ref[:, cols], paper[:, cols]
        finite = np.isfinite(p).all(axis=1)
        out[block] = (
            float(np.abs(p[finite] - r[finite]).max() / np.abs(r).max()) if finite.any() else math.nan,
            int((~finite).sum()),
        )
    out["matrix"] = float(np.abs(ours - ref).max() / np.abs(ref).max())
    return out


@dataclass
class Results:
    """Everything the report shows."""

    verdicts: list[Verdict]
    branch: dict[str, Verdict]
    singular: list[Singular]
    gait: dict
    residual: float
    seconds: float


def compute() -> Results:
    """Run every check (the slow part of ``exo-bench errata``)."""
    t0 = time.perf_counter()
    witnesses = [LagrangeWitness(), PinocchioWitness()]
    verdicts = check_all(witnesses)
    branch = check_branch_rule(witnesses)
    singular = check_singular()
    g = gait_effect()
    m = random_tree(4, 3, 3)
    q, qd, qdd = random_states(m, cases.SAMPLES, cases.SEED)
    residual = form_residual(m, q, qd, qdd)
    return Results(verdicts, branch, singular, g, residual, time.perf_counter() - t0)
