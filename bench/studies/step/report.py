"""The predicted step's section of its scene report, and the plausibility table with computed reasons.

The plausibility table has the columns of :mod:`exo_bench.bench.studies.plausibility` (the same numbers: peak net joint
moments per kg, peak rod forces and net joint forces in body weights, beside Winter's Table A.5). Its
last column says "yes" where the peak is within a factor of 2 of Winter's either way, and otherwise gives
the reason computed from the step: where the peak is, the lever of the net joint force about the joint
(``|M| / |F|``, against Winter's peak moment over peak force), the knee flexion and the rods' strokes used.
"""

from __future__ import annotations

import math

import numpy as np

from exo_bench.bench.studies.plausibility import ROLES, Plausibility, bullets, plausibility, tables
from exo_bench.bench.studies.step import data
from exo_bench.bench.studies.study import Study
from exo_bench.models.mechanism.kinematics import net_joint_loads, point_mass_accelerations
from exo_bench.models.gait.normative import SHORT_SOURCE, SOURCE, WINTER, G as WINTER_G

#: A peak within this factor of Winter's, either way, is "comparable".
FACTOR = 2.0
DEG = math.pi / 180


def _ratio(value: float, norm) -> float | None:
    return None if norm is None or norm.value == 0 else value / norm.value


def _winter_lever(role_key: str | None) -> float | None:
    """Winter's peak moment over his peak joint force at the joint (m): how far from the joint his net
    joint force would pass if both peaks coincided (None: the joint has no counterpart in his tables)."""
    if role_key is None or role_key not in WINTER.moments or role_key not in WINTER.forces:
        return None
    return WINTER.moments[role_key].value / (WINTER.forces[role_key].value * WINTER_G)


def _loads(study: Study) -> Plausibility:
    """The study's loads beside walking; a study in which no method produced tau has none (ValueError)."""
    p = plausibility(study)
    if p is None:
        raise ValueError(f"study {study.name!r}: no method produced tau, so there are no loads to report")
    return p


class _Along:
    """Quantities along the study's motion that the reasons quote."""

    def __init__(self, study: Study, stored: data.StoredStep):
        mech, mo = study.mechanism, study.motion
        self.mech, self.t, self.T = mech, mo.t, stored.duration
        self.M, self.F = net_joint_loads(mech, mo.q, mo.qd, mo.qdd)
        self.Mn = np.linalg.norm(self.M, axis=-1) if mech.dim == 3 else np.abs(self.M)
        self.Fn = np.linalg.norm(self.F, axis=-1)
        self.A = np.linalg.norm(point_mass_accelerations(mech, mo.q, mo.qd, mo.qdd), axis=-1)  # (S, n, 3)
        th = mo.q[:, data.angle_rows(mech)]
        self.knee = (np.degrees(th[:, 1] - th[:, 0]).max(), np.degrees(th[:, 2] - th[:, 3]).max())
        s = stored.settings
        a, b, l5 = s.rest_lengths
        self.stroke = np.abs(mo.q[:, -5:] - np.array([a, b, b, a, l5])).max(axis=0)
        self.limit = s.stroke
        self.mass, self.bw = mech.total_mass, mech.total_mass * mech.g

    def when(self, s: int) -> str:
        x = (self.t[s] % self.T) / self.T if self.t[s] < self.t[-1] else 1.0
        phase = (
            "lift-off"
            if x < 0.1
            else "touch-down"
            if x > 0.9
            else "mid-step"
            if 0.35 < x < 0.65
            else "early step"
            if x < 0.5
            else "late step"
        )
        return f"t = {self.t[s]:.3f} s, {100 * x:.0f} % of the step ({phase})"

    def lever(self, k: int, s: int) -> float:
        return float(self.Mn[s, k] / max(self.Fn[s, k], 1e-300))


