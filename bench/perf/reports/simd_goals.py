"""Issue 23's goals, measured in one process: the SIMD batch path, the lean per-call path, the
limit, Pinocchio and PyDy, and the threading trap.

``python -m exo_bench.bench.perf.reports.simd_goals`` measures and prints the goals, each met or not with its
ratio (the figures the README quotes); ``bench/test_simd.py`` runs the same :func:`measure` as a
benchmark row, and ``exo-bench bench`` writes its lines into reports/scaling.md
(:func:`goals_lines`). Every time is the median of rounds interleaved across the candidates, so a
load that comes and goes on a shared machine falls on all of them alike; compare the ratios.

What is timed (exo5-3d, states along a smooth random motion):

* ``batched_1t``/``batched_2t``: the public call ``model.inverse_dynamics(q, qd, qdd, check=False,
  out=out)`` on ``(samples, dof)`` arrays, with ``numba.set_num_threads(1)`` and ``(2)``;
* ``per_sample_kernel_1t``: the per-sample compiled kernel (compiled_factored) on the same batch,
  the path the SIMD kernel replaced;
* ``pinocchio_best``: Pinocchio's fastest batched path here: the prepared ``pinocchio`` model
  (``pin.rnea`` per sample) and ``rneaInParallel`` at 2, cpus and 2 x cpus threads;
* ``per_call``: one sample, 1-D arrays, ``check=False``, ``out=``, through the public call;
* ``pydy_per_call``: PyDy's Cython code of the same composed equations into ``out``;
* ``trap``: the batch in a fresh process, normally and after a user's ``prange`` started numba's
  OpenMP threads first (the median of each, both in subprocesses alike);
* the limit: the SIMD kernel's counted flops at this CPU's SIMD rate (bench/perf/roofline.py).
* ``newton_euler_batched_1t``: ``newton-euler (numba)``'s public call on the same arrays (its kernel
  that vectorises across samples, models/newton_euler/simd.py), one thread, with its own counted
  limit (bench/perf/roofline.py). The batched goal is judged on the faster of the two
  methods' public calls, named in the line; ``matrix-factored``'s figures stay reported.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

#: Issue 23's goals.
GOAL_US_PER_SAMPLE = 0.06
GOAL_X_LIMIT = 2.0
GOAL_VS_PINOCCHIO = 60.0
GOAL_PER_CALL_US = 0.45
GOAL_VS_PYDY = 0.6
GOAL_TRAP = 1.2
#: The batch size the batched goals are stated at: a smaller run (the quick profile's) reports its
#: figures against them without judging them.
GOAL_SAMPLES = 10_000


def _states(samples: int):
    from exo_bench.models.gait.motion import smooth_random_motion
    from exo_bench.models.mechanism.presets import exo5

    mech = exo5(3)
    mo = smooth_random_motion(mech, np.linspace(0.0, 10.0, samples), seed=5)
    return mech, *(np.ascontiguousarray(a, dtype=float) for a in (mo.q, mo.qd, mo.qdd))


def _interleaved(candidates: dict[str, Callable[[], object]], rounds: int) -> dict[str, float]:
    """Median seconds of each ``candidates[name]()`` over ``rounds`` rounds, interleaved."""
    times: dict[str, list[float]] = {k: [] for k in candidates}
    for _ in range(rounds):
        for k, fn in candidates.items():
            t0 = time.perf_counter()
            fn()
            times[k].append(time.perf_counter() - t0)
    return {k: float(np.median(v)) for k, v in times.items()}


def _with_threads(fn, threads: int):
    import numba

    def run():
        before = numba.get_num_threads()
        numba.set_num_threads(threads)
        try:
            fn()
        finally:
            numba.set_num_threads(before)

    return run


#: What a user's script may do before importing exo-bench: start numba's threads on the OpenMP
#: layer with a ``prange`` of its own (tests/test_threading_layer.py runs it too).
OMP_FIRST = r"""
import numba, numpy as np
numba.config.THREADING_LAYER = "omp"
from numba import njit, prange

@njit(parallel=True)
def users_own(x):
    s = 0.0
    for i in prange(x.shape[0]):
        s += x[i]
    return s

