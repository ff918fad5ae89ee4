"""Issue 35's goals: what the public call costs on top of its kernel, measured in one process as
ratios on exo5-3d, each stated met or not, beside the evidence that each timed call computed the right
forces (:func:`agreement`).

``python -m exo_bench.bench.perf.reports.goals_call_overhead`` measures and prints them;
``bench/test_call_overhead.py`` runs the same :func:`measure` as the benchmark row
``test_issue35_goals`` (and times each call alone as a pytest-benchmark row of its own), and
``exo-bench bench`` writes :func:`goals_lines` into reports/scaling.md (:func:`report_lines`).

What is timed (exo5-3d, ``matrix-factored`` unless named, states along a smooth random motion;
only the public API: ``exo_bench.prepare`` and the prepared model's calls):

* ``rnea``: the bare ``pin.rnea`` of the same model on preallocated joint coordinates (no maps,
  no checks): the denominator of the one-sample goals;
* one sample, 1-D arrays: ``inverse_dynamics`` by default (``check=True``), with ``check=False``,
  with ``check=False, out=``; ``newton-euler``'s the same three ways; ``forward_dynamics``
  checked and unchecked, and newton-euler's checked;
* a batch of ``samples`` states: ``inverse_dynamics`` and ``forward_dynamics`` with and without
  ``check`` (no ``out``, the call as the README shows it);
* issue 47's goals: the public ``model.derivatives.inverse_dynamics`` of one sample, checked and with
  ``check=False`` (``(dtau_dq, dtau_dqd, M)``, three new ``(dof, dof)`` arrays a call), against the same
  bare ``pin.rnea``: the call a user makes, not the kernel that reports/derivatives.md times.

Every time is the median over ``rounds`` rounds interleaved across the candidates (a load that
comes and goes falls on all of them alike); a one-sample round is ``timeit`` of up to 2,000
calls (fewer for a slow call, so that each round takes about 10 ms), the statement calling the
prepared model's method directly, so the loop adds the same few tens of nanoseconds to every
candidate, the bare ``pin.rnea`` included. A one-sample round reads the CPU time of the calling
thread by default (:data:`CLOCKS`: every one-sample candidate runs in that thread alone, so time
spent descheduled by other jobs on a shared machine is not counted; ``clock="wall"`` reads the wall
clock), a batch round the wall clock. The goals are judged on the medians; the ratios of the
fastest rounds are stated beside them (on a shared machine, the least disturbed figures).

**Fast and slow processes.** On the 2-vCPU KVM machine the one-sample calls ran at two speeds:
0.33 or 0.60 us for the lean kernel with ``out``, and a pure-Python loop 9 or 17 us alongside it, in
the same process with the same arrays, switching every second or so (steal time 1-6 %), and in
processes whose every address was the same (``setarch -R``, one ``PYTHONHASHSEED``). So the machine
(its host), not memory layout, sets the speed; but ``pin.rnea`` slows by only 1.2x where the public
call slows by 1.4-1.7x, so a ratio measured in a slow phase is 1.4x larger.

**Without C (issue 47).** Until issue 47 a one-sample call ran in a hand-written C extension
(models/runtime/_lean_call.c, about 0.3 us); it is gone. A one-sample call is now the public call's Python frame,
the checks numba's unboxing trusts (type, dimension count, dtype: about 25 ns an array) and one call of
the kernel's compiled validate-and-compute entry (about 40 ns an array to unbox, the checks and the
kernel in compiled code, scratch on the stack, an int answer).
"""

from __future__ import annotations

import sys
import time
import timeit
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from exo_bench.bench.perf.reports.simd_goals import _states


# The agreement of the results that issue 35's goals time (bench/perf/reports/goals_call_overhead.py): a timing
# is reported only beside the evidence that the timed call computed the right forces.


