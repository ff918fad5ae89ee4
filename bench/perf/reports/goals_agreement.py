"""The agreement of the results that issue 35's goals time (bench/perf/reports/goals_call_overhead.py):
a timing is reported only beside the evidence that the timed call computed the right forces."""

from __future__ import annotations

from typing import Any

import numpy as np


def agreement(st: dict, results: dict, one_sample: tuple[str, ...]) -> dict:
    """Errors of the one-sample inverse results (the keys ``one_sample`` of ``results``) against the
    50-digit reference, and the backward errors of the forward results (the same bound as
    bench/test_forward_dynamics.py); ``st`` holds the states and the model the results came from
    (:func:`exo_bench.bench.perf.reports.goals_call_overhead.calls`)."""
    from exo_bench.bench.studies.reference_forces import reference

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
