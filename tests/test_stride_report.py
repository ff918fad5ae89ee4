"""The stride's comparison with Winter, its actuator-sizing table, report and figures (issue 37).

Oracles: hand-computed r and RMS; the trapezoidal integral of the samples (the resampling keeps it to
rounding: a few ulps of the summed |values|); Winter's stride fed through the model's actuator split
(generalised forces built from his joint moments, rates from his segment velocities) must come back as
his own curves (r = 1, RMS error at rounding), which checks the sign convention end to end; rod and joint
work of hand-built motions (constant force over a stroke).
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_bench.bench.studies.stride import comparison as cmp
from exo_bench.bench.studies.stride import winter
from exo_bench.bench.studies.stride.data import StoredStride
from exo_bench.bench.studies.stride.actuators import sizing
from exo_bench.models.gait.normative import G, WINTER
from exo_bench.models.mechanism.presets import human, human_standing

EPS = float(np.finfo(float).eps)
MOTORS = {"hip": ("right_thigh", "hat"), "knee": ("right_leg", "right_thigh"), "ankle": ("right_foot", "right_leg")}


@pytest.fixture(scope="module")
def mech():
    return human(2)


def winter_stride(mech, moment_scale: float = 1.0, telescopic=("right_leg",)) -> StoredStride:
    """Winter's stride as a stored stride of the 2D human: his right segment angles and velocities, his joint
    moments as generalised forces (``+M`` on the link, ``-M`` on its reference), his ground force."""
    tab = winter.table()
    K, ix = len(tab["t"]), mech.names.index
    q = np.repeat(human_standing(mech), K, axis=0)
    qd = np.zeros_like(q)
    for seg, link in cmp.SEGMENTS:
        q[:, ix(link)] = np.radians(tab[seg])
        qd[:, ix(link)] = tab[f"w_{seg}"]
    tau = np.zeros_like(q)
    for j, (link, ref) in MOTORS.items():
        tau[:, ix(link)] += moment_scale * tab[f"{j}_m"]
        tau[:, ix(ref)] -= moment_scale * tab[f"{j}_m"]
    grf = np.zeros((K, 2, 2))
    grf[:, 0] = np.stack([tab["grf_x"], tab["grf_y"]], axis=1)
    left = np.roll(grf[:-1, 0], (K - 1) // 2, axis=0)  # the left foot half a stride later
    grf[:, 1] = np.concatenate([left, left[:1]])
    meta = {
        "variant": "human",
        "speed": 1.41,
        "stride_length": 1.392,
        "body_weight": winter.MASS * G,
        "settings": {},
        "telescopic": list(telescopic),
        "solver": {"solve_seconds": 12.5, "iterations": 40},
    }
    zeros = np.zeros((K, mech.nlinks - 1))
    return StoredStride(
        t=tab["t"],
        q=q,
        qd=qd,
        qdd=np.zeros_like(q),
        tau=tau,
        moments=np.zeros((K, 8)),
        rod_forces=zeros,
        residuals=np.zeros((K, 3)),
        contact=np.zeros((K, 4, 2)),
        grf=grf,
        meta=meta,
    )


def test_r_and_rms_against_hand_computed_cases():
    a = np.array([1.0, 2.0, 3.0])
    assert cmp.pearson(a, 2 * a + 5) == pytest.approx(1.0, abs=4 * EPS)
    assert cmp.pearson(a, -a) == pytest.approx(-1.0, abs=4 * EPS)
    assert cmp.pearson(np.array([1.0, 0, -1, 0]), np.array([0.0, 1, 0, -1])) == 0.0  # quarter period apart
    assert np.isnan(cmp.pearson(a, np.ones(3)))
    c = cmp.Curve("x", "u", np.array([1.0, 2.0, 3.0]), np.array([1.0, 2.0, 5.0]))
    assert c.rms_error == pytest.approx(np.sqrt(4 / 3), rel=4 * EPS)
    assert c.winter_rms == pytest.approx(np.sqrt(30 / 3), rel=4 * EPS)
    # r of (1, 2, 3) with (1, 2, 5): cov 4 / sqrt(2 * 8.667)
    assert c.r == pytest.approx(4 / np.sqrt(2 * 26 / 3), rel=8 * EPS)


@pytest.mark.parametrize("start", [0.0, 0.137, 0.5, 0.999])
def test_resampling_keeps_the_integral_over_the_cycle(start):
    rng = np.random.default_rng(7)
    t = np.concatenate([[0.0], np.sort(rng.uniform(0, 1.0, 40)), [1.0]])
    y = rng.normal(size=(len(t), 3))
    y[-1] = y[0]  # one period: the last sample is the first again
    means = cmp.cycle_means(t, y, start, 1.0, bins=100)
    exact = np.trapezoid(y, t, axis=0)
    scale = np.abs(y).sum(axis=0) * 1.0
    assert np.all(np.abs(means.sum(axis=0) / 100 - exact) <= 64 * EPS * scale)


def test_resampling_of_a_ramp_is_each_bins_midpoint():
    t = np.linspace(0.0, 2.0, 3)
    means = cmp.cycle_means(t, 3.0 * t, 0.0, 2.0, bins=4)  # y = 3t on [0, 2]
    assert means == pytest.approx([0.75, 2.25, 3.75, 5.25], rel=4 * EPS)


def test_gait_events_are_the_threshold_crossings():
    t = np.linspace(0.0, 1.0, 1001)
    fy = np.where((t > 0.3) & (t < 0.9), np.sin(np.pi * (t - 0.3) / 0.6), 0.0)  # stance 0.3 .. 0.9
    hs, to = cmp.gait_events(t, fy, weight=1.0, threshold=0.5)
    assert hs == pytest.approx(0.3 + 0.6 / 6, abs=1e-6) and to == pytest.approx(0.9 - 0.6 / 6, abs=1e-6)
    bounce = np.where((t > 0.5) & (t < 0.52), 0.0, fy)  # lifted for 2 % of the cycle: still one stance
    assert cmp.gait_events(t, bounce, weight=1.0, threshold=0.5) == pytest.approx((hs, to), abs=1e-6)
    apart = np.where((t > 0.5) & (t < 0.58), 0.0, fy)  # lifted for 8 %: the longer contact is the stance
    assert cmp.gait_events(t, apart, weight=1.0, threshold=0.5) == pytest.approx((0.58, to), abs=1e-3)
    with pytest.raises(ValueError, match="never touches"):
        cmp.gait_events(t, 0 * fy, weight=1.0)


def test_double_hump_finds_each_halfs_peak_and_the_valley_between():
    x = np.array([0.0, 1.1, 1.0, 0.9, 0.6, 0.8, 1.05, 0.2])  # a wiggle after the first peak is not a hump
    (a, b), valley = cmp.double_hump(x)
    assert a == (1, 1.1) and b == (6, 1.05) and valley == (4, 0.6)
    assert cmp.double_hump(np.array([0.0, 0.5, 1.0, 0.5]))[1] is None  # one hump: no valley between


def test_winters_stride_through_the_actuators_is_winters_curves(mech):
    """His moments in as generalised forces, out through actuators.actuators: the same curves (no relabelling)."""
    c = cmp.compare(mech, winter_stride(mech), start=0.0)
    for key, curve in c.curves.items():
        assert curve.r == pytest.approx(1.0, abs=1e-12), key
        assert curve.rms_error <= 1e-12 * max(1.0, curve.winter_rms), key
    assert all(v.passed for v in c.verdicts), c.verdicts
    assert c.stance[1] == pytest.approx(100 * 42 / 69, rel=1e-3)  # frames 28-70 of 28-97
    peaks = {n: (o, w) for n, o, w in c.peaks}
    o, w = peaks["ankle moment, stance, |max|"]
    assert o == pytest.approx(w) and w == pytest.approx(WINTER.moments["ankle, stance"].value, abs=0.02)
    assert "ankle moment, swing, |max|" not in peaks  # below COMPARABLE of the curve's largest


def test_failed_targets_state_their_computed_evidence(mech):
    c = cmp.compare(mech, winter_stride(mech, moment_scale=-3.0), start=0.0)
    v = {x.name.split(":")[0].split(" ")[0]: x for x in c.verdicts}
    assert not v["every"].passed and "ankle moment, stance, |max|: 3.00x" in v["every"].measured
    assert not v["hip,"].passed and "ankle r = -1.00" in v["hip,"].measured
    assert "the right toe carries nan% of the right foot's vertical impulse" in v["hip,"].measured  # no contacts
    assert v["vertical"].passed  # the ground force is Winter's


def test_sizing_energy_equals_the_actuators_work(mech):
    """A rod pushing with 500 N over a 2 cm stroke does 10 J; a knee holding 30 N·m while flexing 0.5 rad, -15 J."""
    K, ix, n = 51, mech.names.index, mech.nlinks
    t = np.linspace(0.0, 1.0, K)
    s = winter_stride(mech)
    q = np.repeat(human_standing(mech), K, axis=0)
    qd = np.zeros_like(q)
    leg, thigh = ix("right_leg"), ix("right_thigh")
    q[:, n + leg] += 0.02 * t**2
    qd[:, n + leg] = 0.04 * t
    q[:, leg] -= 0.5 * t
    qd[:, leg] = -0.5
    tau = np.zeros_like(q)
    tau[:, n + leg] = 500.0
    tau[:, leg], tau[:, thigh] = 30.0, -30.0
    fields = {k: getattr(s, k) for k in ("moments", "rod_forces", "residuals", "contact", "grf")}
    fields = {k: np.resize(v, (K, *v.shape[1:])) for k, v in fields.items()}
    stride = StoredStride(t=t, q=q, qd=qd, qdd=0 * q, tau=tau, meta=s.meta, **fields)
    rows = {r.actuator: r for r in sizing(mech, stride).rows}
    assert set(rows) == {"right_hip", "right_knee", "right_ankle", "left_hip", "left_knee", "left_ankle", "right_leg"}
    rod, knee = rows["right_leg"], rows["right_knee"]
    assert (rod.energy_positive, rod.energy_negative) == pytest.approx((500 * 0.02, 0.0), abs=1e-9)
    assert (rod.peak, rod.rms, rod.power_max) == pytest.approx((500.0, 500.0, 20.0))
    assert (knee.energy_positive, knee.energy_negative) == pytest.approx((0.0, 15.0), abs=1e-9)
    assert knee.power_min == pytest.approx(-15.0) and rows["right_hip"].peak == 0.0
    assert cmp.rod_travel(mech, stride) == "their length ranges over at most 2.00 cm, at rates up to 0.04 m/s"


def test_sizing_of_winters_stride_balances_with_the_integral_of_power(mech):
    s = winter_stride(mech)
    z = sizing(mech, s)
    assert (z.solve_seconds, z.iterations, z.speed) == (12.5, 40, 1.41)
    P = winter.joint_powers()
    for j in ("hip", "knee", "ankle"):
        r = next(r for r in z.rows if r.actuator == f"right_{j}")
        net = np.trapezoid(P[j], s.t)
        assert r.energy_positive - r.energy_negative == pytest.approx(net, abs=1e-9 * np.abs(P[j]).sum())
        assert r.peak == pytest.approx(np.abs(winter.table()[f"{j}_m"]).max())


@pytest.fixture(scope="module")
def stored(mech, tmp_path_factory):
    """Winter's stride stored as the human variant at 1.41 m/s, and a 3x-moment one at 1.8 m/s, in a folder."""
    from exo_bench.bench.studies.stride import data

    folder = tmp_path_factory.mktemp("strides")
    data.save(winter_stride(mech), mech, folder)
    fast = winter_stride(mech, moment_scale=3.0)
    staged = {"solve_seconds": 30.0, "iterations": 5, "stages": [{"iterations": 20}, {"iterations": 5}]}
    staged["start"] = {"variant": "human", "speed": 1.41}
    data.save(StoredStride(**{**fast.__dict__, "meta": {**fast.meta, "speed": 1.8, "solver": staged}}), mech, folder)
    return folder