def agreement(st: dict, results: dict, one_sample: tuple[str, ...]) -> dict:
    """Errors of the one-sample inverse results (the keys ``one_sample`` of ``results``) against the
    50-digit reference, and the backward errors of the forward results (the same bound as
    bench/test_forward_dynamics.py); ``st`` holds the states and the model the results came from
    (:func:`exo_bench.bench.perf.reports.goals_call_overhead.calls`)."""
    from exo_bench.bench.studies.study import reference

    mech, mf, eps, k = st["mech"], st["mf"], float(np.finfo(float).eps), 16
    q, qd, qdd, tau = st["q"], st["qd"], st["qdd"], st["tau"]
    want, label = reference(mech, q[:1], qd[:1], qdd[:1])
    res: dict[str, Any] = {"reference": label, "err_bound": float(k * eps * mech.dof * np.abs(want).max())}
    res["inverse_err"] = {
        key: float(np.abs(np.asarray(results[key]) - want[0]).max())
        for key in one_sample
        if key in results and "forward" not in key and "derivatives" not in key and key != "rnea"
    }
    if "derivatives_checked" in results:  # M = dtau/dqdd of the derivatives against the model's mass matrix
        M = mf.mass_matrix(q[0])
        res["derivatives_mass_err"] = {
            key: float(np.abs(np.asarray(results[key])[2] - M).max()) / float(np.abs(M).max())
            for key in ("derivatives_checked", "derivatives_unchecked")
        }
    if "rnea" in results:
        res["inverse_err"]["rnea"] = float(np.abs(np.asarray(results["rnea"]) @ st["rnea_to_paper"] - want[0]).max())
    idx = np.unique(np.linspace(0, q.shape[0] - 1, min(q.shape[0], 64)).round().astype(int))
    backward = {}
    forward = ("forward_checked", "forward_unchecked", "newton_euler_forward_checked")
    for key in (*forward, "forward_batch_checked", "forward_batch_unchecked"):
        got = np.asarray(results[key]).reshape(-1, mech.dof)
        batch = got.shape[0] == q.shape[0]
        at = idx if batch else np.arange(got.shape[0])  # a batch: a subsample; one sample: sample 0
        got = got[at] if batch else got
        s = (q[at], qd[at], got)
        zero = np.zeros_like(got)
        h = mf.inverse_dynamics(s[0], s[1], zero, check=False)
        mq = mf.inverse_dynamics(s[0], zero, got, check=False) - mf.inverse_dynamics(s[0], zero, zero, check=False)
        residual = mf.inverse_dynamics(*s, check=False) - tau[at]
        scale = np.abs(tau[at]).max() + np.abs(mq).max() + np.abs(h).max()
        backward[key] = (float(np.abs(residual).max()), float(k * eps * mech.dof * scale))
    res["forward_backward_err"] = backward
    res["inverse_batch_diff"] = float(
        np.abs(np.asarray(results["inverse_batch_checked"]) - np.asarray(results["inverse_batch_unchecked"])).max()
    )
    return res


@dataclass(frozen=True)
class Goal:
    """One goal: ``timings[num] / timings[den] <= bound``."""

    what: str
    num: str
    den: str
    bound: float


