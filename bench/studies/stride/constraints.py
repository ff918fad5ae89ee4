"""The stride's constraints re-evaluated from a stored stride with numpy and the project's own models, and
the half-stride join: how far each stored stride's loads jump where its halves meet (the report's section).

Nothing of the optimiser is reused: the contact forces are :func:`exo_bench.models.simulation.contact.ground_reaction`'s,
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

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from exo_bench.bench.studies.stride.actuators import actuators, join_pairs
from exo_bench.bench.studies.stride.coordinates import TELESCOPIC, free_map, mirror_matrix
from exo_bench.bench.studies.stride.data import StoredStride, contact_forces, contact_of
from exo_bench.models.mechanism.kinematics import point_mass_positions, point_mass_velocities
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.simulation.contact import balanced_standing, ground_reaction
from exo_bench.bench.studies.stride import comparison as cmp
from exo_bench.bench.studies.stride import data
from exo_bench.bench.studies.stride.actuators import powers
from exo_bench.models.files import markdown_text as md


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


# The half-stride join in the stride's report: how far each stored stride's loads jump where its halves meet.

#: The name of a stored stride's own row.
STORED = "(the stored stride)"


@dataclass(frozen=True)
class Join:
    """One stride's loads at the join, and what they cost it (module docstring)."""

    name: str  # STORED or the trial's folder
    variant: str
    speed: float
    join_loads: bool  # whether its problem asked for continuous loads
    moments: float  # N·m: the largest jump of a priced joint's moment
    forces: float  # N: of a telescopic rod's force
    bound: tuple[float, float]  # (N·m, N): the solver's constraint tolerance, in these units
    power: float  # W: the largest peak positive power of a joint motor
    power_joint: str
    checks: tuple[int, int]  # (met, of)
    peaks: tuple[int, int]  # (within 2x, of)
    at_join: tuple[int, int]  # (the sizing table's peaks at a join node: t = 0, T, 2T; of)


def join_of(mech: Mechanism, stride: data.StoredStride, name: str = STORED) -> Join:
    """The join of one stored stride (or trial, named ``name``)."""
    c = cmp.compare(mech, stride)
    act = actuators(mech, stride.tau)
    Pj, Pr, _ = powers(mech, act, stride.qd)
    motors = [k for k, n in enumerate(act.joint_names) if not n.endswith("_arch")]
    rods = [k for k, n in enumerate(act.rod_names) if n in stride.telescopic]
    loads = np.concatenate([act.moments[:, motors], act.forces[:, rods]], axis=1)
    P = np.concatenate([Pj[:, motors], Pr[:, rods]], axis=1)
    N = (len(stride.t) - 1) // 2
    at = np.concatenate([np.abs(loads).argmax(0), P.argmax(0), P.argmin(0)])  # the sizing table's peaks' nodes
    top = int(np.argmax(P[:, : len(motors)].max(0)))
    tol = float(stride.solver.get("constr_viol_tol", float("nan")))
    return Join(
        name,
        stride.variant,
        stride.speed,
        bool(stride.settings.get("join_loads", False)),
        *load_jump(mech, stride.moments, stride.rod_forces),
        (tol * mech.total_mass, tol * stride.body_weight),
        float(P[:, top].max()),
        act.joint_names[motors[top]],
        (sum(v.passed for v in c.verdicts), len(c.verdicts)),
        (sum(1 / cmp.FACTOR <= o / w <= cmp.FACTOR for _, o, w in c.peaks), len(c.peaks)),
        (int(np.isin(at, (0, N, 2 * N)).sum()), len(at)),
    )


def joins(mech: Mechanism, strides: list[data.StoredStride], trials: Path) -> list[list[Join]]:
    """Per stored stride: its join, then every trial of its variant and speed (folders of ``trials``) whose
    problem asked the other way about ``join_loads``."""
    out = []
    for s in strides:
        own = bool(s.settings.get("join_loads", False))
        other = [
            join_of(mech, t, name)
            for name, t in data.trials_of(s.variant, s.speed, mech, trials)
            if bool(t.settings.get("join_loads", False)) != own
        ]
        out.append([join_of(mech, s), *other])
    return out