def test_the_report_states_every_verdict_and_the_sizing_of_every_stored_stride(mech, stored):
    from exo_bench.bench.studies.stride import data, report
    from exo_bench.models.files import markdown_text

    s = data.load("human", 1.41, mech, stored)
    text = report.markdown(mech, s, figure="x-winter.png", folder=stored)
    for v in cmp.compare(mech, s).verdicts:
        assert f"| {markdown_text(v.name)} | {markdown_text(v.target)} | {markdown_text(v.measured)} | met |" in text
    assert "| human | 1.41 | met | met | met | met | met |" in text  # every stored stride's verdicts
    assert "| human | 1.8 | **not met** | met | met | met | met |" in text  # 3x the moments: r stays 1
    assert "**human variant at 1.41 m/s**" in text and "**human variant at 1.8 m/s**" in text
    assert "solved in 12.5 s, 40 iterations in 1 stage(s) (stored provenance)" in text
    assert (
        "solved in 30.0 s, 25 iterations in 2 stage(s), starting from the stored human stride at 1\\.41 m\\/s" in text
    )
    assert "| right\\_ankle | joint motor | 89.8 N·m |" in text  # Winter's peak ankle moment, name encoded
    assert "| right\\_ankle | joint motor | 269.4 N·m |" in text  # the 3x stride
    assert "![the stride's curves against Winter's](x-winter.png)" in text
    assert text.count("The telescopic rods do 0.0% of these actuators' positive work (0.0 of ") == 2