RNEA = "bare `pin.rnea`"
#: Issue 35's goals, in the issue's order.
GOALS = (
    Goal("one sample, default call (`check=True`)", "inverse_checked", "rnea", 0.3),
    Goal("one sample, `check=False`, no `out`", "inverse_unchecked", "rnea", 0.15),
    Goal("one sample, `check=False, out=`", "inverse_unchecked_out", "rnea", 0.1),
    Goal("newton-euler, one sample, `check=False`, no `out`", "newton_euler_unchecked", "rnea", 0.15),
    Goal("newton-euler, one sample, `check=False, out=`", "newton_euler_unchecked_out", "rnea", 0.15),
    Goal("`forward_dynamics`, one sample, checked", "forward_checked", "rnea", 0.5),
    Goal("inverse batch, checked against unchecked", "inverse_batch_checked", "inverse_batch_unchecked", 1.25),
    Goal("forward batch, checked against unchecked", "forward_batch_checked", "forward_batch_unchecked", 1.25),
    # issue 47: the public derivative call a user makes, not its kernel (reports/derivatives.md times that)
    Goal("`model.derivatives.inverse_dynamics`, one sample, `check=False`", "derivatives_unchecked", "rnea", 1.0),
    Goal("`model.derivatives.inverse_dynamics`, one sample, checked", "derivatives_checked", "rnea", 1.5),
)
#: Timed beside the goals and reported, no goal of their own.
ALSO = (
    ("newton-euler, one sample, default call (`check=True`)", "newton_euler_checked", "rnea"),
    ("`forward_dynamics`, one sample, `check=False`", "forward_unchecked", "rnea"),
    ("newton-euler `forward_dynamics`, one sample, checked", "newton_euler_forward_checked", "rnea"),
)
#: Which timings are one sample per call (the rest are batches).
ONE_SAMPLE = (
    "rnea",
    "inverse_checked",
    "inverse_unchecked",
    "inverse_unchecked_out",
    "newton_euler_checked",
    "newton_euler_unchecked",
    "newton_euler_unchecked_out",
    "forward_checked",
    "forward_unchecked",
    "newton_euler_forward_checked",
    "derivatives_checked",
    "derivatives_unchecked",
)
BATCH = ("inverse_batch_checked", "inverse_batch_unchecked", "forward_batch_checked", "forward_batch_unchecked")


@dataclass(frozen=True)
class Call:
    """One timed call: ``fn(*args, **kwargs)``."""

    fn: Callable[..., Any]
    args: tuple
    kwargs: dict

    def __call__(self):
        return self.fn(*self.args, **self.kwargs)

    def timer(self, clock: Callable[[], float] = time.perf_counter) -> timeit.Timer:
        """A ``timeit`` timer whose statement calls ``fn`` with the arguments by name (no unpacking),
        reading ``clock``."""
        names = {"fn": self.fn, **{f"a{i}": a for i, a in enumerate(self.args)}}
        names.update({f"k_{k}": v for k, v in self.kwargs.items()})
        params = [f"a{i}" for i in range(len(self.args))] + [f"{k}=k_{k}" for k in self.kwargs]
        return timeit.Timer(f"fn({', '.join(params)})", timer=clock, globals=names)


def calls(samples: int) -> tuple[dict[str, Call], dict]:
    """The candidates (:data:`ONE_SAMPLE` and :data:`BATCH` keys) on exo5-3d, and the states they use."""
    from exo_bench import prepare

    mech, q, qd, qdd = _states(samples)
    mf, ne = prepare(mech, "matrix-factored"), prepare(mech, "newton-euler")
    tau = mf.inverse_dynamics(q, qd, qdd, check=False)
    q0, qd0, qdd0, tau0 = (np.ascontiguousarray(a[0]) for a in (q, qd, qdd, tau))
    o_mf, o_ne = np.empty(mech.dof), np.empty(mech.dof)
    one, unchecked = (q0, qd0, qdd0), {"check": False}
    c = {
        "inverse_checked": Call(mf.inverse_dynamics, one, {}),
        "inverse_unchecked": Call(mf.inverse_dynamics, one, unchecked),
        "inverse_unchecked_out": Call(mf.inverse_dynamics, one, {"check": False, "out": o_mf}),
        "newton_euler_checked": Call(ne.inverse_dynamics, one, {}),
        "newton_euler_unchecked": Call(ne.inverse_dynamics, one, unchecked),
        "newton_euler_unchecked_out": Call(ne.inverse_dynamics, one, {"check": False, "out": o_ne}),
        "forward_checked": Call(mf.forward_dynamics, (q0, qd0, tau0), {}),
        "forward_unchecked": Call(mf.forward_dynamics, (q0, qd0, tau0), unchecked),
        "newton_euler_forward_checked": Call(ne.forward_dynamics, (q0, qd0, tau0), {}),
        "inverse_batch_checked": Call(mf.inverse_dynamics, (q, qd, qdd), {}),
        "inverse_batch_unchecked": Call(mf.inverse_dynamics, (q, qd, qdd), unchecked),
        "forward_batch_checked": Call(mf.forward_dynamics, (q, qd, tau), {}),
        "forward_batch_unchecked": Call(mf.forward_dynamics, (q, qd, tau), unchecked),
        "derivatives_checked": Call(mf.derivatives.inverse_dynamics, one, {}),
        "derivatives_unchecked": Call(mf.derivatives.inverse_dynamics, one, unchecked),
    }
    states: dict[str, Any] = {"mech": mech, "q": q, "qd": qd, "qdd": qdd, "tau": tau, "mf": mf}
    try:
        import pinocchio as pin

        from exo_bench.models.engines.pinocchio_backend import build_model

        pm = build_model(mech)
        qj, vj, aj = (np.ascontiguousarray(pm.G @ x) for x in one)
        c["rnea"] = Call(pin.rnea, (pm.model, pm.create_data(), qj, vj, aj), {})
        states["rnea_to_paper"] = pm.G  # tau_paper = G^T tau_joint
    except ImportError as e:
        states["rnea_missing"] = f"pinocchio not installed ({e})"
    return c, states


