"""The stride's section of its scene report: against Winter over the cycle, the done-when verdicts, and the
actuator-sizing table of every stored stride.

Every name and computed sentence reaching Markdown goes through the Markdown encoder
(:func:`exo_bench.models.files.markdown_text`); numbers are formatted here. The verdicts' evidence is
the numbers :func:`exo_bench.bench.studies.stride.comparison.verdicts` computed, never a typed-in reason.
"""

from __future__ import annotations

from exo_bench.bench.studies.stride import comparison as cmp
from exo_bench.bench.studies.stride import data
from exo_bench.bench.studies.stride.actuators import Sizing, sizing
from exo_bench.models.files import markdown_text as md
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.gait.normative import SOURCE

CONVENTION = (
    "Sign convention (Winter's Table A.5): a joint moment is the moment the proximal segment exerts on the "
    "distal one at their joint (on the thigh at the hip, on the leg at the knee, on the foot at the ankle), "
    "counter-clockwise positive with the walker moving in +x; the model's joint motors "
    "(bench/studies/stride/actuators.py) are that moment by construction, so no curve is relabelled. "
    "Powers: moment x (angular velocity of the distal segment - of the proximal), generated positive. "
    "Ground force on the right foot in body weights, forward and up positive. Segment angles: of the vector "
    "from the distal to the proximal end, counter-clockwise from +x."
)


def _f(x: float | None, fmt: str = ".3g") -> str:
    return "" if x is None else format(x, fmt)


def curves_table(c: cmp.Comparison) -> list[str]:
    lines = [
        "| quantity | unit | r | RMS error | Winter's RMS | RMS error / Winter's RMS |",
        "|---|---|---|---|---|---|",
    ]
    for key, cv in c.curves.items():
        lines.append(
            f"| {md(key)} | {md(cv.unit)} | {cv.r:.2f} | {cv.rms_error:.3g} | {cv.winter_rms:.3g} | "
            f"{cv.rms_error / cv.winter_rms:.2f} |"
        )
    return lines


def peaks_table(c: cmp.Comparison) -> list[str]:
    lines = ["| peak | this stride | Winter's | ratio | within 2x |", "|---|---|---|---|---|"]
    for name, o, w in c.peaks:
        ratio = o / w
        ok = 1 / cmp.FACTOR <= ratio <= cmp.FACTOR
        lines.append(f"| {md(name)} | {o:.3g} | {w:.3g} | {ratio:.2f} | {'yes' if ok else '**no**'} |")
    return lines


def verdicts_table(c: cmp.Comparison) -> list[str]:
    lines = ["| done-when check (issue 37) | target | measured | verdict |", "|---|---|---|---|"]
    for v in c.verdicts:
        verdict = "met" if v.passed else "**not met** by this stride"
        lines.append(f"| {md(v.name)} | {md(v.target)} | {md(v.measured)} | {verdict} |")
    return lines


