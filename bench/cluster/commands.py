"""``exo-bench bench --full`` and ``exo-bench stability --full`` on the cluster: the sweep's rows and the
stability study's parts as tasks (:mod:`exo_bench.bench.cluster.cluster`), then their reports."""

from __future__ import annotations

import json
import uuid
import warnings
from pathlib import Path

from exo_bench.bench.studies.options import BenchOptions
from exo_bench.bench.studies.options import ClusterOptions, Evaluator, StabilityOptions
from exo_bench.bench.perf import rows as _rows
from exo_bench.bench.output.provenance import REPO
from exo_bench.models.files import atomic_write
from exo_bench.bench.cluster.checkpoints import (
    checkpoint_dir,
    code_key,
    default_checkpoints,
    load_checkpoint,
    load_part,
    save_part,
)
from exo_bench.bench.cluster.cluster import (
    RETRIES,
    cancel_tasks,
    progress_bar,
    check_scheduler,
    cluster,
    enumerate_rows,
    run_sweep,
)
from exo_bench.bench.cluster.tasks import stability_task


# ----------------------------------------------------------------------------- exo-bench bench
def bench_run(options: BenchOptions) -> int:
    """``exo-bench bench`` on the cluster: the sweep as row tasks, then the reports of
    :mod:`exo_bench.bench.perf.reports.benchmark_reports` from the merged JSON (written only once every row is in)."""

    full = options.full
    sweep = "full" if full else "quick"
    out = options.folder.resolve()
    where = options.cluster or ClusterOptions()
    command = "exo-bench bench" + (" --full" if full else "")
    check_scheduler(where.scheduler)
    only = None
    if options.rows:  # a selection: its own report folder, the same checkpoints
        only = selected_rows(sweep, list(options.rows))
        command += "".join(f" --rows '{p}'" for p in options.rows)
    outcome = run_sweep(
        ["bench"],
        sweep,
        checkpoints=default_checkpoints(out),
        scheduler=where.scheduler,
        workers=where.workers,
        only=only,
    )
    if only is not None:
        out = out / "selected-rows"
    print(
        f"sweep {sweep}: {len(outcome.ran)} rows run on {outcome.workers} worker(s), {len(outcome.resumed)} "
        f"from checkpoints, {outcome.seconds:.0f} s",
        flush=True,
    )
    _write_reports(outcome.merged, outcome.skips, out, sweep, command, options.update_readme)
    return 0


def selected_rows(sweep: str, patterns: list[str]) -> list[str]:
    """The keys of the benchmark rows that match any of the shell-style ``patterns``; a ValueError
    naming some keys when none does."""
    from fnmatch import fnmatchcase

    keys = [r["key"] for r in enumerate_rows(["bench"], sweep)]
    only = [k for k in keys if any(fnmatchcase(k, p) for p in patterns)]
    if not only:
        raise ValueError(
            f"--rows: no row of the {sweep} sweep matches {', '.join(map(repr, patterns))}; "
            f"rows look like {', '.join(keys[:3])} ({len(keys)} rows)"
        )
    return only


def _write_reports(merged: dict, skips: list, out: Path, sweep: str, command: str, update_readme: bool) -> list[Path]:
    """The merged JSON and skips of a sweep into a staging folder, then every benchmark report from
    them (:func:`exo_bench.bench.perf.reports.benchmark_reports.write_reports`), published into ``out`` together."""
    from exo_bench.bench.perf.reports import benchmark_reports as br
    from exo_bench.bench.output.publish import staging_dir
    from exo_bench.bench.output.publish import benchmark_json

    with staging_dir(out) as st:
        bjson, sjson = st / benchmark_json(sweep), st / "skips.json"
        atomic_write(bjson, json.dumps(merged, indent=1))
        atomic_write(sjson, json.dumps(skips, indent=1))
        return br.write_reports(bjson, sjson, st, out, sweep, command, update_readme)