def _calls_per_round(timer: timeit.Timer, most: int, round_seconds: float) -> int:
    """How many calls make a round of about ``round_seconds`` (at least 1, at most ``most``),
    from ten calls' time: a slow call (the checked call before issue 35) does not make the run long."""
    one = timer.timeit(10) / 10
    return int(max(1, min(most, round_seconds / max(one, 1e-9))))


def _round_times(timers: dict[str, timeit.Timer], most: int, rounds: int, round_seconds: float) -> tuple[dict, dict]:
    """Seconds per call of each timer in each of ``rounds`` interleaved rounds, and the calls of
    its rounds (:func:`_calls_per_round`). Every other round runs the timers in reverse order, so
    that no timer always runs first in a round (the first call after other work pays for waking
    the thread pool and for cold caches: the checked batch, first in a fixed order, measured 1.8x
    its unchecked twin where alternating orders give 1.15x)."""
    number = {k: _calls_per_round(t, most, round_seconds) for k, t in timers.items()}
    seconds: dict[str, list[float]] = {k: [] for k in timers}
    order = list(timers)
    for r in range(rounds):
        for k in order if r % 2 == 0 else order[::-1]:
            seconds[k].append(timers[k].timeit(number[k]) / number[k])
    return seconds, number


#: The clocks of one-sample rounds (module docstring); batches read the wall clock.
CLOCKS = {"thread": time.thread_time, "wall": time.perf_counter}


def measure(
    samples: int = 10_000,
    rounds: int = 30,
    calls_per_round: int = 2000,
    round_seconds: float = 0.01,
    clock: str = "thread",
) -> dict:
    """Every figure of the goals (module docstring), in this process: seconds per call in
    ``timings``, the agreement of every result, and how it was measured (a one-sample round is at
    most ``calls_per_round`` calls and about ``round_seconds``; a batch round is one call)."""
    c, st = calls(samples)
    results = {k: np.array(call(), copy=True) for k, call in c.items()}  # first calls: compile, load, agree
    t0 = time.perf_counter()
    one = {k: c[k].timer(CLOCKS[clock]) for k in ONE_SAMPLE if k in c}
    seconds, number = _round_times(one, calls_per_round, rounds, round_seconds)
    seconds.update(_round_times({k: c[k].timer() for k in BATCH}, 1, rounds, 0.0)[0])
    r = {
        "mechanism": st["mech"].name,
        "samples": samples,
        "rounds": rounds,
        "clock": clock,
        "calls_per_round": number,
        "seconds_measuring": time.perf_counter() - t0,
        "load": _load(),  # how busy the machine was as the timing ended
        "timings": {k: float(np.median(v)) for k, v in seconds.items()},  # what the goals judge
        "fastest": {k: float(np.min(v)) for k, v in seconds.items()},  # the least disturbed rounds
    }
    if "rnea_missing" in st:
        r["rnea_missing"] = st["rnea_missing"]
    r.update(agreement(st, results, ONE_SAMPLE))
    return r


