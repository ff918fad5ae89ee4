"""The stride's constraints re-evaluated from a stored stride with numpy and the project's own models.

Nothing of the optimiser is reused: the contact forces are :func:`exo_bench.models.simulation.posture.ground_reaction`'s,
the dynamics newton-euler's numpy inverse dynamics with ``f_ext`` (:mod:`exo_bench.models.runtime.external_forces`),
the split :func:`exo_bench.bench.studies.stride.actuators.actuators`. So a wrong store or a wrong CasADi
model shows up here.

**Violation measure.** For each constraint, the largest absolute amount by which it is missed at any node
(0 when met), in its own unit (m, rad, m/s, rad/s, s, N and N·m): an equality ``g = 0`` by ``|g|``, a
bound ``lo <= g <= hi`` by ``max(lo - g, g - hi, 0)``. The residuals (N·m, N) are compared as they are:
forces of up to about a body weight (556 N), so 1e-8 N is a relative 2e-11.

The collocation defects are those of the solved half (nodes ``0..N``): the stored second half is its
mirror with the hips moved (:func:`~.coordinates.full_stride`), and trapezoidal defects of the root's
polar coordinates are not invariant under that move; every other constraint is checked on the full stride.
"""

from __future__ import annotations

import numpy as np

from exo_bench.bench.studies.stride.actuators import actuators, join_pairs
from exo_bench.bench.studies.stride.coordinates import TELESCOPIC, free_map, mirror_matrix
from exo_bench.bench.studies.stride.data import StoredStride, contact_forces, contact_of
from exo_bench.models.mechanism.kinematics import point_mass_positions, point_mass_velocities
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.simulation.posture import balanced_standing, ground_reaction


def _excess(x, lo, hi) -> float:
    x = np.asarray(x, dtype=float)
    return float(max(np.max(lo - x, initial=0.0), np.max(x - hi, initial=0.0), 0.0))


def optimiser_loads_by(model, stride: StoredStride) -> np.ndarray:
    """``tau = ID(q, qd, qdd) - Q(f_contact)`` along the stride by a prepared model (any method), the
    contact forces recomputed from ``q, qd`` with the stride's contact parameters (:func:`~.data.contact_of`)."""
    f = ground_reaction(model.mechanism, stride.q, stride.qd, contact_of(stride.settings))
    return model.inverse_dynamics(stride.q, stride.qd, stride.qdd, f_ext=f)


def load_jump(mech: Mechanism, moments: np.ndarray, forces: np.ndarray) -> tuple[float, float]:
    """How far a stored stride's loads jump at the half-stride join: the largest ``|difference|`` between the
    priced joints' moments (N·m), then the telescopic rods' forces (N), at ``t = 0`` and the mirror image
    (right and left exchanged) of those at ``t = T`` (node ``N`` of the ``2N + 1``); ``moments (K, joints)``,
    ``forces (K, rods)`` as :func:`~.actuators.actuators` splits them. What ``join_loads`` constrains."""
    N = (len(moments) - 1) // 2
    (ja, jb), (ra, rb) = join_pairs(mech)
    return (
        float(np.abs(moments[0, ja] - moments[N, jb]).max()),
        float(np.abs(forces[0, ra] - forces[N, rb]).max()),
    )


def violations(stride: StoredStride, mech: Mechanism) -> dict[str, float]:
    """Every constraint of the stride problem, re-evaluated: name -> largest violation (module docstring)."""
    from exo_bench import prepare

    s = stride.settings
    n = mech.nlinks
    ix = {name: i for i, name in enumerate(mech.names)}
    K = len(stride.t)
    N = (K - 1) // 2
    fm = free_map(mech, balanced_standing(mech, s["stature"]))
    q, qd, qdd, t = stride.q, stride.qd, stride.qdd, stride.t
    out: dict[str, float] = {}
    T = t[N]
    out["grid (equal intervals)"] = float(np.abs(t - np.linspace(0, 2 * T, K)).max())
    h = T / N
    z, zd, zdd = (x[: N + 1, fm.free] for x in (q, qd, qdd))
    out["trapezoidal defects: positions"] = float(np.abs(z[1:] - z[:-1] - h / 2 * (zd[1:] + zd[:-1])).max())
    out["trapezoidal defects: rates"] = float(np.abs(zd[1:] - zd[:-1] - h / 2 * (zdd[1:] + zdd[:-1])).max())
    fixed = np.abs(q - fm.full(q[:, fm.free]))
    out["fixed coordinates (HAT, feet, heels, arches)"] = float(fixed.max())
    tau = optimiser_loads_by(prepare(mech, "newton-euler", kernel="numpy"), stride)
    out["residuals: HAT angle, root angle (N·m), root length (N)"] = float(np.abs(actuators(mech, tau).residuals).max())
    P = mirror_matrix(fm)
    keep = [i for i, name in enumerate(fm.names) if not name.startswith("root")]
    out["symmetry: coordinates"] = float(np.abs((z[0] - P @ z[N])[keep]).max())
    out["symmetry: rates"] = float(np.abs((zd[0] - P @ zd[N])[keep]).max())
    hip = point_mass_positions(mech, q)[:, ix["root"], 2]
    hv = point_mass_velocities(mech, q, qd)[:, ix["root"], 2]
    out["speed: hips advance v T"] = float(abs(hip[N, 0] - hip[0, 0] - s["speed"] * T))
    out["symmetry: hip height and velocity"] = float(max(abs(hip[N, 1] - hip[0, 1]), np.abs(hv[N] - hv[0]).max()))
    out["stride: hips advance a stride length"] = float(abs(hip[-1, 0] - hip[0, 0] - stride.stride_length))
    out["hips' x at t = 0"] = float(abs(hip[0, 0] - s["hip_x0"]))
    heel = point_mass_positions(mech, q[:1])[0, ix["right_heel"], 2, 1]
    out["right heel on the floor at t = 0"] = float(abs(heel))
    for side in ("right", "left"):
        th = {p: q[:, ix[f"{side}_{p}"]] for p in ("thigh", "leg", "foot")}
        out[f"{side} hip range"] = _excess(th["thigh"] - q[:, ix["hat"]], *s["hip"])
        out[f"{side} knee range"] = _excess(th["thigh"] - th["leg"], *s["knee"])
        lo, hi = s["ankle"]
        out[f"{side} ankle range"] = _excess(th["foot"] - th["leg"] - s["ankle_standing"], lo, hi)
    out["trunk angle"] = _excess(q[:, ix["hat"]], *s["trunk"])
    strokes, rates = [], []
    for r in TELESCOPIC:
        rest = s["rest_lengths"][r.split("_", 1)[1]]
        strokes.append(_excess(q[:, n + ix[r]] - rest, -s["stroke"], s["stroke"]))
        rates.append(_excess(qd[:, n + ix[r]], -s["rate"], s["rate"]))
    out[f"rod strokes (±{s['stroke'] * 100:g} cm)"] = max(strokes)
    out[f"rod rates (<= {s['rate']:g} m/s)"] = max(rates)
    out["period range"] = _excess(np.array([t[-1]]), *s["period"])
    if s.get("join_loads"):
        act = actuators(mech, tau)
        out["join: loads mirrored (N·m, N)"] = max(load_jump(mech, act.moments, act.forces))
    out["contact forces as stored"] = float(np.abs(contact_forces(mech, q, qd, contact_of(s)) - stride.contact).max())
    return out


__all__ = ["load_jump", "optimiser_loads_by", "violations"]