def _legend_over_data(fig) -> list[str]:
    """The y labels of the plots a figure legend overlaps (after the figure was drawn, e.g. saved)."""
    r = fig.canvas.get_renderer()
    plots = [ax for ax in fig.axes if ax.axison]
    assert fig.legends and plots
    return [
        ax.get_ylabel()
        for leg in fig.legends
        for ax in plots
        if leg.get_window_extent(r).overlaps(ax.get_window_extent(r))
    ]


def test_figures_are_written_with_legends_off_the_data(mech, tmp_path):
    """One draw per figure (saving it): a 12-panel constrained layout takes seconds on a loaded machine."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from exo_bench.bench.output.provenance import save_figure
    from exo_bench.bench.studies.stride.scene import PANELS, stride_kinogram, winter_figure

    s = winter_stride(mech)
    fig = winter_figure(cmp.compare(mech, s), "Winter through the model")
    kino = stride_kinogram(mech, s.t, s.q, "Winter's angles", frames=3)
    for f, name in ((fig, "w.png"), (kino, "k.png")):
        FigureCanvasAgg(f)  # the canvas savefig draws on, and whose renderer measures the boxes after
        assert save_figure(f, tmp_path / name).stat().st_size > 10_000
        assert not _legend_over_data(f)
    labels = [ax.get_ylabel() for ax in fig.axes if ax.axison]
    assert labels == [label for _, label in PANELS] and all("(" in lab for lab in labels)  # units in every label


def test_a_stride_scene_loads_its_stored_stride_and_refuses_bad_fields(mech, stored, tmp_path, monkeypatch):
    from exo_bench.bench.studies.scene_run import scene_files
    from exo_bench.bench.studies.scenes import load_scene
    from exo_bench.bench.studies.stride import data

    monkeypatch.setattr(data, "DATA", stored)
    head = (
        'mechanism = "human-2d"\nmethods = ["pinocchio"]\noutputs = ["table", "kinogram"]\n[motion]\nkind = "stride"\n'
    )
    (tmp_path / "s.toml").write_text(head + 'variant = "human"\nspeed = 1.41\n')
    sc = load_scene(tmp_path / "s.toml")
    assert sc.build_motion().q.shape == (70, mech.dof) and sc.samples() == 70
    assert scene_files(sc) == ["s.md", "s-kinogram.png", "s-winter.png"]
    for bad, field in (
        ('variant = "robot"', "motion.variant"),
        ("speed = -1", "motion.speed"),
        ("speed = 1.0", "motion"),
    ):
        (tmp_path / "b.toml").write_text(head + bad + "\n")
        with pytest.raises(ValueError, match=f"b.toml: field '{field}'"):
            load_scene(tmp_path / "b.toml")


def test_a_single_hump_fails_with_the_knee_yield_as_evidence(mech):
    s = winter_stride(mech)
    grf = s.grf.copy()
    stance = s.t <= winter.table()["t"][42]  # frames 28-70
    grf[:, 0, 1] = np.where(stance, 1.2 * winter.MASS * G * np.sin(np.pi * s.t / s.t[42]), 0.0)
    c = cmp.compare(mech, StoredStride(**{**s.__dict__, "grf": grf}), start=0.0)
    v = next(x for x in c.verdicts if x.name.startswith("vertical GRF"))
    his = cmp.stance_knee_flexion(c.curves, winters=True)
    assert not v.passed and "(no lower value between them: one hump)" in v.measured
    assert f"knee yield in the first 30 % of the cycle: {his:.1f} deg (Winter's {his:.1f} deg)" in v.measured
    assert 10.0 < his < 20.0  # Winter's early-stance knee flexion (about 16 deg at its peak)


def test_the_report_says_what_the_methods_table_shows_without_the_floor(mech):
    from exo_bench.bench.studies.stride.report import without_floor

    s = winter_stride(mech)
    tau = np.zeros_like(s.tau)
    tau[:, mech.nlinks + mech.names.index("root")] = np.linspace(0.0, 612.5, len(s.t))
    assert "its root length row peaks at 612.5 N" in without_floor(mech, s, tau)


def test_the_recording_logs_the_actuators_and_the_ground_force(mech, stored, tmp_path, monkeypatch):
    """The scene's extra series, written with rr.send_columns and read back with ``rerun rrd print``."""
    import subprocess

    import rerun as rr

    from exo_bench.bench.output.recording import rerun_executable
    from exo_bench.bench.studies.scenes import load_scene
    from exo_bench.bench.studies.stride import data
    from exo_bench.bench.studies.stride.scene import log_stride

    monkeypatch.setattr(data, "DATA", stored)
    (tmp_path / "s.toml").write_text(
        'mechanism = "human-2d"\nmethods = ["pinocchio"]\n[motion]\nkind = "stride"\nvariant = "human"\nspeed = 1.41\n'
    )
    sc = load_scene(tmp_path / "s.toml")
    stream = rr.RecordingStream("stride-test")
    stream.save(str(tmp_path / "s.rrd"))
    log_stride(sc)(stream, rr.TimeColumn("t", duration=sc.motion["stored"].t))
    stream.flush()
    stream.disconnect()
    exe = rerun_executable()
    if exe is None:
        pytest.skip("no rerun executable to read the recording back")
    out = subprocess.run(
        [str(exe), "rrd", "print", str(tmp_path / "s.rrd")], capture_output=True, text=True, timeout=120
    )
    for entity in ("joint_moments/right_ankle", "rod_forces/right_leg", "ground_force/right_vertical"):
        assert f"stride/{entity}" in out.stdout + out.stderr