def _load() -> dict:
    """The 1-minute load average against the CPUs (``{}`` where the OS does not say)."""
    import os

    try:
        return {"load_1min": os.getloadavg()[0], "cpus": os.cpu_count()}
    except (AttributeError, OSError):
        return {}


def _met(ok: bool) -> str:
    return "**met**" if ok else "**not met**"


def _us(seconds: float) -> str:
    return f"{seconds * 1e6:.3g} us"


def _calls(r: dict) -> str:
    n = r.get("calls_per_round") or {}
    values = list(n.values()) if isinstance(n, dict) else [n]  # one count for all (the first rows' form)
    if not values:
        return "? calls a round"
    lo, hi = min(values), max(values)
    return f"{hi:,} calls a round" if lo == hi else f"{lo:,} to {hi:,} calls a round (rounds of about the same time)"


def _clock(r: dict) -> str:
    """Which clock timed the one-sample rounds (rows before the option: the wall clock)."""
    if r.get("clock", "wall") == "thread":
        return " timed by the CPU time of the calling thread (time descheduled by other jobs not counted)"
    return " timed by the wall clock"


def _busy(load: dict) -> str:
    if not load:
        return ""
    shared = load["load_1min"] > 0.5 * (load["cpus"] or 1)
    return f" Load average {load['load_1min']:.2f} on {load['cpus']} CPUs as the timing ended" + (
        ": a busy machine, the figures are provisional." if shared else "."
    )


def verdicts(r: dict) -> list[tuple[Goal, float | None, bool]]:
    """``(goal, ratio or None when unmeasured, met)`` for every goal of :data:`GOALS`, in order;
    an unmeasured goal is not met."""
    t = r.get("timings", {})
    out = []
    for g in GOALS:
        ratio = t[g.num] / t[g.den] if g.num in t and g.den in t and t[g.den] > 0 else None
        out.append((g, ratio, ratio is not None and ratio <= g.bound))
    return out


def goals_lines(r: dict, source: str = "bench/test_call_overhead.py::test_issue35_goals") -> list[str]:
    """Issue 35's section: every goal of :data:`GOALS` with its measured ratio, met or not."""
    t = r.get("timings", {})
    lines = [
        "## Issue 35: the cost of the public call",
        "",
        f"{r.get('mechanism', 'exo5-3d')}, `matrix-factored` unless named, one process (`{source}`; medians of "
        f"{r.get('rounds', '?')} interleaved rounds, {_calls(r)} for one sample{_clock(r)}, "
        f"one call of {r.get('samples', 0):,} samples for a batch). One-sample ratios are against "
        + (
            f"{RNEA} on the same model, {_us(t['rnea'])} a call."
            if "rnea" in t
            else f"{RNEA}: not measured ({r.get('rnea_missing', 'no rnea timing')})."
        )
        + _busy(r.get("load") or {}),
        "",
        "| goal | measured | against | ratio | goal | verdict |",
        "|---|---|---|---|---|---|",
    ]
    for g, ratio, ok in verdicts(r):
        num = _us(t[g.num]) if g.num in t else "not measured"
        den = RNEA if g.den == "rnea" else (f"unchecked {_us(t[g.den])}" if g.den in t else "not measured")
        cell = f"{ratio:.3g}x" if ratio is not None else "not measured"
        verdict = _met(ok) + ("" if ratio is not None else " (unmeasured)")
        lines.append(f"| {g.what} | {num} | {den} | {cell} | <= {g.bound:g}x | {verdict} |")
    met = sum(ok for _, _, ok in verdicts(r))
    lines += ["", f"{met} of {len(GOALS)} goals met (judged on the medians)."]
    fastest = [(g, ratio) for g, ratio, _ in verdicts({"timings": r.get("fastest", {})}) if ratio is not None]
    if fastest:
        lines += [
            "",
            "The same ratios of the fastest rounds (the least disturbed by other work on a shared machine): "
            + "; ".join(f"{g.what} {ratio:.3g}x" for g, ratio in fastest)
            + ".",
        ]
    also = [f"{what}: {_us(t[k])}, {t[k] / t[d]:.3g}x" for what, k, d in ALSO if k in t and d in t]
    if also:
        lines += ["", "Also timed, no goal: " + "; ".join(also) + f" ({RNEA})."]
    if "inverse_err" in r:
        worst = max(r["inverse_err"].values(), default=float("nan"))
        fwd = r.get("forward_backward_err", {})
        lines += [
            "",
            f"Agreement of the timed results: one-sample inverse dynamics within {worst:.2g} of the "
            f"{r.get('reference', 'reference')} (bound {r['err_bound']:.2g}); forward dynamics' backward error "
            + ", ".join(f"{k} {e:.2g} (bound {b:.2g})" for k, (e, b) in fwd.items())
            + f"; checked and unchecked inverse batches differ by {r.get('inverse_batch_diff', float('nan')):.2g}.",
        ]
    return lines + [""]


