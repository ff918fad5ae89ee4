"""Normative level walking: the numbers the gait is fitted to and the loads are compared with.

**Source.** D. A. Winter, *Biomechanics and Motor Control of Human Movement*, 4th ed., Wiley
2009, Appendix A: one stride of one subject walking at natural cadence, sagittal plane, as
tables A.1-A.7. We read the tables from their Excel transcription ``Winter_Appendix_data.xlsx``
(github.com/namita-kumar/WinterWalkingData, commit 563879e; it credits dustynrobots.com). **The
book itself was not available to check the transcription against.** :func:`winter_appendix`
recomputes every number below from that file (``python -m exo_bench.models.gait.normative FILE``); the
stored constants are its output.

What the numbers are (frames of the tables, 69.9 frames/s):

* the stride: right heel contact (``HCR``, frame 28, t = 0.386 s) to the next (frame 97,
  t = 1.373 s): **0.987 s, 121.6 steps/min** (Table A.3, column STATE); right toe-off (``TOR``)
  at frame 70, so stance is 0.601 s (60.9 %) and swing 0.386 s;
* the speed: the base-of-rib-cage marker moves 1.392 m over the stride: **1.41 m/s** (Table A.2);
* single support of the right leg: the tables mark right-foot events only, so the left toe-off and
  heel contact are **estimated by left-right symmetry** (each double support lasts
  (stance - swing)/2 = 7.5 frames): frames 36 to 62;
* segment angles (Tables A.3(b) leg, A.3(c) thigh, column THETA): the angle of the vector from the
  distal to the proximal joint, counter-clockwise from the walking direction, in degrees;
* peak net joint moments (Table A.5, N·m) and intersegmental joint forces (magnitude of RX, RY),
  per kg and in body weights of the subject;
* the subject's mass, **56.7 kg**, is not in the transcription: it is the mass for which Table
  A.6's potential energy of 1/2 HAT (203.6 J at y = 1.08 m, so 19.2 kg) is 0.339 of the body
  (HAT = 0.678 of body mass in Winter's Table 4.1, which we could not check); twice the mean
  vertical ground reaction of the right foot over the stride gives 54.3 kg, 4 % less.

These are one subject's values, not ranges across subjects: a model value within a factor of
about 1.5 of them is in the normal range of level walking, several times larger is not.
"""

from __future__ import annotations

import math
import re
import sys
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar
from xml.etree import ElementTree

import numpy as np

SOURCE = (
    "Winter, Biomechanics and Motor Control of Human Movement, 4th ed. (2009), Appendix A; "
    "from the Excel transcription github.com/namita-kumar/WinterWalkingData (not checked against the book)"
)
SHORT_SOURCE = "Winter (2009) App. A"

#: Frames of Winter's Appendix A stride (see the module text).
HEEL_CONTACT, TOE_OFF, NEXT_HEEL_CONTACT = 28, 70, 97
SINGLE_SUPPORT = (36, 62)  # estimated by left-right symmetry
SUBJECT_MASS = 56.7  # kg
G = 9.81


@dataclass(frozen=True)
class Normative:
    """One number of the normative stride, with where it comes from."""

    value: float
    unit: str
    where: str


@dataclass(frozen=True)
class WinterStride:
    """Winter's Appendix A stride: timing, speed, sagittal segment angles, peak loads."""

    stride_time: Normative
    speed: Normative
    #: segment angle (degrees, ccw from the walking direction, distal -> proximal joint) of every
    #: frame from HEEL_CONTACT to NEXT_HEEL_CONTACT: "leg" (Table A.3(b)), "thigh" (Table A.3(c))
    theta: dict[str, tuple[float, ...]]
    #: peak ``|net joint moment|`` per kg of body mass, by joint and phase
    moments: dict[str, Normative]
    #: peak ``|intersegmental joint force|`` in body weights, by joint and phase
    forces: dict[str, Normative]

    @property
    def cadence(self) -> float:
        """Steps per minute (two steps per stride)."""
        return 120.0 / self.stride_time.value

    def curve(self, segment: str, phase: str) -> np.ndarray:
        """The angles of ``segment`` ("leg", "thigh") over ``phase`` (a key of :data:`PHASES`), degrees."""
        a, b = PHASES[phase]
        return np.asarray(self.theta[segment][a - HEEL_CONTACT : b - HEEL_CONTACT + 1], dtype=float)

    def angle_range(self, segment: str, phase: str) -> tuple[float, float]:
        c = self.curve(segment, phase)
        return float(c.min()), float(c.max())


#: Frames (first, last) of each phase of the right leg.
PHASES = {"single support": SINGLE_SUPPORT, "stance": (HEEL_CONTACT, TOE_OFF), "swing": (TOE_OFF, NEXT_HEEL_CONTACT)}


def _n(value, unit, where) -> Normative:
    return Normative(value, unit, where)