def _joint_reason(al: _Along, k: int, name: str, ratio: float) -> str:
    role = ROLES[name]
    s = int(np.argmax(al.Mn[:, k]))
    wl = _winter_lever(role[1])
    lever = f"the net joint force passes {100 * al.lever(k, s):.1f} cm from the joint at the peak" + (
        f" (Winter's peak moment over peak force: {100 * wl:.1f} cm)" if wl else ""
    )
    if ratio > FACTOR:
        return f"**{ratio:.1f}× Winter's**: peak at {al.when(s)}; {lever}"
    if k == 0:
        return (
            f"**no push-off: a point foot.** In walking the ankle moment is the ground reaction's moment "
            f"about the ankle, the centre of pressure rolling forward under the foot; here the centre of "
            f"pressure is the ankle O itself, and the ankle moment is an actuator's that the optimiser uses "
            f"only where it lowers the effort: {lever}; peak at {al.when(s)}"
        )
    if k in (1, 4):
        what = "knee" if k == 1 else "hip"
        return (
            f"**the stance leg is a strut on telescopic rods**: {lever}. The stance knee flexes at most "
            f"{al.knee[0]:.1f}° and the stance rods change length by up to {100 * al.stroke[0]:.1f} and "
            f"{100 * al.stroke[1]:.1f} cm (limit ±{100 * al.limit:g} cm), so the body rides on the rods' axial "
            f"forces and the {what} carries little moment; in walking the loaded knee flexes about 15-20° and "
            f"the ground reaction passes well off the joints; peak at {al.when(s)}"
        )
    return (
        f"**the swing leg swings with a small moment**: peak at {al.when(s)}; {lever}; the swing knee flexes at most "
        f"{al.knee[1]:.1f}° and the swing rods change length by up to {100 * al.stroke[2]:.1f} and "
        f"{100 * al.stroke[3]:.1f} cm, shortening the leg for clearance instead of flexing the knee"
    )


def _rod_reason(al: _Along, k: int, name: str, ratio: float) -> str:
    s = int(np.argmax(al.Fn[:, k]))
    from exo_bench.models.mechanism.kinematics import subtree

    links = list(subtree(al.mech, k))
    acc = float(al.A[s, links].max())
    what = (
        f"peak at {al.when(s)}, where a point mass of the {al.mech.names[k]}'s subtree accelerates at "
        f"{acc:.0f} m/s² ({acc / al.mech.g:.1f} g)"
    )
    if ratio > FACTOR and k in (2, 3):
        return (
            f"**{ratio:.1f}× Winter's: the swing foot starts and stops at rest** (no impact at touch-down, the "
            f"old stance foot at lift-off) and must clear {100 * 0.01:g} cm within the lift-off and touch-down "
            f"windows; {what}; the swing rods change length by up to {100 * al.stroke[2]:.1f} and "
            f"{100 * al.stroke[3]:.1f} cm. Winter's swing leg leaves the floor already moving, after push-off"
        )
    if ratio > FACTOR:
        return f"**{ratio:.1f}× Winter's**: {what}"
    return f"**{ratio:.2f}× Winter's**: {what}"


def plausibility_tables(p: Plausibility, al: _Along) -> list[str]:
    """The two tables of :func:`exo_bench.bench.studies.plausibility.markdown` with computed reasons in the last column."""

    def cells(value: float, normative, missing: str, link: int, reason) -> tuple[str, str]:
        ratio = _ratio(value, normative)
        if ratio is None:
            return "", missing
        if 1 / FACTOR <= ratio <= FACTOR:
            return f"{ratio:.2f}×", f"yes: within {FACTOR:g}× of Winter's"
        return f"{ratio:.2f}×", reason(al, link, al.mech.names[link], ratio)

    return tables(
        p,
        lambda r: cells(r.sagittal, r.normative, "—", r.link, _joint_reason),
        lambda rod: cells(rod.joint_force, rod.normative, "no counterpart in Winter's tables", rod.link, _rod_reason),
    )