def sizing_table(z: Sizing) -> list[str]:
    solve = (
        "solve time not stored"
        if z.solve_seconds is None
        else f"solved in {z.solve_seconds:.1f} s, {z.iterations} iterations in {z.stages} stage(s)"
        + (f", starting from {md(z.start)}" if z.start else "")
        + " (stored provenance)"
    )
    lines = [
        f"**{md(z.variant)} variant at {z.speed:g} m/s** (stride {z.period:.3f} s; {solve}):",
        "",
        "| actuator | kind | peak load | RMS load | peak + power (W) | peak - power (W) | energy + (J/stride) "
        "| energy - (J/stride) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    rods = sum(r.energy_positive for r in z.rows if r.kind == "telescopic rod")
    total = sum(r.energy_positive for r in z.rows)
    for r in z.rows:
        lines.append(
            f"| {md(r.actuator)} | {md(r.kind)} | {r.peak:.4g} {md(r.unit)} | {r.rms:.4g} {md(r.unit)} | "
            f"{r.power_max:.4g} | {r.power_min:.4g} | {r.energy_positive:.4g} | {r.energy_negative:.4g} |"
        )
    if total > 0:
        lines += [
            "",
            f"The telescopic rods do {rods / total:.1%} of these actuators' positive work ({rods:.1f} of {total:.1f} J).",
        ]
    return lines


def _stored(mech: Mechanism, folder=None) -> list[data.StoredStride]:
    """Every stride stored for ``mech`` (speeds ascending, human variant first)."""
    keys = sorted(data.stored(folder), key=lambda k: (k[0] != "human", k[1]))
    return [data.load(v, s, mech, folder) for v, s in keys]


def stored_sizings(mech: Mechanism, folder=None) -> list[Sizing]:
    """The sizing of every stride stored for ``mech`` (speeds ascending, human variant first)."""
    return [sizing(mech, s) for s in _stored(mech, folder)]


def verdicts_by_stride(mech: Mechanism, folder=None) -> list[str]:
    """One row per stored stride: whether each verdict holds, against Winter's 1.41 m/s stride."""
    rows = []
    for s in _stored(mech, folder):
        vs = cmp.compare(mech, s).verdicts
        rows.append(
            f"| {md(s.variant)} | {s.speed:g} | "
            + " | ".join(("met" if v.passed else "**not met**") for v in vs)
            + " |"
        )
    names = [v.short for v in cmp.compare(mech, _stored(mech, folder)[0]).verdicts] if rows else []
    head = ["| variant | m/s | " + " | ".join(md(n) for n in names) + " |", "|---|---|" + "---|" * len(names)]
    return head + rows if rows else []


def without_floor(mech: Mechanism, stride: data.StoredStride, tau) -> str:
    """What the scene's methods table shows along the stride, measured: inverse dynamics without the floor's
    force, so the root's rows carry what the floor carries in the stride (``tau``: a method's, ``(K, dof)``)."""
    row = mech.nlinks + mech.names.index("root")
    return (
        "The methods' table above runs every method's inverse dynamics along the stored stride without the "
        f"floor's force (the scene runner passes no external force): its root length row peaks at "
        f"{float(abs(tau[:, row]).max()):.4g} N, where in the stride the floor carries the body (the stored "
        f"residual of that row peaks at {float(abs(stride.residuals[:, 2]).max()):.2g} N). The loads below are "
        "the optimiser's, with the floor's contact forces."
    )


def objective_line(stride: data.StoredStride) -> str:
    """The stored stride's objective and rod specification, from its stored settings
    (:class:`exo_bench.bench.studies.stride.problem.StrideSettings`; a setting not stored reads as its
    default)."""
    from exo_bench.bench.studies.stride.problem import StrideSettings

    s = {**StrideSettings().to_dict(), **stride.settings}
    hip, knee, ankle = s["strength"]
    lo, hi = s["period"]
    return (
        f"The problem (bench/studies/stride/problem.py): work per metre over body weight, positive priced "
        f"{s['w_positive']:g} and negative {s['w_negative']:g}, the telescopic rods' work at "
        f"{s['w_rod_work']:g}x the joints'; effort {s['w_moment']:g} x (moment / (body mass x strength))^2 "
        f"with strengths hip {hip:g}, knee {knee:g}, ankle {ankle:g} N·m/kg, plus {s['w_force']:g} x (rod force "
        f"/ body weight)^2; rods within {100 * s['stroke']:g} cm of rest at up to {s['rate']:g} m/s; the stride "
        + (f"period fixed at {lo:.3f} s." if lo == hi else f"period free in [{lo:g}, {hi:g}] s.")
        + _passive_and_floor(s)
    )


def _passive_and_floor(s: dict) -> str:
    """The stored problem's passive joint elements, floor price and contact changes, in words (none: empty)."""
    out = []
    if s.get("w_floor"):
        out.append(
            f"the work the floor absorbs (its contact's damping and friction) priced at {s['w_floor']:g} per "
            "metre over body weight"
        )
    springs = [f"{j} {k:g}" for j, k in zip(("hip", "knee", "ankle"), s.get("spring", ())) if k]
    if springs:
        out.append(f"passive springs about standing (N·m/kg/rad): {', '.join(springs)}; the active moment priced")
    if s.get("passive", "none") != "none":
        out.append(f"passive end-range moments: {s['passive']}")
    if s.get("contact"):
        out.append("floor contact changed: " + ", ".join(f"{k} {v:g}" for k, v in sorted(s["contact"].items())))
    if s.get("w_floor") or springs:
        out.append(
            "the floor price and the springs were chosen from the trials below by the checks below (a calibration "
            "against Winter's, bench/studies/stride/problem.py; the objective tracks no curve of his), so those "
            "checks do not test these numbers independently, and the springs' values have no checked source"
        )
    return (" Also: " + "; ".join(out) + ".") if out else ""


#: Trial solves of the stored strides' problem with one setting changed, each stored in a folder of its own.
TRIALS = data.DATA / "trials"


def settings_difference(stored: dict, trial: dict) -> str:
    """The settings in which ``trial`` differs from ``stored`` (a setting not stored reads as its default)."""
    from exo_bench.bench.studies.stride.problem import StrideSettings

    base = StrideSettings().to_dict()
    a, b = {**base, **stored}, {**base, **trial}
    out = [f"{k} {_value(b[k])} (stored: {_value(a[k])})" for k in sorted(a) if _value(a[k]) != _value(b[k])]
    return "; ".join(out) or "none"


def _value(x) -> str:
    return (
        ", ".join(_value(v) for v in x)
        if isinstance(x, (list, tuple))
        else format(x, "g")
        if isinstance(x, float)
        else str(x)
    )


def trials_table(mech: Mechanism, stride: data.StoredStride, trials=None) -> list[str]:
    """The stored stride and every trial of its variant and speed (a folder of ``trials``, :data:`TRIALS`
    by default, holding it): the settings changed, the verdicts met, each joint moment's r, the toe's
    share of the foot's vertical impulse and the rods' share of positive work, all computed here."""
    from pathlib import Path

    from exo_bench.bench.studies.stride.evidence import floor_work, toe_share

    found = data.trials_of(stride.variant, stride.speed, mech, Path(TRIALS if trials is None else trials))
    rows = []
    for name, t in [("(the stored stride)", stride), *found]:
        c = cmp.compare(mech, t)
        met = sum(v.passed for v in c.verdicts)
        rs = ", ".join(f"{j} {c.curves[f'{j} moment'].r:.2f}" for j in cmp.JOINTS)
        inside = sum(1 / cmp.FACTOR <= o / w <= cmp.FACTOR for _, o, w in c.peaks)
        diff = "" if t is stride else settings_difference(stride.settings, t.settings)
        rows.append(
            f"| {md(name)} | {md(diff)} | {met} of {len(c.verdicts)} | {inside} of {len(c.peaks)} | {rs} | "
            f"{toe_share(t):.1%} | {cmp.rod_share(mech, t)[0]:.1%} | {t.period:.3f} | "
            f"{t.solver.get('objective', float('nan')):.4g} | {-floor_work(mech, t):.1f} |"
        )
    head = [
        "| trial | settings changed | checks met | peaks within 2x | moment r | toe's share | rods' share | period s "
        "| objective | floor absorbs J |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    return head + rows if found else []


def markdown(mech: Mechanism, stride: data.StoredStride, figure: str | None = None, folder=None, tau=None) -> str:
    """The section: the stride against Winter's (``figure``: the file of its curves, written beside the
    report), the verdicts, and the sizing table of every stored stride (in ``folder``); ``tau``: the
    scene's reference method's generalised forces along the stride, to say what its methods table shows."""
    from pathlib import Path

    from exo_bench.bench.studies.stride import constraints

    c = cmp.compare(mech, stride)
    cadence = 120.0 / stride.period
    strides = _stored(mech, folder)  # every stored stride: the join of each, then its sizing
    groups = constraints.joins(mech, strides, TRIALS if folder is None else Path(folder) / "trials")
    lines = [
        "## The stride against Winter's, over the whole gait cycle",
        "",
        f"The stored {md(stride.variant)} stride at {stride.speed:g} m/s: {stride.period:.3f} s, "
        f"{stride.stride_length:.3f} m, {cadence:.1f} steps/min; right stance {c.stance[0]:.1f} % of the cycle "
        f"(Winter: {c.stance[1]:.1f} %). Our right heel strike is at t = {c.heel_strike:.4f} s of the stored "
        f"stride, where the right foot's vertical force rises through {cmp.CONTACT_THRESHOLD:g} body weights.",
        "",
        f"Winter's curves: {md(SOURCE)}, one subject, frames 28-97 (right heel contact to the next). "
        f"Both strides are resampled to {cmp.BINS} bins of the cycle (bin means, which keep every integral).",
        "",
        md(CONVENTION),
        "",
        md(objective_line(stride)),
        "",
    ]
    if tau is not None:
        lines += [without_floor(mech, stride, tau), ""]
    if figure is not None:
        lines += [f"![the stride's curves against Winter's]({figure})", ""]
    lines += ["### Verdicts", "", *verdicts_table(c), ""]
    lines += [
        "A target not met is not met by this stride, with the numbers above as the evidence; whether this model "
        "class could meet it is not shown by one solution.",
        "",
        "### Curves",
        "",
        "Winter's RMS is his curve's RMS over the cycle (a segment angle's about its mean): the transcription "
        "has one subject and no inter-subject spread.",
        "",
        *curves_table(c),
        "",
        "### Peaks",
        "",
        f"Every phase's peak whose Winter value is at least {cmp.COMPARABLE:g} of the curve's largest: "
        "|moment| per phase, the positive and negative power peaks, the ground force's extremes in stance.",
        "",
        *peaks_table(c),
        "",
        *_trials_section(mech, stride, folder),
        "### Every stored stride against Winter's",
        "",
        "The same checks on every stored stride (each against Winter's stride at 1.41 m/s, so the other speeds' "
        "timing differs from his by construction):",
        "",
        *verdicts_by_stride(mech, folder),
        "",
        *constraints.section(groups),
        "### Actuator sizing",
        "",
        "Per joint motor (hips, knees, ankles) and telescopic rod, over one stride: peak and RMS torque (N·m) or "
        "force (N), peak positive and negative power, and positive and negative energy per stride "
        "(bench/studies/stride/actuators.py). Solve times are wall time on the host that solved the stride.",
        "",
    ]
    for st, g in zip(strides, groups):
        lines += [*sizing_table(sizing(mech, st)), "", md(constraints.note(g[0])), ""]
    return "\n".join(lines).rstrip("\n") + "\n"


def _trials_section(mech: Mechanism, stride: data.StoredStride, folder=None) -> list[str]:
    """The trials' section (none when no trial of this stride is stored; ``folder``: the stored strides'
    folder, whose ``trials`` folder holds them)."""
    from pathlib import Path

    rows = trials_table(mech, stride, None if folder is None else Path(folder) / "trials")
    if not rows:
        return []
    return [
        "### Trials of the problem",
        "",
        "The problem solved with settings changed (the column: against the stored stride's), each stored "
        "beside it (bench/studies/stride/data/trials/): what the change does to the checks above. Each trial "
        "started from the human stride at 1.41 m/s stored before the floor's absorbed work was priced (the row "
        "floor-unpriced, that stride itself). A trial's objective is its own problem's (not comparable across "
        "rows). Each is one local optimum, not a proof of what the model class can do.",
        "",
        *rows,
        "",
    ]


def text(mech: Mechanism, stride: data.StoredStride) -> str:
    """The verdicts as Markdown, for the recording's description."""
    c = cmp.compare(mech, stride)
    return "\n".join(verdicts_table(c)) + "\n"


__all__ = ["CONVENTION", "TRIALS", "markdown", "settings_difference", "stored_sizings", "text", "trials_table"]