def test_contacts_and_double_support_count_the_intervals_on_the_ground():
    """11 nodes over 1 s, node 10 the same instant as node 0: the right foot down at nodes 0-5 (and 10), the
    left at 4-10 (and 0). Both down at nodes 4, 5 and 0 = 10: the interval [0.4, 0.5] whole and half of each
    of the four next to those nodes, 30 %; the right foot 60 %, the left 70 %, each one contact."""
    from types import SimpleNamespace

    t = np.linspace(0.0, 1.0, 11)
    grf = np.zeros((11, 2, 2))
    grf[[0, 1, 2, 3, 4, 5, 10], 0, 1] = 500.0
    grf[[0, 4, 5, 6, 7, 8, 9, 10], 1, 1] = 500.0
    s = SimpleNamespace(t=t, grf=grf, body_weight=1.0)
    assert cmp.double_support(s) == pytest.approx(30.0)
    assert cmp.contacts(s, 0) == (1, pytest.approx(60.0))
    assert cmp.contacts(s, 1) == (1, pytest.approx(70.0))
    contact = np.zeros((11, 4, 2))
    contact[:, 0, 1], contact[:, 1, 1] = 300.0, 100.0  # right heel 300 N, right toe 100 N throughout
    assert cmp.toe_share(SimpleNamespace(t=t, contact=contact)) == pytest.approx(0.25)