def render_checkpoints(
    code: str,
    out: Path,
    sweep: str = "full",
    checkpoints: Path | None = None,
    repo: Path = REPO,
    update_readme: bool = False,
) -> list[Path]:
    """The benchmark reports again, from the rows a sweep measured at ``code`` (its checkpoints),
    with this process's report code: for a change to how the reports are drawn, without measuring
    again. Every row of the profile must be there (a ValueError names the missing ones); the reports
    say at which code the rows were measured and that they were rendered again."""
    out = Path(out).resolve()
    folder = checkpoint_dir(checkpoints or default_checkpoints(out), code)
    rows = enumerate_rows(["bench"], sweep, repo=repo)
    records = {r["key"]: load_checkpoint(folder, r["key"]) for r in rows}
    missing = [k for k, v in records.items() if v is None]
    if missing:
        raise ValueError(
            f"render: {len(missing)} of {len(rows)} rows have no checkpoint at code {code} in {folder} "
            f"(first: {missing[0]}); run the sweep at that code first"
        )
    merged, skips = _rows.merge([rec for rec in records.values() if rec is not None])
    merged["sweep"] = {"profile": sweep, "code": code, "rendered_at": code_key(repo), "resumed": len(rows)}
    command = (
        f"exo-bench bench {'--full' if sweep == 'full' else ''}".strip()
        + f" (rows measured at {code}, reports rendered again at {code_key(repo)})"
    )
    from exo_bench.bench.output.publish import record_files, snapshot

    before = snapshot(out)
    written = _write_reports(merged, skips, out, sweep, command, update_readme)
    record_files(out, before, command)  # runs.json and summary.md say which run made each file
    return written


def stability_evaluator(options: StabilityOptions) -> Evaluator:
    """The ``evaluate(profile, methods, log)`` of :func:`exo_bench.bench.studies.stability.report.run` that runs the
    families and the forward part as tasks on the cluster, checkpointed per part."""
    from exo_bench.bench.studies import study
    from exo_bench.bench.studies.stability import cases

    out = options.folder.resolve()
    where = options.cluster or ClusterOptions()
    check_scheduler(where.scheduler)

    def evaluate(profile, methods, log):
        from exo_bench.bench.cluster.waits import completed

        folder = checkpoint_dir(default_checkpoints(out), code_key())
        parts = [f"family:{name}" for name in cases.FAMILIES] + ["forward"]
        tag = lambda part: _rows.safe_name(f"stability:{profile.name}:{','.join(methods)}:{part}")  # noqa: E731
        results = {}
        for part in parts:  # JSON, checked: every part before any work (never a pickle)
            kind = "ForwardResults" if part == "forward" else "FamilyResult"
            found = load_part(folder, tag(part), kind)
            if found is not None:
                results[part] = found
        todo = [p for p in parts if p not in results]
        log(
            f"stability {profile.name}: {len(parts)} parts, {len(parts) - len(todo)} from checkpoints, "
            f"{len(todo)} to run"
        )
        if todo:
            folder.mkdir(parents=True, exist_ok=True)
            with cluster(where.scheduler, where.workers) as client:
                futures = {
                    client.submit(
                        stability_task,
                        p,
                        profile.name,
                        methods,
                        pure=False,
                        retries=RETRIES,
                        key=f"exo-bench-stability-{tag(p)}-{uuid.uuid4().hex[:8]}",
                    ): p
                    for p in todo
                }
                try:
                    with progress_bar(len(todo), True) as bar:
                        task = bar.add_task("stability parts", total=len(todo))
                        for f in completed(
                            list(futures),
                            where.wait_timeout,
                            what="stability parts",
                            option="ClusterOptions.wait_timeout",
                        ):
                            part = futures[f]
                            results[part] = f.result()
                            save_part(folder, tag(part), results[part])
                            bar.advance(task)
                except BaseException:
                    cancel_tasks(client, list(futures))
                    raise
        categories = {
            c.__name__: c for c in (study.StabilityWarning, study.UnusableMethodWarning, cases.IllConditionedWarning)
        }
        for part in parts:
            for cat, msg in results[part][1]:
                warnings.warn(msg, categories.get(cat, UserWarning), stacklevel=2)
        families = [results[p][0] for p in parts if p != "forward"]
        return families, results["forward"][0]

    return evaluate