def rows_lines(df) -> list[str]:
    """The same calls timed one after another as pytest-benchmark rows (group ``overhead-exo5-3d``
    of bench/test_call_overhead.py): each median, and per sample against the bare ``pin.rnea`` row."""
    rows = df[df["group"] == "overhead-exo5-3d"] if not df.empty and "group" in df else df.iloc[:0]
    if rows.empty:
        return []
    med = rows.set_index("method")["median"]
    order = [k for k in (*ONE_SAMPLE, *BATCH) if k in med.index]
    lines = [
        "The same calls, each its own pytest-benchmark row (`bench/test_call_overhead.py::test_call`, timed one "
        "after another, so not the goals' figures): median per call, and per sample against the `rnea` row.",
        "",
        "| call | median per call | per sample against rnea |",
        "|---|---|---|",
    ]
    for k in order:
        per = med[k] / float(rows.set_index("method").loc[k, "samples"])
        x = f"{per / med['rnea']:.3g}x" if "rnea" in med.index else "no rnea row"
        lines.append(f"| {k} | {_us(med[k])} | {x} |")
    return lines + [""]


def report_lines(df) -> list[str]:
    """The section of reports/scaling.md from the benchmark rows (the ``issue35-goals`` group of
    bench/test_call_overhead.py, then :func:`rows_lines`), or nothing when neither ran."""
    if df.empty or "group" not in df:
        return []
    rows = df[df["group"] == "issue35-goals"] if "call_overhead" in df else df.iloc[:0]
    if rows.empty:
        extra = rows_lines(df)
        return (
            ["## Issue 35: the cost of the public call", "", "The goals' row did not run.", "", *extra] if extra else []
        )
    return goals_lines(rows.iloc[0]["call_overhead"]) + rows_lines(df)


def main(argv=None) -> int:
    import argparse
    import json

    ap = argparse.ArgumentParser(
        prog="python -m exo_bench.bench.perf.reports.goals_call_overhead", description=__doc__.splitlines()[0]
    )
    ap.add_argument("--samples", type=int, default=10_000)
    ap.add_argument("--rounds", type=int, default=30)
    ap.add_argument("--calls", type=int, default=2000, help="one-sample calls per round")
    ap.add_argument("--clock", choices=sorted(CLOCKS), default="thread", help="clock of the one-sample rounds")
    ap.add_argument("--json", default=None, help="also write the figures to this JSON file")
    a = ap.parse_args(argv)
    command = " ".join(
        ["python -m exo_bench.bench.perf.reports.goals_call_overhead", *(sys.argv[1:] if argv is None else argv)]
    )
    r = measure(a.samples, a.rounds, a.calls, clock=a.clock)
    if a.json:
        from exo_bench.models.files import atomic_write

        atomic_write(a.json, json.dumps(r, indent=1))
    print("\n".join(goals_lines(r, command)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