def _settings_lines(st: data.StoredStep) -> list[str]:
    s = st.settings
    d = lambda x: f"{x / DEG:.0f}°"
    winter_step = WINTER.stride_time.value / 2
    return [
        f"- **grid**: {s.intervals} Hermite-Simpson intervals (separated form), {len(st.t)} collocation points; "
        f"free duration in [{s.duration[0]:g}, {s.duration[1]:g}] s: **{st.duration:.3f} s** (Winter's step, half his "
        f"{WINTER.stride_time.value} s stride: {winter_step:.3f} s)",
        f"- **average speed** prescribed: **{s.speed:g} m/s** (Winter {WINTER.speed.value} m/s); step length "
        f"{st.step_length:.3f} m (Winter {WINTER.speed.value * winter_step:.3f} m)",
        "- **leg swap**: the swing foot lands one step length ahead with zero velocity; the end state relabelled "
        "(links 1-5 take 4, 3, 2, 1, 5; 3D azimuths negated: the mirror image) is the start state",
        f"- **swing foot**: every swing-leg point mass ≥ {100 * s.clearance:g} cm above the floor from "
        f"{100 * s.window:g} % to {100 * (1 - s.window):g} % of the step (lift-off and touch-down windows of "
        f"{1000 * s.window * st.duration:.0f} ms each, above the floor there)",
        f"- **joint ranges**: knee flexion (thigh angle − shin angle, both legs) in [{d(s.knee[0])}, {d(s.knee[1])}] "
        f"(no hyperextension); hip (thigh − trunk) in [{d(s.hip[0])}, {d(s.hip[1])}]; leg segments in "
        f"[{d(s.segment[0])}, {d(s.segment[1])}] and trunk in [{d(s.trunk[0])}, {d(s.trunk[1])}] from the walking "
        f"direction"
        + (
            "; azimuths fixed at 0 (a sagittal step: every leg rod passes the vertical, where eq. (7)'s "
            "chart is singular)"
            if s.dim == 3 and s.azimuth == 0
            else ""
        ),
        f"- **rod strokes**: ±{100 * s.stroke:g} cm about the rest lengths {list(s.rest_lengths)} m (shin, thigh, "
        "trunk; both legs alike)",
        f"- **ground reaction** at O pushes (vertical ≥ {s.min_support:g} BW) within a friction cone μ = {s.friction:g}; "
        "the hip moves forward at every point",
        f"- **objective** (per second, Simpson): {s.w_moment:g} × Σ_joints |net joint moment|² in (N·m/kg)² + "
        f"{s.w_force:g} × Σ_rods (rod force / BW)² + {s.w_accel:g} × Σ qdd² (regulariser); the loads are the "
        "inverse dynamics of the equations' CasADi export (matrix_method/export/casadi_functions.py) and the net joint "
        "loads of models/mechanism/kinematics.py in CasADi (bench/studies/step/transcription.py)",
    ]