users_own(np.ones(10_000))
"""

_TRAP = r"""
import json, sys, time, numba, numpy as np
if sys.argv[1] == "omp-first":
    exec(sys.argv[4])
from exo_bench.bench.perf.reports.simd_goals import _states
from exo_bench import prepare
mech, q, qd, qdd = _states(int(sys.argv[2]))
m = prepare(mech, "matrix-factored")
out = np.empty_like(q)
m.inverse_dynamics(q, qd, qdd, check=False, out=out)
t = []
for _ in range(int(sys.argv[3])):
    t0 = time.perf_counter(); m.inverse_dynamics(q, qd, qdd, check=False, out=out); t.append(time.perf_counter() - t0)
try:
    layer = numba.threading_layer()
except ValueError:                              # numba's threads never started in this process
    layer = "none started"
print(json.dumps({"seconds": float(np.median(t)), "layer": layer, "threads": numba.get_num_threads()}))
"""


def _trap(samples: int, rounds: int) -> dict:
    res = {}
    for mode in ("normal", "omp-first"):
        r = subprocess.run(
            [sys.executable, "-c", _TRAP, mode, str(samples), str(rounds), OMP_FIRST],
            capture_output=True,
            text=True,
            timeout=600,
        )
        if r.returncode != 0:
            return {"error": (r.stderr.strip().splitlines() or ["?"])[-1]}
        res[mode] = json.loads(r.stdout.strip().splitlines()[-1])
    res["ratio"] = res["omp-first"]["seconds"] / res["normal"]["seconds"]
    return res


def measure(samples: int = 10_000, rounds: int = 30, calls: int = 2000, pydy: bool = True, trap: bool = True) -> dict:
    """Every figure of the goals (module docstring), in this process (the trap in two subprocesses)."""
    from exo_bench import prepare
    from exo_bench.api.cost_model import ResourceLimit
    from exo_bench.bench.perf import peers, roofline as limit
    from exo_bench.matrix_method.prepared import MatrixFactored

    mech, q, qd, qdd = _states(samples)
    model = prepare(mech, "matrix-factored")
    if not isinstance(model, MatrixFactored):  # its per-sample kernel is timed below
        raise TypeError(f"prepare(mech, 'matrix-factored') gave a {type(model).__name__}, not a MatrixFactored")
    out = np.empty_like(q)
    p = model.kernel_args[0]
    flat = (q.reshape(-1), qd.reshape(-1), qdd.reshape(-1))
    ref_out = np.empty(q.size)
    cpus = os.cpu_count() or 1
    pins = {1: prepare(mech, "pinocchio")}
    for t in sorted({2, cpus, 2 * cpus}):
        try:
            pins[t] = prepare(mech, "pinocchio", threads=t)
        except (MemoryError, ResourceLimit):  # one Data per thread does not fit
            pass
    pin_out = {t: None for t in pins}

    def pin_call(t):
        def run():
            pin_out[t] = pins[t].inverse_dynamics(q, qd, qdd, check=False)

        return run

    ne = prepare(mech, "newton-euler")
    ne_out = np.empty_like(q)
    batched = {
        "batched_1t": _with_threads(lambda: model.inverse_dynamics(q, qd, qdd, check=False, out=out), 1),
        "newton_euler_batched_1t": _with_threads(lambda: ne.inverse_dynamics(q, qd, qdd, check=False, out=ne_out), 1),
        "batched_2t": _with_threads(lambda: model.inverse_dynamics(q, qd, qdd, check=False, out=out), 2),
        "per_sample_kernel_1t": lambda: model.serial_kernel(p, *flat, ref_out),
    }
    for fn in batched.values():
        fn()  # compile or load, first-use costs
    res: dict[str, Any] = {"samples": samples, "mechanism": mech.name}  # JSON: numbers, names, dicts
    tb = _interleaved(batched, rounds)
    res.update({k: v / samples * 1e6 for k, v in tb.items()})  # us per sample
    pin_rounds = max(3, rounds // 10)  # Pinocchio is ~100x slower
    for fn in (pin_call(k) for k in pins):
        fn()
    tp = _interleaved({f"pinocchio_{k}t": pin_call(k) for k in pins}, pin_rounds)
    res["pinocchio_us"] = {k: v / samples * 1e6 for k, v in tp.items()}
    res["pinocchio_best"] = min(res["pinocchio_us"], key=res["pinocchio_us"].get)
    res["pinocchio_best_us"] = res["pinocchio_us"][res["pinocchio_best"]]

    # one sample per call: the public lean path, and PyDy into out
    q0, qd0, qdd0, o0 = q[0].copy(), qd[0].copy(), qdd[0].copy(), np.empty(mech.dof)
    model.inverse_dynamics(q0, qd0, qdd0, check=False, out=o0)
    idf = model.inverse_dynamics

    def per_call():
        for _ in range(calls):
            idf(q0, qd0, qdd0, check=False, out=o0)

    single = {"per_call": per_call}
    why = peers.missing() if pydy else "not asked (pydy=False)"
    if not why:
        f = peers.pydy_cython(mech)
        po = np.empty(mech.dof)
        call = f.call

        def pydy_call():
            for _ in range(calls):
                call(q0, qd0, qdd0, po)

        single["pydy_per_call"] = pydy_call
    res["pydy_missing"] = why
    ts = _interleaved(single, rounds)
    res.update({k: v / calls * 1e6 for k, v in ts.items()})  # us per call
    # the errors, against the 50-digit reference (bench/studies/study.py), bound as the benchmark's
    from exo_bench.bench.studies.study import reference

    idx = np.unique(np.linspace(0, samples - 1, 12).round().astype(int))
    want, label = reference(mech, q[idx], qd[idx], qdd[idx])
    bound = 16 * np.finfo(float).eps * mech.dof * np.abs(want).max()
    res["batched_err"] = float(np.abs(out[idx] - want).max())
    res["newton_euler_batched_err"] = float(np.abs(ne_out[idx] - want).max())
    one, _ = reference(mech, q0[None], qd0[None], qdd0[None])
    res["per_call_err"] = float(np.abs(o0 - one[0]).max())
    res["err_bound"], res["reference"] = float(bound), label
    if "pydy_per_call" in single:
        res["pydy_err"] = float(np.abs(po - one[0]).max())
    # the limit
    count, tau = limit.count_simd(mech, q0, qd0, qdd0)
    assert np.array_equal(tau, model.inverse_dynamics(q0[None], qd0[None], qdd0[None], check=False)[0]), (
        "the counted run is not what the SIMD kernel computes"
    )
    rates = limit.throughput()
    res["count"], res["rates"] = count, rates
    res["limit_1t_us"] = limit.estimate_simd(count, rates, 1) * 1e6
    res["limit_2t_us"] = limit.estimate_simd(count, rates, 2) * 1e6
    from exo_bench.bench.perf.roofline import count_newton_euler_simd

    ne_count, ne_tau = count_newton_euler_simd(mech, q0, qd0, qdd0)
    from exo_bench.models.newton_euler.simd import MIN_SAMPLES

    qr, qdr, qddr = (np.repeat(a[None], MIN_SAMPLES, axis=0) for a in (q0, qd0, qdd0))  # a batch on the SIMD path
    assert np.array_equal(ne_tau, ne.inverse_dynamics(qr, qdr, qddr, check=False)[0]), (
        "the counted run is not what newton-euler's SIMD kernel computes"
    )
    res["newton_euler_count"] = ne_count
    res["newton_euler_limit_1t_us"] = limit.estimate_simd(ne_count, rates, 1) * 1e6
    if trap:
        res["trap"] = _trap(samples, rounds)
    return res


def _met(ok: bool) -> str:
    return "**met**" if ok else "**not met**"


def _batched_verdict(ok: bool, samples: int) -> str:
    """A batched goal's verdict, judged only at the goal's own batch size (:data:`GOAL_SAMPLES`)."""
    if samples >= GOAL_SAMPLES:
        return _met(ok)
    return f"{'within' if ok else 'outside'} it at {samples:,} samples, not judged"


def goals_lines(r: dict) -> list[str]:
    """Issue 23's goals from :func:`measure`'s figures, each met or not with its ratio."""
    out = [
        "## Issue 23: kernels at the hardware limit",
        "",
        f"exo5-3d, {r['samples']:,} samples, one process (`python -m exo_bench.bench.perf.reports.simd_goals`; "
        "medians of interleaved rounds). Batched: `matrix-factored (numba)`'s public call on (samples, dof) "
        "arrays, which runs the kernel that vectorises across samples (`matrix_method/numba_kernels/simd.py`). "
        f"Errors against the {r['reference']}: batched {r['batched_err']:.2g}, per call {r['per_call_err']:.2g} "
        f"(bound {r['err_bound']:.2g}).",
        "",
    ]
    n = r["samples"]
    if n < GOAL_SAMPLES:
        out[-1:] = [
            f"The batched goals are stated at {GOAL_SAMPLES:,} samples; this run (the quick profile) has {n:,}, so "
            "they are reported here without a verdict. They are judged by the full sweep (reports/full/scaling.md, "
            "`exo-bench bench --full`) and by `python -m exo_bench.bench.perf.reports.simd_goals`.",
            "",
        ]
    us1, us2 = r["batched_1t"], r["batched_2t"]
    c = r["count"]
    if "newton_euler_batched_1t" in r:
        ne1, ne_lim = r["newton_euler_batched_1t"], r["newton_euler_limit_1t_us"]
        fastest = "newton-euler" if ne1 < us1 else "matrix-factored"
        best = min(us1, ne1)
        out.append(
            f"- Batched goal on the faster method's public call, **`{fastest} (numba)`**: {best:.3g} us per "
            f"sample (one thread), goal at most {GOAL_US_PER_SAMPLE} us: {_batched_verdict(best <= GOAL_US_PER_SAMPLE, n)}."
        )
        out.append(
            f"- `newton-euler (numba)` batched, one thread (models/newton_euler/simd.py): {ne1:.3g} us per "
            f"sample, {ne1 / us1:.2f}x `matrix-factored`'s; {ne1 / ne_lim:.2f}x its counted limit "
            f"({r['newton_euler_count']['flops']} flops per sample: {ne_lim * 1e3:.3g} ns); error "
            f"{r['newton_euler_batched_err']:.2g} (bound {r['err_bound']:.2g})."
        )
    out.append(
        f"- `matrix-factored (numba)` batched, one thread: {us1:.3g} us per sample, goal at most {GOAL_US_PER_SAMPLE} us: "
        f"{_batched_verdict(us1 <= GOAL_US_PER_SAMPLE, n)}; {us1 / r['limit_1t_us']:.2f}x the counted limit "
        f"({c['flops']} flops per sample, sin and cos as arithmetic, at "
        f"{r['rates']['simd_flops_per_s'] / 1e9:.3g} Gflop/s SIMD: {r['limit_1t_us'] * 1e3:.3g} ns), goal at "
        f"most {GOAL_X_LIMIT}x: {_batched_verdict(us1 <= GOAL_X_LIMIT * r['limit_1t_us'], n)}. The per-sample kernel it "
        f"replaced: {r['per_sample_kernel_1t']:.3g} us ({r['per_sample_kernel_1t'] / us1:.2g}x slower)."
    )
    out.append(
        f"- Batched, two threads: {us2:.3g} us per sample, {us2 / r['limit_2t_us']:.2f}x the limit on two "
        f"cores ({r['limit_2t_us'] * 1e3:.3g} ns)."
    )
    x = r["pinocchio_best_us"] / us1
    out.append(
        f"- Against Pinocchio's best batched path here (`{r['pinocchio_best']}`, {r['pinocchio_best_us']:.3g} "
        f"us per sample): {x:.3g}x faster per sample (one thread), goal at least {GOAL_VS_PINOCCHIO:g}x: "
        f"{_batched_verdict(x >= GOAL_VS_PINOCCHIO, n)}."
    )
    pc = r["per_call"]
    line = (
        f"- Per call, one sample, 1-D arrays, `check=False`, `out=`: {pc:.3g} us, goal at most "
        f"{GOAL_PER_CALL_US} us: {_met(pc <= GOAL_PER_CALL_US)}"
    )
    if "pydy_per_call" in r:
        ratio = pc / r["pydy_per_call"]
        line += (
            f"; PyDy's Cython code {r['pydy_per_call']:.3g} us in the same process: {ratio:.2f}x, goal at most "
            f"{GOAL_VS_PYDY}x: {_met(ratio <= GOAL_VS_PYDY)}."
        )
    else:
        line += f"; against PyDy: not measured ({r['pydy_missing']}): **not met** (unmeasured)."
    out.append(line)
    trap = r.get("trap") or {}
    if "ratio" in trap:
        out.append(
            f"- numba's OpenMP threads started first by the user's code: the batch took "
            f"{trap['omp-first']['seconds'] * 1e3:.3g} ms against {trap['normal']['seconds'] * 1e3:.3g} ms "
            f"normally ({trap['ratio']:.2f}x; layer then `{trap['omp-first']['layer']}`, "
            f"{trap['omp-first']['threads']} threads), goal at most {GOAL_TRAP}x: {_met(trap['ratio'] <= GOAL_TRAP)}."
        )
    else:
        out.append(f"- Threading trap: not measured ({trap.get('error', 'not asked')}): **not met** (unmeasured).")
    return out + [""]


def report_lines(df) -> list[str]:
    """The goals' lines of reports/scaling.md from the benchmark rows (the ``simd-goals`` group of
    bench/test_simd.py), or nothing when that row did not run."""
    if df.empty or "group" not in df or "simd_goals" not in df:
        return []
    rows = df[df["group"] == "simd-goals"]
    return goals_lines(rows.iloc[0]["simd_goals"]) if not rows.empty else []


#: The README block (bench/perf/reports/readme_blocks.py) that states issue 23's figures.
README_BLOCK = "simd-goals"


def readme_with_goals(readme: str, lines: list[str], command: str, details: str = "reports/simd-goals.md") -> str:
    """The README with :func:`goals_lines`' figures (``lines``; the heading left out) in its
    ``simd-goals`` block, pointing to ``details``, the report of the same run (the sweep's: its
    scaling.md); unchanged when there are no figures or no block."""
    from exo_bench.bench.perf.reports.readme_blocks import inserted_by, replace_block

    body = [ln for ln in lines if not ln.startswith("## ")]
    if not any(ln.strip() for ln in body):
        return readme
    head = inserted_by(command, f"one process, exo5-3d; details in [{details}]({details})")
    return replace_block(readme, README_BLOCK, "\n".join([head, "", *body]).rstrip())


def main(argv=None) -> int:
    import argparse

    ap = argparse.ArgumentParser(
        prog="python -m exo_bench.bench.perf.reports.simd_goals", description=__doc__.splitlines()[0]
    )
    ap.add_argument("--samples", type=int, default=10_000)
    ap.add_argument("--rounds", type=int, default=30)
    ap.add_argument("--json", default=None, help="also write the figures to this JSON file")
    ap.add_argument(
        "--markdown", default=None, help="also write them as a report with its provenance (e.g. reports/simd-goals.md)"
    )
    ap.add_argument(
        "--update-readme",
        action="store_true",
        help="also replace the figures in the checkout's reports/full/highlights.md (its simd-goals block), which the README links",
    )
    a = ap.parse_args(argv)
    command = " ".join(["python -m exo_bench.bench.perf.reports.simd_goals", *(sys.argv[1:] if argv is None else argv)])
    r = measure(a.samples, a.rounds)
    if a.json:
        from exo_bench.models.files import atomic_write

        atomic_write(a.json, json.dumps(r, indent=1))  # the one writer: never through a link
    print("\n".join(goals_lines(r)))
    if a.markdown:
        from exo_bench.bench.output.provenance import provenance
        from exo_bench.models.files import atomic_write

        atomic_write(
            a.markdown,
            "# The kernels against the hardware limit (issue 23)\n\n"
            + provenance(command)
            + "\n"
            + "\n".join(goals_lines(r)).replace("## Issue 23: kernels at the hardware limit\n", "")
            + "\n",
        )
    if a.update_readme:
        from exo_bench.bench.perf.reports.readme_blocks import rewrite_highlights

        page = rewrite_highlights(lambda readme: readme_with_goals(readme, goals_lines(r), command, "../simd-goals.md"))
        if page is not None:
            print(f"updated issue 23's figures in {page}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