def test_the_report_states_the_stored_strides_objective(mech, stored):
    from dataclasses import replace

    from exo_bench.bench.studies.stride import data, report
    from exo_bench.bench.studies.stride.problem import settings_for
    from exo_bench.models.files import markdown_text

    s = data.load("human", 1.41, mech, stored)
    assert "the telescopic rods' work at 1x the joints'" in report.objective_line(s)  # none stored: defaults
    mine = replace(settings_for(mech, "human", 1.41), w_negative=0.2, strength=(2.5, 2.0, 3.0)).to_dict()
    line = report.objective_line(StoredStride(**{**s.__dict__, "meta": {**s.meta, "settings": mine}}))
    assert "positive priced 1 and negative 0.2, the telescopic rods' work at 10x the joints'" in line
    assert "strengths hip 2.5, knee 2, ankle 3 N·m/kg" in line and "period fixed at 0.987 s" in line
    assert report.markdown(mech, s, folder=stored).count(markdown_text(report.objective_line(s))) == 1


def test_trials_are_tabled_beside_the_stored_stride_with_what_they_change(mech, stored, tmp_path):
    from exo_bench.bench.studies.stride import data, report
    from exo_bench.models.files import markdown_text

    s = data.load("human", 1.41, mech, stored)
    assert report.trials_table(mech, s, tmp_path / "none") == []  # no trials: no section
    assert "Trials of the problem" not in report.markdown(mech, s, folder=stored)
    fast = winter_stride(mech, moment_scale=3.0)
    meta = {**fast.meta, "settings": {"w_negative": 0.2, "strength": [1.0, 1.0, 2.0]}}
    data.save(StoredStride(**{**fast.__dict__, "meta": meta}), mech, tmp_path / "trials" / "cheaper")
    rows = report.trials_table(mech, s, tmp_path / "trials")
    assert len(rows) == 4 and rows[2].startswith("| \\(the stored stride\\) |  | 5 of 5 | 17 of 17 | hip ")
    diff = "strength 1, 1, 2 (stored: 1, 1, 1); w_negative 0.2 (stored: 0.5)"
    assert rows[3].startswith(f"| cheaper | {markdown_text(diff)} | 4 of 5 | 5 of 17 | hip ")  # 3x: peaks fail
    assert rows[3].split(" | ")[4] == rows[2].split(" | ")[4]  # the same r: the moments scaled
    assert "| cheaper |" in report.markdown(mech, s, folder=tmp_path)
    assert report.settings_difference({"w_rod_work": 10.0}, {"w_rod_work": 10.0}) == "none"
