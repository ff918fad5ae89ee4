"""The rerun executable beside this Python's rerun-sdk: checking a recording (``rerun rrd verify``)
and taking a picture of it in the viewer (for the README and the scene reports)."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path


def rerun_executable() -> Path | None:
    """The ``rerun`` command installed with this Python's rerun-sdk, if any."""
    exe = Path(sys.executable).with_name("rerun")
    return exe if exe.exists() else None


def verify_recording(path: str | Path) -> str:
    """Run ``rerun rrd verify`` on a recording; return its report, raise ValueError if it fails.

    (``rerun rrd verify`` exits 0 on a file that is not a recording at all and only says
    "0 files verified", so the report is checked too.)"""
    exe = rerun_executable()
    if exe is None:
        raise OSError(f"rerun executable not found next to {sys.executable}")
    res = subprocess.run([str(exe), "rrd", "verify", str(path)], capture_output=True, text=True, timeout=120)
    report = (res.stdout + res.stderr).strip()
    if res.returncode != 0 or "1 file verified without error" not in report:
        raise ValueError(
            f"{path}: rerun rrd verify failed (exit {res.returncode}): {report.splitlines()[-1:] or report}"
        )
    return report


def screenshot(path: str | Path, png: str | Path, size: str = "1600x900", timeout: float = 300.0) -> Path:
    """A picture of the recording in the rerun viewer with its saved layout, written atomically.

    Runs ``rerun --window-size SIZE --screenshot-to PNG FILE``, which needs a display (an X server;
    ``Xvfb`` with Mesa's software Vulkan works: ``--renderer vulkan``) and is slow on a CPU renderer.
    The viewer renders at twice the window size on a high-DPI setup; the picture is scaled back to
    ``size``."""
    from PIL import Image

    from exo_bench.bench.output.provenance import atomic_write

    exe = rerun_executable()
    if exe is None:
        raise OSError(f"rerun executable not found next to {sys.executable}")
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        raise OSError("screenshot: no display (set DISPLAY, e.g. run under Xvfb)")
    png = Path(png)
    with tempfile.TemporaryDirectory() as tmp:
        shot = Path(tmp) / "shot.png"
        res = subprocess.run(
            [str(exe), "--renderer", "vulkan", "--window-size", size, "--screenshot-to", str(shot), str(path)],
            capture_output=True,
            text=True,
            timeout=timeout,
        )
        if res.returncode != 0 or not shot.exists():
            last = (res.stderr or res.stdout).strip().splitlines()[-1:] or ["no output"]
            raise OSError(f"screenshot of {path}: rerun exited {res.returncode}: {last[0]}")
        w, h = (int(x) for x in size.split("x"))
        img = Image.open(shot).convert("RGB")
        if img.size != (w, h):
            img = img.resize((w, h), Image.Resampling.LANCZOS)
        import io

        buf = io.BytesIO()
        img.save(buf, format="PNG", optimize=True)
    return atomic_write(png, buf.getvalue())
