"""Forward-dynamics study, the terms per method: mass matrices and bias forces against Pinocchio's, and the
singular configurations each method names.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from exo_bench.api import METHODS, PreparedSet
from exo_bench.bench.studies.stability.forward_cases import _models
from exo_bench.bench.studies.study import one_line
from exo_bench.models.simulation import forward_dynamics as fd
from exo_bench.models.mechanism.presets import exo5
from exo_bench.models.mechanism.presets import random_tree


@dataclass
class TermsRow:
    mechanism: str
    method: str
    source: str  # "exposed" or "from inverse dynamics"
    status: str = "ok"
    m_rel: float = math.nan  # max |M - M_crba| / max |M_crba|
    h_rel: float = math.nan
    seconds: float = math.nan


def terms_agreement(methods: list[str], samples: int = 4, models: PreparedSet | None = None) -> list[TermsRow]:
    """Each method's M and h (exposed or from its inverse dynamics) against Pinocchio's CRBA and
    ``nonLinearEffects``; Pinocchio itself also through its inverse dynamics (the linearity identity)."""
    import time

    from exo_bench.models.gait.motion import random_states

    models = _models(models)
    rows = []
    for mech in (exo5(3), random_tree(5, 3, 9), exo5(2)):
        q, qd, _ = random_states(mech, samples, 21)
        pin_model = models(mech, "pinocchio")
        M0, h0 = pin_model.mass_matrix(q), pin_model.bias_forces(q, qd)
        plan = [(m, False) for m in methods] + [("pinocchio", True)]
        for m, via in plan:
            try:
                model = models(mech, m)
            except ImportError as e:  # a missing module is a row, not a crash
                rows.append(TermsRow(mech.name, m, "", "missing: " + one_line(e)))
                continue
            except Exception as e:  # noqa: BLE001 - over budget or failing to prepare: a row
                skip = getattr(e, "skip_reason", None)
                rows.append(TermsRow(mech.name, m, "", f"skipped: {skip}" if skip else "failed: " + one_line(e)))
                continue
            exposed = (not via) and model.native_terms
            source = METHODS[m].exposed_terms if m in METHODS else None
            row = TermsRow(
                mech.name,
                m,
                (f"exposed ({source})" if source else "exposed") if exposed else "from inverse dynamics",
            )
            try:
                t0 = time.perf_counter()
                M, h = fd.mass_matrix_and_bias(model, q, qd, via_inverse_dynamics=via)
                row.seconds = time.perf_counter() - t0
                row.m_rel = float(np.abs(M - M0).max() / np.abs(M0).max())
                row.h_rel = float(np.abs(h - h0).max() / np.abs(h0).max())
            except Exception as e:  # noqa: BLE001
                skip = getattr(e, "skip_reason", None)
                row.status = f"skipped: {skip}" if skip else "failed: " + one_line(e)
            rows.append(row)
    return rows


@dataclass
class SingularDemo:
    case: str
    inverse: str  # what inverse dynamics gives there
    forward: str  # what forward dynamics says


def singular_demos(models: PreparedSet | None = None) -> list[SingularDemo]:
    """Forward dynamics at genuinely singular configurations: refused, with the link named."""
    from exo_bench.models.gait.motion import gait, random_states

    models = _models(models)

    e3 = exo5(3)
    g = gait(e3, np.array([0.0]))
    q, qd, qdd = random_states(e3, 1, 5)
    q0 = q.copy()
    q0[0, -4] = 0.0  # l_2 = 0
    m = list(e3.masses)
    m[3] = (m[3][0], 0.0, 0.0)
    massless = e3.replace(masses=tuple(m), name="exo5-3d, massless swing shin")
    out = []
    for label, mech, (a, b, c) in (
        ("exo5-3d gait of eq. (26) at t = 0 (trunk at psi5 = pi/2)", e3, (g.q, g.qd, g.qdd)),
        ("exo5-3d, random state with l2 = 0", e3, (q0, qd, qdd)),
        ("exo5-3d with a massless swing shin", massless, (q, qd, qdd)),
    ):
        model = models(mech, "pinocchio")
        tau = model.inverse_dynamics(a, b, c)
        inv = "finite" if np.isfinite(tau).all() else "NaN/Inf"
        try:
            fd.accelerations(model, a, b, tau)
            fwd = "accepted (NOT detected)"
        except fd.SingularConfigurationError as e:
            fwd = f"refused: {e.reasons[0]}"
        out.append(SingularDemo(label, inv, fwd))
    return out
