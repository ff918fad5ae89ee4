"""The gait scenes of the paper's section 7: figures and rerun recordings.

``write_gait_outputs(out_dir)`` runs the inverse-dynamics methods along one period of the gait
for the five-link spatial exoskeleton (eq. 26) and for the planar scenes of Figs. 2a, 2b and 5
(eq. 26 in the sagittal plane), and writes per scene ``<scene>-moments.png`` (Fig. 7),
``<scene>-forces.png`` (Fig. 8), ``<scene>-kinogram.png`` (Fig. 9), ``<scene>-differences.png``
(with two or more methods) and ``<scene>.rrd``; for the exoskeleton also
``exo5-3d-overview.png``, one picture in the layout of the recording.

Run it as ``python -m bench.gait_demo [OUT_DIR] [--methods pinocchio lagrange ...]``.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from bench.plots import overview_figure, save_figure, write_plots
from bench.recording import rerun_executable, verify_recording, write_recording
from bench.reporting import REPORTS
from bench.study import Study, run_methods
from models.mechanism import Mechanism
from models.motion import GaitParams, Motion, gait, planar_gait
from models.presets import exo5, fig2a, fig2b, fig5

#: Samples per gait period.
SAMPLES = 1000


@dataclass(frozen=True)
class GaitScene:
    name: str
    make: Callable[[], Mechanism]
    motion: Callable[[Mechanism, np.ndarray], Motion]
    label: str


SCENES: tuple[GaitScene, ...] = (
    GaitScene("exo5-3d", lambda: exo5(3), gait, "gait of eq. (26)"),
    GaitScene("fig2a-2d", lambda: fig2a(2), planar_gait, "planar gait (eq. 26, sagittal)"),
    GaitScene("fig2b-2d", lambda: fig2b(2), planar_gait, "planar gait (eq. 26, sagittal)"),
    GaitScene("fig5-2d", lambda: fig5(2), planar_gait, "planar gait (eq. 26, sagittal)"),
)


def gait_study(scene: GaitScene, methods: Sequence[str], samples: int = SAMPLES) -> Study:
    """Run the methods along one period of the scene's gait, ``samples`` instants per period."""
    if samples < 2:
        raise ValueError(f"gait scenes: field 'samples': expected >= 2, got {samples}")
    methods = list(methods)
    if not methods:
        raise ValueError("gait scenes: field 'methods': expected at least one method, got none")
    T = GaitParams().T
    t = np.linspace(0.0, T, samples, endpoint=False)
    mech = scene.make()
    reference = "pinocchio" if "pinocchio" in methods else methods[0]
    return run_methods(scene.name, mech, scene.motion(mech, t), f"{scene.label}, T = {T:g} s", methods,
                       reference=reference)


def write_gait_outputs(out_dir: str | Path = REPORTS, methods: Sequence[str] = ("pinocchio",),
                       samples: int = SAMPLES, scenes: Sequence[GaitScene] = SCENES) -> list[Path]:
    """Write every scene's PNGs and ``.rrd`` into ``out_dir``; return the paths written.

    Each recording is checked with ``rerun rrd verify`` when the ``rerun`` command is installed
    next to this Python (a failing check raises ValueError)."""
    out = Path(out_dir)
    written: list[Path] = []
    for scene in scenes:
        study = gait_study(scene, methods, samples)
        ran = study.ok_methods()
        print(f"{scene.name}: {len(study.motion.t)} samples, methods {', '.join(ran) or 'none'}"
              + "".join(f"; {m} {'skipped' if r.skipped else 'failed'}: {r.skipped or r.error}"
                        for m, r in study.results.items() if not r.ok), flush=True)
        if ran:
            written += write_plots(study, out)
            if scene.name == "exo5-3d":
                written.append(save_figure(overview_figure(study), out / f"{scene.name}-overview.png"))
        rrd = write_recording(study, out / f"{scene.name}.rrd")
        if rerun_executable() is not None:
            verify_recording(rrd)
        written.append(rrd)
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.gait_demo", description=__doc__.splitlines()[0])
    parser.add_argument("out_dir", nargs="?", default=str(REPORTS), help="where to write (default: reports/)")
    parser.add_argument("--methods", nargs="+", default=["pinocchio"], help="registered methods to run")
    parser.add_argument("--samples", type=int, default=SAMPLES, help="samples per gait period")
    args = parser.parse_args(argv)
    try:
        paths = write_gait_outputs(args.out_dir, args.methods, args.samples)
    except (ValueError, OSError) as e:
        print(f"gait_demo: {e}", file=sys.stderr)
        return 2
    for p in paths:
        print(f"wrote {p} ({p.stat().st_size / 1e6:.2f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