#: The stored numbers: :func:`winter_appendix` of the transcription, as the tables print them.
WINTER = WinterStride(
    stride_time=_n(0.987, "s", "Table A.3, HCR frame 28 to HCR frame 97"),
    speed=_n(1.41, "m/s", "Table A.2, base of rib cage, frames 28 to 97"),
    theta={
        "leg": (
            108.4,
            106.6,
            104.6,
            102.5,
            100.3,
            98.1,
            95.9,
            93.8,
            91.9,
            90.3,
            88.9,
            87.6,
            86.5,
            85.4,
            84.4,
            83.5,
            82.5,
            81.6,
            80.6,
            79.7,
            78.7,
            77.8,
            76.8,
            75.9,
            74.9,
            73.8,
            72.7,
            71.6,
            70.2,
            68.7,
            67.1,
            65.2,
            63.2,
            61.1,
            58.7,
            56.2,
            53.6,
            50.9,
            48.1,
            45.4,
            42.9,
            40.7,
            38.9,
            37.6,
            36.8,
            36.8,
            37.4,
            38.8,
            40.9,
            43.6,
            46.8,
            50.6,
            54.6,
            59.0,
            63.6,
            68.3,
            73.1,
            78.0,
            82.9,
            87.9,
            92.8,
            97.6,
            102.0,
            105.9,
            109.0,
            111.0,
            112.0,
            112.0,
            111.1,
            109.6,
        ),
        "thigh": (
            109.6,
            109.3,
            109.0,
            108.6,
            108.4,
            108.2,
            107.9,
            107.6,
            106.9,
            105.9,
            104.5,
            102.9,
            101.2,
            99.3,
            97.6,
            95.9,
            94.3,
            92.8,
            91.4,
            90.0,
            88.7,
            87.4,
            86.0,
            84.6,
            83.1,
            81.7,
            80.2,
            78.8,
            77.5,
            76.3,
            75.3,
            74.5,
            73.8,
            73.4,
            73.1,
            73.1,
            73.4,
            74.1,
            75.0,
            76.4,
            78.1,
            80.2,
            82.5,
            85.2,
            88.2,
            91.3,
            94.5,
            97.7,
            100.7,
            103.6,
            106.1,
            108.3,
            110.1,
            111.7,
            113.0,
            114.0,
            114.9,
            115.4,
            115.7,
            115.7,
            115.4,
            114.8,
            114.0,
            113.2,
            112.4,
            111.7,
            111.3,
            110.9,
            110.8,
            110.6,
        ),
    },
    moments={
        "ankle, stance": _n(1.58, "N·m/kg", "Table A.5 ankle moment 89.8 N·m, frames 28-70"),
        "knee, stance": _n(0.67, "N·m/kg", "Table A.5 knee moment 37.8 N·m, frames 28-70"),
        "hip, stance": _n(0.96, "N·m/kg", "Table A.5 hip moment 54.4 N·m, frames 28-70"),
        "knee, swing": _n(0.28, "N·m/kg", "Table A.5 knee moment 15.9 N·m, frames 70-97"),
        "hip, swing": _n(0.35, "N·m/kg", "Table A.5 hip moment 19.7 N·m, frames 70-97"),
    },
    forces={
        "ankle, stance": _n(1.10, "BW", "Table A.5 ankle RX, RY 609 N, frames 28-70"),
        "knee, stance": _n(1.04, "BW", "Table A.5 knee RX, RY 580 N, frames 28-70"),
        "hip, stance": _n(0.96, "BW", "Table A.5 hip RX, RY 532 N, frames 28-70"),
        "knee, swing": _n(0.11, "BW", "Table A.5 knee RX, RY 61 N, frames 70-97"),
        "hip, swing": _n(0.22, "BW", "Table A.5 hip RX, RY 124 N, frames 70-97"),
    },
)


# ----------------------------------------------------------------------------- reading the transcription
_NS = {"m": "http://schemas.openxmlformats.org/spreadsheetml/2006/main"}
_REL = "{http://schemas.openxmlformats.org/officeDocument/2006/relationships}id"
_T = TypeVar("_T")


def _required(value: _T | None, path: Path, what: str) -> _T:
    """``value``, or a ValueError naming the workbook and the part of it that is missing."""
    if value is None:
        raise ValueError(f"{path}: not an .xlsx workbook as expected, {what} is missing")
    return value