def markdown(scene, study: Study) -> str:
    """The step's section of ``reports/<scene>.md``: the problem, the solve, the constraints re-evaluated,
    every method against the optimiser's loads, and the plausibility table with reasons."""
    stored: data.StoredStep = scene.motion["stored"]
    mech = study.mechanism
    meta, sv = stored.meta, stored.meta.get("solver", {})
    viol = data.violations(stored, mech)
    hip = data.hip_path(stored, mech)
    K = len(stored.t)
    lo, hi = int(round(stored.settings.window * (K - 1))), int(round((1 - stored.settings.window) * (K - 1)))
    low = data.lowest_swing_mass(stored, mech)
    from exo_bench.models.mechanism.kinematics import point_mass_velocities

    hipv = point_mass_velocities(mech, stored.q, stored.qd)[:, 1, 2, 0]
    lines = [
        "## The predicted step",
        "",
        f"One step of `{mech.name}` solved by direct collocation with IPOPT (`bench/studies/step/problem.py`), stored "
        f"as `bench/studies/step/data/{stored.file_name}`; the scene walks {scene.motion['steps']} step(s), each "
        "after the first the stored one mirrored with the support point moved to the new foot. Solve it again "
        f"with `exo-bench gait --solve --dim {mech.dim}`.",
        "",
    ]
    lines += _settings_lines(stored)
    lines += [
        "",
        f"**Solved** at commit {meta.get('commit', '?')} on {meta.get('date', '?')}: IPOPT "
        f"`{sv.get('status')}` after {sv.get('iterations')} iterations in {sv.get('solve_seconds', float('nan')):.1f} s "
        f"(on a shared 2-core host; CasADi {sv.get('casadi')}), objective {sv.get('objective', float('nan')):.6g}, "
        f"largest constraint violation as CasADi evaluates it {sv.get('constraint_violation', float('nan')):.1e}.",
        "",
        "**Every constraint re-evaluated** in numpy from the stored arrays with models/mechanism/kinematics.py and "
        "models/mechanism/kinematics.py (largest violation; 0 = met with margin):",
        "",
        "| constraint | largest violation |",
        "|---|---|",
    ]
    lines += [f"| {k} | {v:.1e} |" for k, v in viol.items()]
    lines += [
        "",
        f"**Along the step**: the hip advances {hip[-1, 0] - hip[0, 0]:.4f} m (one step length, "
        f"{stored.step_length:.4f} m) from {hip[0, 0]:+.3f} m to {hip[-1, 0]:+.3f} m over O, its forward "
        f"velocity never below {hipv.min():.3f} m/s; its height stays within [{hip[:, -1].min():.3f}, "
        f"{hip[:, -1].max():.3f}] m. The lowest swing-leg point mass is {100 * low[lo : hi + 1].min():.2f} cm above the "
        f"floor at its lowest between lift-off and touch-down.",
        "",
    ]
    # every method against the optimiser's loads, on the first step's points
    tau_opt = stored.tau
    scale = float(np.abs(tau_opt).max())
    rows = []
    for m in study.ok_methods():
        diff = np.abs(study.tau(m)[:K] - tau_opt)
        bad = int(np.count_nonzero(~np.isfinite(diff)))
        d = float(diff[np.isfinite(diff)].max()) if bad < diff.size else float("nan")
        note = f" over the finite entries; **{bad} NaN/Inf entries** (see the notes above)" if bad else ""
        rows.append(f"| {m} | {d:.2e}{note} | {d / scale:.1e} |")
    lines += [
        "**Every method against the optimiser's loads** (the CasADi inverse dynamics stored with the step), "
        f"on the first step's {K} points:",
        "",
        "| method | max abs. difference (N·m or N) | relative to the largest optimiser load |",
        "|---|---|---|",
    ] + rows
    p = _loads(study)
    al = _Along(study, stored)
    lines += [
        "",
        "## Plausibility: the loads beside level walking",
        "",
        f"Peak net joint moments (the moment the parent side exerts on everything beyond the joint, about the joint; "
        f"`models/mechanism/kinematics.py`) per kg of the model's {p.body_mass:.4g} kg, and peak rod forces ({p.reference}) "
        f"in body weights (BW = {p.weight:.0f} N), beside the normative peak of the joint each plays in level "
        f"walking ({SHORT_SOURCE}). `comparable?` says yes within a factor of {FACTOR:g} either way, and otherwise "
        "gives the reason computed from the step.",
        "",
    ]
    lines += plausibility_tables(p, al)
    lines += [
        "",
        "The rod force is the actuator's force along the rod; the net joint force is the whole force the parent "
        "side exerts at the joint (its magnitude), like Winter's intersegmental force.",
        "",
        "Where this step still differs from walking:",
        "",
        "- **No feet, no double support.** The stance leg stands on a point; the swap is instantaneous, so one leg "
        "carries the body through the whole step. Winter's stance peaks fall in double support and push-off, "
        "which this model does not have.",
        "- **Telescopic rods.** The effort counts rod forces, not rod motion: a rod's stroke costs only the force "
        "that accelerates it, so the optimiser shortens and lengthens the legs (within the stated stroke) where "
        "a human flexes the knee and rolls over the foot.",
        f"- Normative values: {SOURCE}; one subject, one stride: a factor of about 1.5 is within normal variation "
        "between people.",
    ]
    return "\n".join(lines) + "\n"


def text(study: Study) -> str:
    """A compact version for the rerun recording's description."""
    p = _loads(study)
    lines = [
        f"Peak net joint moments (N·m/kg of {p.body_mass:.4g} kg) and net joint forces (body weights) along the "
        f"predicted step, beside level walking ({SHORT_SOURCE}); the scene report gives the reason for every "
        f"peak outside {FACTOR:g}× of Winter's:",
        "",
    ]
    lines += bullets(p, lambda value, norm: f"{value / norm.value:.2f}×")
    return "\n".join(lines)


__all__ = ["FACTOR", "markdown", "plausibility_tables", "text"]