def table(groups: list[list[Join]]) -> list[str]:
    lines = [
        "| variant | m/s | stride | loads continuous asked | moments jump (N·m) | rod forces jump (N) | largest joint "
        "power (W) | sizing peaks at the join | checks met | peaks within 2x |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for j in (j for g in groups for j in g):
        lines.append(
            f"| {md(j.variant)} | {j.speed:g} | {md(j.name)} | {'yes' if j.join_loads else 'no'} | {j.moments:.3g} | "
            f"{j.forces:.3g} | {j.power:.4g} ({md(j.power_joint)}) | {j.at_join[0]} of {j.at_join[1]} | "
            f"{j.checks[0]} of {j.checks[1]} | "
            f"{j.peaks[0]} of {j.peaks[1]} |"
        )
    return lines


def sentence(group: list[Join]) -> str:
    """What one stored stride's row and its trials say, in words (computed numbers only)."""
    s, others = group[0], group[1:]
    head = f"The {s.variant} stride at {s.speed:g} m/s"
    if s.join_loads:
        within = s.moments <= s.bound[0] and s.forces <= s.bound[1]
        text = (
            f"{head} is solved with its loads continuous across the join: they differ there by at most "
            f"{s.moments:.1g} N·m and {s.forces:.1g} N, "
            + ("within" if within else "**outside**")
            + f" the solver's constraint tolerance ({s.bound[0]:.2g} N·m, {s.bound[1]:.2g} N)."
        )
        for t in others:
            text += (
                f" Solved without it (trial {t.name}), they jumped by {t.moments:.3g} N·m and {t.forces:.3g} N, "
                f"{t.at_join[0]} of its {t.at_join[1]} sizing peaks sat at the join, and its largest joint power "
                f"was {t.power:.4g} W ({t.power_joint}); now {s.at_join[0]} of {s.at_join[1]} and {s.power:.4g} W "
                f"({s.power_joint})."
            )
        return text
    text = (
        f"{head} is solved without it: its loads jump at the join by {s.moments:.3g} N·m and {s.forces:.3g} N, "
        f"and {s.at_join[0]} of its {s.at_join[1]} sizing peaks sit at the join, where they may carry that "
        f"artefact (largest joint power {s.power:.4g} W, {s.power_joint})."
    )
    for t in others:
        text += (
            f" Solved with it (trial {t.name}): {t.checks[0]} of {t.checks[1]} checks met and {t.peaks[0]} of "
            f"{t.peaks[1]} peaks within 2x, against {s.checks[0]} and {s.peaks[0]} for this stride; largest "
            f"joint power {t.power:.4g} W ({t.power_joint})."
        )
    return text


def note(j: Join) -> str:
    """One line beside a stride's sizing table: whether its loads are continuous across the join."""
    if j.join_loads and j.moments <= j.bound[0] and j.forces <= j.bound[1]:
        return (
            f"Loads at the half-stride join: continuous (within the solver's tolerance, {j.moments:.1g} N·m and "
            f"{j.forces:.1g} N); {j.at_join[0]} of these {j.at_join[1]} peaks sit there."
        )
    return (
        f"Loads at the half-stride join: they jump by {j.moments:.3g} N·m and {j.forces:.3g} N; {j.at_join[0]} of "
        f"these {j.at_join[1]} peaks sit there and may carry that artefact (the half-stride join, above)."
    )


def section(groups: list[list[Join]]) -> list[str]:
    """The report's section on the join (``groups``: :func:`joins`): what it is, a table, a sentence per
    stored stride."""
    if not groups:
        return []
    lines = [
        "### The half-stride join",
        "",
        md(
            "Each stride is solved over half a stride and mirrored: coordinates and rates are mirrored at the "
            "join, the loads only when the problem asks for it (join_loads, bench/studies/stride/problem.py). "
            "The jump: the largest difference between the priced joints' moments and the telescopic rods' "
            "forces at the stride's start and the mirror image of those at its half (computed from the stored "
            "loads, bench/studies/stride/constraints.py). Beside each stored stride, its trials solved the other way."
        ),
        "",
        *table(groups),
        "",
    ]
    for g in groups:
        lines += [md(sentence(g)), ""]
    return lines


__all__ = [
    "Join",
    "STORED",
    "join_of",
    "joins",
    "load_jump",
    "note",
    "optimiser_loads_by",
    "section",
    "sentence",
    "table",
    "violations",
]
