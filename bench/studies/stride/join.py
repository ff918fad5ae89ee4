"""The half-stride join in the stride's report: how far each stored stride's loads jump where its halves meet.

The stride is solved over half a stride and mirrored (:mod:`~exo_bench.bench.studies.stride.transcription`, "The join"): coordinates and
rates are mirrored at the join, the loads only when the problem asks for it (``join_loads``, per variant:
:data:`~.problem.JOIN_LOADS`). A jump there is the transcription's, not the walk's, and a sizing table's
peaks would carry it. For every stored stride, computed here from the stored loads (the optimiser's):

* the jump of the priced joints' moments (N·m) and the telescopic rods' forces (N) across the join
  (:func:`~.constraints.load_jump`);
* with ``join_loads``, the bound it meets: the transcription constrains ``(M_0 - P M_N) / m`` and
  ``(F_0 - P F_N) / BW`` to zero, and IPOPT stops at a largest violation of ``constr_viol_tol``, so
  ``constr_viol_tol`` times the body mass (N·m) and times the body weight (N);
* its largest joint power; how many of its sizing table's peaks (each actuator's peak load, peak positive
  and negative power: :mod:`~.sizing`) sit at a join node, ``t = 0, T`` or ``2T`` (where a jump would put
  them; a genuine peak may sit there too); and the checks against Winter's (:mod:`~.comparison`);

and the same for every trial of its variant and speed solved the other way (:mod:`~.trials`), so the report
says what the setting changes. Every sentence is built from these numbers; names pass the Markdown encoder.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from exo_bench.bench.studies.stride import comparison as cmp
from exo_bench.bench.studies.stride import data
from exo_bench.bench.studies.stride.actuators import actuators, powers
from exo_bench.bench.studies.stride.constraints import load_jump
from exo_bench.models.files.encoders import markdown_text as md
from exo_bench.models.mechanism.mechanism import Mechanism

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
            "loads, bench/studies/stride/join.py). Beside each stored stride, its trials solved the other way."
        ),
        "",
        *table(groups),
        "",
    ]
    for g in groups:
        lines += [md(sentence(g)), ""]
    return lines


__all__ = ["STORED", "Join", "join_of", "joins", "note", "section", "sentence", "table"]