def _sheets(path: Path) -> dict[str, dict[int, dict[int, str]]]:
    """Every sheet of an .xlsx as ``name -> {row: {column: text}}`` (1-based), with the standard library."""
    with zipfile.ZipFile(path) as z:
        shared: list[str] = []
        if "xl/sharedStrings.xml" in z.namelist():
            root = ElementTree.fromstring(z.read("xl/sharedStrings.xml"))
            shared = ["".join(t.text or "" for t in si.iter(f"{{{_NS['m']}}}t")) for si in root.findall("m:si", _NS)]
        rels = {r.get("Id"): r.get("Target") for r in ElementTree.fromstring(z.read("xl/_rels/workbook.xml.rels"))}
        out: dict[str, dict[int, dict[int, str]]] = {}
        sheets = ElementTree.fromstring(z.read("xl/workbook.xml")).find("m:sheets", _NS)
        for s in _required(sheets, path, "the workbook's <sheets>"):
            name = _required(s.get("name"), path, "a sheet's name")
            target = _required(rels.get(s.get(_REL)), path, f"the target of sheet {name!r}")
            rows: dict[int, dict[int, str]] = {}
            target = target.lstrip("/").removeprefix("xl/")
            for c in ElementTree.fromstring(z.read("xl/" + target)).iter(f"{{{_NS['m']}}}c"):
                cell = _required(re.match(r"([A-Z]+)(\d+)", c.get("r") or ""), path, f"a cell reference in {name!r}")
                col, row = cell.groups()
                v = c.find("m:v", _NS)
                if v is None or v.text is None:
                    continue
                k = 0
                for ch in col:
                    k = 26 * k + ord(ch) - 64
                rows.setdefault(int(row), {})[k] = shared[int(v.text)] if c.get("t") == "s" else v.text
            out[name] = rows
    return out


def _number(text: str | None) -> float:
    try:
        return float(str(text).replace("\u2212", "-"))
    except ValueError:
        return math.nan


def _by_frame(rows: dict[int, dict[int, str]], columns: dict[str, int]) -> dict[int, dict[str, float]]:
    out = {}
    for r in rows.values():
        frame = _number(r.get(2))
        if math.isfinite(frame):
            out[int(frame)] = {name: _number(r.get(c)) for name, c in columns.items()}
    return out


def winter_appendix(path: str | Path) -> WinterStride:
    """Recompute :data:`WINTER` from the Excel transcription of Winter's Appendix A."""
    sheets = _sheets(Path(path))

    def sheet(prefix: str):
        return next(v for k, v in sheets.items() if k.startswith(prefix))

    a2 = _by_frame(sheet("A2"), {"t": 3, "rib_x": 4})
    a3 = _by_frame(sheet("A3"), {"t": 3, "leg": 14, "thigh": 24})
    a5 = _by_frame(
        sheet("A5"),
        {
            "ankle_m": 9,
            "knee_m": 16,
            "hip_m": 24,
            "ankle_x": 6,
            "ankle_y": 7,
            "knee_x": 13,
            "knee_y": 14,
            "hip_x": 21,
            "hip_y": 22,
        },
    )
    hc, hc2 = HEEL_CONTACT, NEXT_HEEL_CONTACT
    stride = a3[hc2]["t"] - a3[hc]["t"]
    speed = (a2[hc2]["rib_x"] - a2[hc]["rib_x"]) / (a2[hc2]["t"] - a2[hc]["t"])
    phases = {k: range(a, b + 1) for k, (a, b) in PHASES.items()}

    def peak(key: str, phase: str, scale: float, unit: str, what: str):
        fr = phases[phase]
        if key.endswith("_m"):
            v = max(abs(a5[f][key]) for f in fr)
            raw = f"{v:.1f} N·m"
        else:
            v = max(math.hypot(a5[f][key + "_x"], a5[f][key + "_y"]) for f in fr)
            raw = f"{v:.0f} N"
        return _n(round(v / scale, 2), unit, f"Table A.5 {what} {raw}, frames {fr[0]}-{fr[-1]}")

    bw = SUBJECT_MASS * G
    return WinterStride(
        stride_time=_n(round(stride, 3), "s", f"Table A.3, HCR frame {hc} to HCR frame {hc2}"),
        speed=_n(round(speed, 2), "m/s", f"Table A.2, base of rib cage, frames {hc} to {hc2}"),
        theta={seg: tuple(a3[f][seg] for f in range(hc, hc2 + 1)) for seg in ("leg", "thigh")},
        moments={
            f"{j}, {p}": peak(f"{j}_m", p, SUBJECT_MASS, "N·m/kg", f"{j} moment")
            for j, p in (
                ("ankle", "stance"),
                ("knee", "stance"),
                ("hip", "stance"),
                ("knee", "swing"),
                ("hip", "swing"),
            )
        },
        forces={
            f"{j}, {p}": peak(j, p, bw, "BW", f"{j} RX, RY")
            for j, p in (
                ("ankle", "stance"),
                ("knee", "stance"),
                ("hip", "stance"),
                ("knee", "swing"),
                ("hip", "swing"),
            )
        },
    )


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print("usage: python -m exo_bench.models.gait.normative Winter_Appendix_data.xlsx", file=sys.stderr)
        return 2
    w = winter_appendix(argv[0])
    print(f"stride {w.stride_time.value} s ({w.cadence:.1f} steps/min), speed {w.speed.value} m/s")
    for seg in ("leg", "thigh"):
        for phase in PHASES:
            lo, hi = w.angle_range(seg, phase)
            print(f"{seg}, {phase} (frames {PHASES[phase][0]}-{PHASES[phase][1]}): {lo}-{hi} deg")
    for part in (w.moments, w.forces):
        for k, v in part.items():
            print(f"{k}: {v.value} {v.unit} ({v.where})")
    same = w == WINTER
    print("matches the stored WINTER" if same else "DIFFERS from the stored WINTER")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
