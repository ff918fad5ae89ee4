"""Trials of the stride problem: the stored problem with settings changed, solved from a stored stride and
stored beside it (data/trials/<name>/, tabled in the stride's report by :func:`~.report.trials_table`).

``python -m exo_bench.bench.studies.stride.trials NAME KEY=VALUE ...`` solves one (values are Python
literals: ``w_accel=1e-5``, ``spring=(0.0, 0.0, 1.0)``) from the stored human stride at 1.41 m/s and
writes it, with the command and commit in its provenance; ``--store-all [human|exo]`` solves the stored
strides again with the problem as it is now (:func:`store_all`). One solve at a time: each takes a minute
or more.
"""

from __future__ import annotations

import ast
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from exo_bench.bench.studies.stride import data, problem
from exo_bench.models.files.names import check_name


def trial_folder(name: str, root: Path | None = None) -> Path:
    """The folder of trial ``name`` (a checked name, never a path)."""
    check_name(name, "trial")
    from exo_bench.models.files.names import file_stem

    return Path(data.DATA / "trials" if root is None else root) / file_stem(name)


def run(name: str, overrides: dict[str, Any], variant: str = "human", speed: float = 1.41, root=None) -> Path:
    """Solve the stored problem of ``variant`` at ``speed`` with ``overrides`` from its stored stride; store it."""
    from exo_bench.bench.output.provenance import _git_commit  # git with a timeout (issue 34: no unbounded wait)
    from exo_bench.models.mechanism.presets import human

    mech = human(2)
    source = data.load(variant, speed, mech)
    s = replace(problem.settings_for(mech, variant, speed), **overrides)
    st = problem.solve_from(mech, s, source)
    commit = _git_commit()
    args = ", ".join(f"{k}={v!r}" for k, v in overrides.items())
    st.meta["provenance"] = {
        "command": f"trial: problem.solve_from(mech, replace(settings_for(mech, {variant!r}, {speed:g}), {args}), "
        f"the stored {variant} stride at {speed:g} m/s of {commit})",
        "commit": commit,
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
    }
    return data.save(st, mech, trial_folder(name, root))


#: The stored strides, in the order :func:`store_all` solves them: ``(variant, speed, the stride it starts from)``.
STORED = (("human", 1.41, ("human", 1.41)), ("human", 1.0, ("human", 1.41)), ("human", 1.8, ("human", 1.41)))
STORED_EXO = (("exo", 1.41, ("exo", 1.41)),)


def store_all(keys=STORED + STORED_EXO) -> list[str]:
    """Solve every stored stride again with the problem as :func:`~.problem.settings_for` sets it now, each
    from the stride named (the human at 1.41 m/s first, so the others start from the new one), and store
    it; one line per stride."""
    from exo_bench.bench.output.provenance import _git_commit  # bounded wait; says when the tree differs
    from exo_bench.models.mechanism.presets import human

    mech = human(2)
    commit = _git_commit()
    out = []
    for variant, speed, (sv, ss) in keys:
        st = problem.solve_from(mech, problem.settings_for(mech, variant, speed), data.load(sv, ss, mech))
        st.meta["provenance"] = {
            "commit": commit,
            "date": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime()),
            "command": f"trials.store_all: problem.solve_from(mech, settings_for(mech, {variant!r}, {speed:g}), "
            f"the stored {sv} stride at {ss:g} m/s)",
        }
        path = data.save(st, mech)
        out.append(f"{path.name}: {st.solver['solve_seconds']:.1f} s, objective {st.solver['objective']:.6g}")
        print(out[-1], flush=True)
    return out


def main(argv: list[str]) -> int:
    if argv[:1] == ["--store-all"]:
        store_all(STORED if argv[1:] == ["human"] else STORED_EXO if argv[1:] == ["exo"] else STORED + STORED_EXO)
        return 0
    name, *pairs = argv
    overrides = {k: ast.literal_eval(v) for k, v in (p.split("=", 1) for p in pairs)}
    variant = overrides.pop("variant", "human")  # the stored stride of this variant at 1.41 m/s is the start
    path = run(name, overrides, variant)
    st = data.load(variant, 1.41, folder=path.parent)
    print(path, st.solver["solve_seconds"], st.solver["objective"])
    return 0


if __name__ == "__main__":  # pragma: no cover - a maintainer's command
    sys.exit(main(sys.argv[1:]))
